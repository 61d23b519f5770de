//! Wavefront OBJ + MTL loading through tobj, plain or gzip-compressed (`.obj.gz`).
//!
//! tobj reports what went wrong but not where. When it fails, or when the loaded data
//! fails validation, a second pass over the file finds the first offending line so the
//! error names `file:line`. That pass only runs on the error path.

use super::data::Scene;
use super::input::{self, Limited};
use super::material::Material;
use crate::error::{Error, Location, Result};
use glam::Vec3;
use std::cell::{Cell, RefCell};
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// Options for [`load_obj`].
#[derive(Clone, Debug, Default)]
pub struct ObjOptions {
    /// Uniform scale applied to positions (1 when zero or unset).
    pub scale: f32,
    /// Translation applied after scaling.
    pub translate: Vec3,
    /// Bytes read from the OBJ and from each MTL at most, after decompression
    /// (default: [`super::input::max_input_bytes`]).
    pub max_bytes: Option<u64>,
    /// Skip `mtllib` statements: every triangle gets the default material (Mitsuba's
    /// OBJ shapes take their BSDF from the scene, not from the file).
    pub ignore_materials: bool,
}

/// A regular file's text (decompressed when it ends in `.gz`), cut off after `limit`
/// bytes with `exceeded` set.
fn open_text<'a>(path: &Path, limit: u64, exceeded: &'a Cell<bool>) -> Result<Box<dyn BufRead + 'a>> {
    let file = input::open_regular(path)?;
    let gz = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    Ok(if gz {
        let text = Limited::new(flate2::read::MultiGzDecoder::new(file), limit, exceeded);
        Box::new(BufReader::with_capacity(1 << 16, text))
    } else {
        Box::new(BufReader::with_capacity(1 << 16, Limited::new(file, limit, exceeded)))
    })
}

/// A reader that watches the bytes tobj consumes: it counts lines, so a parse error can
/// name its line, and notes the first `f` statement with fewer than three vertices
/// (tobj would silently read it as a line and drop it). The line count lives in a
/// `Cell` so the MTL callback can read it while tobj holds the reader.
struct LineCounter<'a, R> {
    inner: R,
    newlines: &'a Cell<usize>,
    scan: FaceScan,
}

/// Byte-level state of the short-face check, and whether any line is a `usemtl`.
#[derive(Default)]
struct FaceScan {
    tokens: u32,
    in_token: bool,
    /// The first token so far is exactly `f`.
    face: bool,
    /// How many bytes of the first token match `usemtl` so far (7: not a match).
    usemtl: u8,
    line: usize,
    first_short_face: Option<usize>,
    saw_usemtl: bool,
}

impl FaceScan {
    fn feed(&mut self, bytes: &[u8]) {
        for &b in bytes {
            match b {
                b'\n' => self.end_line(),
                b' ' | b'\t' | b'\r' => self.in_token = false,
                _ => {
                    if !self.in_token {
                        self.tokens += 1;
                        self.in_token = true;
                        if self.tokens == 1 {
                            self.face = b == b'f';
                            self.usemtl = if b == b'u' { 1 } else { 7 };
                            continue;
                        }
                    }
                    if self.tokens == 1 {
                        self.face = false; // "fo..." is not a face
                        let k = self.usemtl as usize;
                        self.usemtl = if k < 6 && b"usemtl"[k] == b { self.usemtl + 1 } else { 7 };
                    }
                }
            }
        }
    }

    fn end_line(&mut self) {
        self.line += 1;
        if self.face && self.tokens < 4 && self.first_short_face.is_none() {
            self.first_short_face = Some(self.line);
        }
        let saw_usemtl = self.saw_usemtl || (self.usemtl == 6 && self.tokens >= 2);
        *self = FaceScan { line: self.line, first_short_face: self.first_short_face, saw_usemtl, ..Default::default() };
    }
}

impl<'a, R: BufRead> LineCounter<'a, R> {
    fn new(inner: R, newlines: &'a Cell<usize>) -> Self {
        LineCounter { inner, newlines, scan: FaceScan::default() }
    }

    fn note(newlines: &Cell<usize>, scan: &mut FaceScan, bytes: &[u8]) {
        newlines.set(newlines.get() + bytes.iter().filter(|&&b| b == b'\n').count());
        scan.feed(bytes);
    }

