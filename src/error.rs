//! One error type for everything a user can get wrong: files, scene content, sizes and
//! output. Every variant names the file, and the line where it is known.

use std::path::PathBuf;

/// Where in an input file something went wrong. `line` is 1-based; 0 means unknown.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    pub path: PathBuf,
    pub line: usize,
}

impl Location {
    pub fn new(path: impl Into<PathBuf>, line: usize) -> Self {
        Location { path: path.into(), line }
    }
    pub fn file(path: impl Into<PathBuf>) -> Self {
        Location { path: path.into(), line: 0 }
    }
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}", self.path.display(), self.line)
        } else {
            write!(f, "{}", self.path.display())
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: is {what}, not a regular file; refusing to read it")]
    NotRegularFile { path: PathBuf, what: &'static str },
    #[error("{path}: more than {limit} bytes (after decompression); raise WARPRAY_MAX_INPUT_BYTES to read it")]
    TooLarge { path: PathBuf, limit: u64 },
    #[error("GPU library {library}: {msg}")]
    Gpu { library: PathBuf, msg: String },
    #[error("{at}: malformed OBJ: {msg}")]
    MalformedObj { at: Location, msg: String },
    #[error("{at}: material library '{mtl}' not found (looked for {looked})")]
    MissingMtl { at: Location, mtl: String, looked: PathBuf },
    #[error("{at}: malformed MTL: {msg}")]
    MalformedMtl { at: Location, msg: String },
    #[error("{at}: face index out of range: {msg}")]
    IndexOutOfRange { at: Location, msg: String },
    #[error("{at}: {what} is not finite (NaN or infinity)")]
    NonFinite { at: Location, what: String },
    #[error("{at}: the scene has no triangles")]
    EmptyMesh { at: Location },
    #[error(
        "{at}: the scene has no emitters (no Ke material on a triangle of positive area, no point light of positive intensity); add a light in a scene file"
    )]
    NoEmitters { at: Location },
    #[error("{at}: {msg}")]
    SceneFile { at: Location, msg: String },
    #[error("image size {width}x{height} is not allowed: {why}")]
    BadImageSize { width: u32, height: u32, why: &'static str },
    #[error("{0}")]
    BadSetting(String),
    #[error("{path}: cannot write image: {msg}")]
    Output { path: PathBuf, msg: String },
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
