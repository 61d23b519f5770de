//! One error type for everything a user can get wrong: files, scene content, sizes and
//! output. Every variant names the file, and the line where it is known.

use std::path::PathBuf;

/// Where in an input file something went wrong. `line` is 1-based; 0 means unknown.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The input file.
    pub path: PathBuf,
    /// 1-based line, or 0 when unknown.
    pub line: usize,
}

impl Location {
    /// A line of a file.
    pub fn new(path: impl Into<PathBuf>, line: usize) -> Self {
        Location { path: path.into(), line }
    }
    /// A whole file (no line known).
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

/// Everything that can go wrong, each variant naming its file (and line where known).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or opening a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// The path is a FIFO, device, socket or directory: nothing is read from it.
    #[error("{path}: is {what}, not a regular file; refusing to read it")]
    NotRegularFile {
        /// The path given.
        path: PathBuf,
        /// What it is instead ("a FIFO", "a directory", ...).
        what: &'static str,
    },
    /// A file (after decompression) is larger than the input limit.
    #[error("{path}: more than {limit} bytes (after decompression); raise WARPRAY_MAX_INPUT_BYTES to read it")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The limit in bytes.
        limit: u64,
    },
    /// The CUDA library could not be loaded or a call into it failed.
    #[error("GPU library {library}: {msg}")]
    Gpu {
        /// The shared library (built by `cuda/build.sh`).
        library: PathBuf,
        /// What failed.
        msg: String,
    },
    /// The Embree library could not be loaded or a call into it failed.
    #[error("Embree library {library}: {msg}")]
    Embree {
        /// The shared library (Debian's libembree3, or the file `WARPRAY_EMBREE` names).
        library: PathBuf,
        /// What failed.
        msg: String,
    },
    /// A line of an OBJ file is malformed.
    #[error("{at}: malformed OBJ: {msg}")]
    MalformedObj {
        /// File and line.
        at: Location,
        /// What is wrong with the line.
        msg: String,
    },
    /// A PLY file is malformed.
    #[error("{at}: malformed PLY: {msg}")]
    MalformedPly {
        /// File and line (0 when the parser does not know it).
        at: Location,
        /// What is wrong.
        msg: String,
    },
    /// An OBJ names a material library that does not exist.
    #[error("{at}: material library '{mtl}' not found (looked for {looked})")]
    MissingMtl {
        /// The OBJ line naming the library.
        at: Location,
        /// The name as written.
        mtl: String,
        /// Where it was looked for.
        looked: PathBuf,
    },
    /// A field of an MTL file is malformed or out of range.
    #[error("{at}: malformed MTL: {msg}")]
    MalformedMtl {
        /// File and line.
        at: Location,
        /// The field and what is wrong with it.
        msg: String,
    },
    /// A face names a vertex or material that does not exist.
    #[error("{at}: face index out of range: {msg}")]
    IndexOutOfRange {
        /// File (and line where known).
        at: Location,
        /// Which index.
        msg: String,
    },
    /// A number is NaN or infinite.
    #[error("{at}: {what} is not finite (NaN or infinity)")]
    NonFinite {
        /// File (and line where known).
        at: Location,
        /// Which value.
        what: String,
    },
    /// The scene has no triangles.
    #[error("{at}: the scene has no triangles")]
    EmptyMesh {
        /// The file.
        at: Location,
    },
    /// Nothing in the scene emits light.
    #[error(
        "{at}: the scene has no emitters (no Ke material on a triangle of positive area, no point light of positive intensity); add a light in a scene file"
    )]
    NoEmitters {
        /// The scene's file.
        at: Location,
    },
    /// A scene file's key is unknown, mistyped or out of range.
    #[error("{at}: {msg}")]
    SceneFile {
        /// File and line.
        at: Location,
        /// The key and what is wrong with it.
        msg: String,
    },
    /// A `converge` CSV (replotted with `--replot`) that is not what `converge` writes.
    #[error("{at}: {msg}")]
    MalformedCsv {
        /// File and line.
        at: Location,
        /// The field and what is wrong with it.
        msg: String,
    },
    /// An image size of zero or beyond the limits.
    #[error("image size {width}x{height} is not allowed: {why}")]
    BadImageSize {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
        /// The rule it breaks.
        why: &'static str,
    },
    /// A setting or option out of range, or two that conflict.
    #[error("{0}")]
    BadSetting(String),
    /// An input (a scene, a render's size) that would need more memory than the budget
    /// (`crate::limits::memory_budget`), refused before the large allocations.
    #[error("{what} {over}")]
    OverMemoryBudget {
        /// The input: a file and line, or a render's size and integrator.
        what: String,
        /// The estimate and the budget ([`crate::limits::OverBudget`]).
        over: String,
    },
    /// An output image cannot be written.
    #[error("{path}: cannot write image: {msg}")]
    Output {
        /// The file.
        path: PathBuf,
        /// Why.
        msg: String,
    },
    /// An input image (a reference, a `diff` operand) cannot be read.
    #[error("{path}: cannot read image: {msg}")]
    Input {
        /// The file.
        path: PathBuf,
        /// Why.
        msg: String,
    },
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}

/// The crate's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;