    /// The first short face line, and whether any line was a `usemtl`, once the whole
    /// input has been read.
    fn finish(mut self) -> (Option<usize>, bool) {
        self.scan.end_line();
        (self.scan.first_short_face, self.scan.saw_usemtl)
    }
}

impl<R: BufRead> Read for LineCounter<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        Self::note(self.newlines, &mut self.scan, &buf[..n]);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for LineCounter<'_, R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }
    fn consume(&mut self, amt: usize) {
        let LineCounter { inner, newlines, scan } = self;
        if let Ok(buf) = inner.fill_buf() {
            let n = amt.min(buf.len());
            Self::note(newlines, scan, &buf[..n]);
        }
        inner.consume(amt)
    }
}

/// Loads an OBJ file (and the MTL files it names) as a scene. The camera is framed
/// on the geometry; emitters are not required here (see [`Scene::check_renderable`]).
pub fn load_obj(path: impl AsRef<Path>, opts: &ObjOptions) -> Result<Scene> {
    let path = path.as_ref();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let limit = opts.max_bytes.unwrap_or_else(input::max_input_bytes);
    let (lines_read, exceeded) = (Cell::new(0usize), Cell::new(false));
    let mut reader = LineCounter::new(open_text(path, limit, &exceeded)?, &lines_read);
    // The MTL loader is called from inside tobj; remember the first failure and the
    // line that named the library.
    let mtl_error: RefCell<Option<Error>> = RefCell::new(None);
    let load_opts =
        tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let result = tobj::load_obj_buf(&mut reader, &load_opts, |mtl_path: &Path| {
        if opts.ignore_materials {
            return Ok(Default::default());
        }
        load_mtl(&dir, mtl_path, path, lines_read.get(), limit, &mtl_error)
    });
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    if exceeded.get() {
        return Err(Error::TooLarge { path: path.into(), limit });
    }
    let (models, materials) = match result {
        Ok(r) => r,
        Err(e) => {
            return Err(diagnose(path, Some(e), lines_read.get().max(1), limit));
        }
    };
    let (short_face, saw_usemtl) = reader.finish();
    if let Some(line) = short_face {
        return Err(Error::MalformedObj {
            at: Location::new(path, line),
            msg: "a face needs at least three vertices".into(),
        });
    }
    let materials = materials.unwrap_or_default();
    // tobj gives faces under a `usemtl` of an unknown name no material, as if none was
    // named; they would render with the default material without a word.
    if saw_usemtl && !opts.ignore_materials && models.iter().any(|m| m.mesh.material_id.is_none()) {
        let known: Vec<&str> = materials.iter().map(|m| m.name.as_str()).collect();
        if let Some(e) = unknown_material(path, &known, limit) {
            return Err(e);
        }
    }

    let mut scene = Scene::empty(path);
    for m in &materials {
        let (mat, ke) = Material::from_mtl(m);
        scene.add_material(m.name.clone(), mat, ke);
    }
    let default_material = scene.materials.len() as u32;
    scene.add_material("default", Material::DEFAULT, Vec3::ZERO);

    let scale = if opts.scale == 0.0 { 1.0 } else { opts.scale };
    for model in &models {
        let mesh = &model.mesh;
        let base = scene.positions.len() as u32;
        scene
            .positions
            .extend(mesh.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2]) * scale + opts.translate));
        let mat = mesh.material_id.map(|m| m as u32).filter(|&m| m < default_material).unwrap_or(default_material);
        for t in mesh.indices.chunks_exact(3) {
            scene.triangles.push([t[0] + base, t[1] + base, t[2] + base]);
            scene.material_of.push(mat);
        }
    }
    if scene.triangles.is_empty() {
        return Err(Error::EmptyMesh { at: Location::file(path) });
    }
    if scene.positions.iter().any(|p| !p.is_finite()) {
        return Err(diagnose(path, None, 0, limit));
    }
    scene.frame_camera();
    scene.validate()?;
    Ok(scene)
}

