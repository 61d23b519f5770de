//! Stanford PLY meshes (ASCII and binary, either byte order) through `ply-rs-bw`.
//!
//! Only positions and faces are read: `vertex` elements' `x`, `y`, `z` and `face`
//! elements' `vertex_indices` (or `vertex_index`) lists; polygons are split into fans.
//! Normals, texture coordinates, colours and other elements are skipped, as the OBJ
//! loader skips them (shading uses geometric normals). Elements are decoded straight
//! into small structs, not into per-vertex maps, so memory stays proportional to the
//! mesh. Errors name the file and, where the parser knows it, the line.

use super::input::{self, Limited};
use crate::error::{Error, Location, Result};
use glam::Vec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{Property, PropertyAccess, PropertyAccessResult};
use std::cell::Cell;
use std::io::BufReader;
use std::path::Path;

/// A mesh as positions and triangles.
pub(crate) struct PlyMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

#[derive(Default)]
struct PlyVertex {
    p: [f64; 3],
    seen: u8,
}

fn number(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        PlyVertex::default()
    }
    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        if let Some(v) = number(&property) {
            self.p[axis] = v;
            self.seen |= 1 << axis;
        }
        PropertyAccessResult::Ignored
    }
}

#[derive(Default)]
struct PlyFace {
    indices: Vec<i64>,
    bad: bool,
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        PlyFace::default()
    }
    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.indices = match property {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => {
                self.bad = true;
                Vec::new()
            }
        };
        PropertyAccessResult::Ignored
    }
}

struct Skip;
impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// Reads a PLY file's positions and triangles.
pub(crate) fn load_ply(path: &Path) -> Result<PlyMesh> {
    let file = input::open_regular(path)?;
    let file_len = file.metadata().map(|m| m.len()).unwrap_or(u64::MAX);
    let limit = input::max_input_bytes();
    let exceeded = Cell::new(false);
    let mut reader = Reader::new(BufReader::with_capacity(1 << 16, Limited::new(file, limit, &exceeded)));
    let bad = |line: usize, msg: String| Error::MalformedPly { at: Location::new(path, line), msg };
    let parse_error = |e: ply_rs_bw::parser::ParseError, exceeded: &Cell<bool>| {
        if exceeded.get() {
            Error::TooLarge { path: path.into(), limit }
        } else {
            let line = e.line().unwrap_or(0);
            let text = e.to_string();
            let msg = text.strip_prefix(&format!("Line {line}: ")).unwrap_or(&text);
            bad(line, msg.lines().next().unwrap_or("unreadable").to_string())
        }
    };
    let header = Parser::<Skip>::new().read_header(&mut reader).map_err(|e| parse_error(e, &exceeded))?;
    // Each element takes at least one byte: a header that claims more elements than the
    // file has bytes is refused before any is read.
    let claimed: u128 = header.elements.values().map(|e| e.count as u128).sum();
    if claimed > file_len as u128 {
        return Err(bad(0, format!("header claims {claimed} elements but the file has {file_len} bytes")));
    }
    let (mut positions, mut faces) = (Vec::new(), Vec::new());
    for (name, def) in &header.elements {
        let at = reader.line();
        match name.as_str() {
            "vertex" => {
                let vs = Parser::<PlyVertex>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(|e| parse_error(e, &exceeded))?;
                if let Some(i) = vs.iter().position(|v| v.seen != 0b111) {
                    return Err(bad(at, format!("vertex {} lacks an x, y or z coordinate", i + 1)));
                }
                positions = vs.iter().map(|v| Vec3::new(v.p[0] as f32, v.p[1] as f32, v.p[2] as f32)).collect();
                if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
                    return Err(Error::NonFinite { at: Location::file(path), what: format!("PLY vertex {}", i + 1) });
                }
            }
            "face" => {
                faces = Parser::<PlyFace>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(|e| parse_error(e, &exceeded))?;
            }
            _ => {
                Parser::<Skip>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(|e| parse_error(e, &exceeded))?;
            }
        }
    }
    if exceeded.get() {
        return Err(Error::TooLarge { path: path.into(), limit });
    }
    let n = positions.len() as i64;
    let mut triangles = Vec::with_capacity(faces.len());
    for (i, f) in faces.iter().enumerate() {
        if f.bad || f.indices.len() < 3 {
            return Err(bad(0, format!("face {} needs a list of at least three vertex indices", i + 1)));
        }
        if let Some(&v) = f.indices.iter().find(|&&v| v < 0 || v >= n) {
            return Err(Error::IndexOutOfRange {
                at: Location::file(path),
                msg: format!("PLY face {} uses vertex {v} but there are {n} vertices", i + 1),
            });
        }
        for k in 1..f.indices.len() - 1 {
            triangles.push([f.indices[0] as u32, f.indices[k] as u32, f.indices[k + 1] as u32]);
        }
    }
    if triangles.is_empty() {
        return Err(Error::EmptyMesh { at: Location::file(path) });
    }
    Ok(PlyMesh { positions, triangles })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("warpray-ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn ascii_and_binary_quads_become_two_triangles() {
        let ascii = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
                     property float nx\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
                     0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n4 0 1 2 3\n";
        let m = load_ply(&write("a.ply", ascii.as_bytes())).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.positions[2], Vec3::new(1.0, 1.0, 0.0));
        let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
                        property double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"
            .to_vec();
        for v in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.5]] {
            v.iter().for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
        }
        bin.push(3);
        [0u32, 1, 2].iter().for_each(|i| bin.extend_from_slice(&i.to_le_bytes()));
        let m = load_ply(&write("b.ply", &bin)).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.positions[2], Vec3::new(0.0, 3.0, 0.5));
    }

    #[test]
    fn bad_files_are_errors_naming_the_file() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                    element face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let cases = [
            ("index.ply", format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"), "vertex 7"),
            ("short.ply", format!("{head}0 0 0\n1 0 0\n0 1 0\n2 0 1\n"), "at least three"),
            ("nan.ply", format!("{head}0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"), "nan.ply:11"),
            ("text.ply", format!("{head}0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"), "text.ply"),
            ("huge.ply", head.replace("vertex 3", "vertex 999999999999"), "claims"),
            ("magic.ply", "plx\n".to_string(), "magic.ply"),
        ];
        for (name, text, want) in cases {
            let e = load_ply(&write(name, text.as_bytes())).err().map(|e| e.to_string()).unwrap_or_default();
            assert!(e.contains(want) && e.contains(name), "{name}: {e}");
        }
    }
}