fn load_mtl(
    dir: &Path,
    mtl_path: &Path,
    obj: &Path,
    line: usize,
    limit: u64,
    err: &RefCell<Option<Error>>,
) -> tobj::MTLLoadResult {
    let full: PathBuf = dir.join(mtl_path);
    let fail = |e: Error| {
        err.borrow_mut().get_or_insert(e);
        Err(tobj::LoadError::OpenFileFailed)
    };
    // tobj calls us after it has read the `mtllib` line, so `line` counts it.
    let at = Location::new(obj, line.max(1));
    if !full.exists() {
        return fail(Error::MissingMtl { at, mtl: mtl_path.display().to_string(), looked: full });
    }
    // Read whole (bounded, regular files only) and checked before tobj parses it.
    let text = match input::read_text(&full, limit).and_then(|t| input::check_mtl(&full, &t)) {
        Ok(t) => t,
        Err(e) => return fail(e),
    };
    let mtl_lines = Cell::new(0usize);
    let mut reader = LineCounter::new(text.as_bytes(), &mtl_lines);
    match tobj::load_mtl_buf(&mut reader) {
        Ok(r) => Ok(r),
        Err(e) => fail(Error::MalformedMtl { at: Location::new(&full, mtl_lines.get().max(1)), msg: e.to_string() }),
    }
}

/// The first `usemtl` line naming a material that no MTL file defined.
fn unknown_material(path: &Path, known: &[&str], limit: u64) -> Option<Error> {
    let exceeded = Cell::new(false);
    let reader = open_text(path, limit, &exceeded).ok()?;
    for (i, line) in reader.lines().enumerate() {
        let line = line.ok()?;
        let Some(name) = line.trim_start().strip_prefix("usemtl").filter(|r| r.starts_with([' ', '\t'])) else {
            continue;
        };
        let name = name.trim();
        if !name.is_empty() && !known.contains(&name) {
            let list = if known.is_empty() { "none: no mtllib was loaded".to_string() } else { known.join(", ") };
            return Some(Error::MalformedObj {
                at: Location::new(path, i + 1),
                msg: format!("usemtl '{name}' names a material that no MTL file defines (defined: {list})"),
            });
        }
    }
    None
}

/// Finds the first line of the OBJ that is malformed, out of range or not finite.
/// `fallback` is tobj's error when the scan finds nothing more precise.
fn diagnose(path: &Path, fallback: Option<tobj::LoadError>, fallback_line: usize, limit: u64) -> Error {
    let exceeded = Cell::new(false);
    let Ok(reader) = open_text(path, limit, &exceeded) else {
        return Error::MalformedObj { at: Location::file(path), msg: "cannot re-read file".into() };
    };
    let mut n_v = 0usize;
    for (i, line) in reader.lines().enumerate() {
        let at = Location::new(path, i + 1);
        let Ok(line) = line else {
            return Error::MalformedObj { at, msg: "unreadable line (not UTF-8, or a corrupt gzip stream)".into() };
        };
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                n_v += 1;
                let coords: Vec<_> = words.take(3).map(str::parse::<f32>).collect();
                if coords.len() < 3 || coords.iter().any(|c| c.is_err()) {
                    return Error::MalformedObj { at, msg: format!("vertex needs three numbers: '{line}'") };
                }
                if coords.iter().any(|c| !c.as_ref().unwrap().is_finite()) {
                    return Error::NonFinite { at, what: format!("vertex {n_v}") };
                }
            }
            Some("f") => {
                let refs: Vec<&str> = words.collect();
                if refs.len() < 3 {
                    return Error::MalformedObj { at, msg: format!("face needs at least three vertices: '{line}'") };
                }
                for r in refs {
                    let Ok(idx) = r.split('/').next().unwrap_or("").parse::<i64>() else {
                        return Error::MalformedObj { at, msg: format!("bad face vertex '{r}'") };
                    };
                    let resolved = if idx < 0 { n_v as i64 + idx + 1 } else { idx };
                    if resolved < 1 || resolved > n_v as i64 {
                        return Error::IndexOutOfRange { at, msg: format!("vertex {idx} named, {n_v} defined so far") };
                    }
                }
            }
            _ => {}
        }
    }
    let msg = fallback.map_or("unknown problem".to_string(), |e| e.to_string());
    Error::MalformedObj { at: Location::new(path, fallback_line), msg }
}
