//! Bounded input: every file the loaders read is a regular file (not a FIFO, device or
//! directory, even through a symlink) and no more than a byte limit is read from it,
//! after decompression. The limit is [`DEFAULT_MAX_INPUT_BYTES`] unless the
//! `WARPRAY_MAX_INPUT_BYTES` environment variable or [`super::ObjOptions::max_bytes`]
//! says otherwise.

use crate::error::{Error, Result};
use std::cell::Cell;
use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Bytes a loader reads from one file at most (after decompression): 1 GiB, about
/// ten times the largest standard model's OBJ text.
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 1 << 30;

/// The limit in force: `WARPRAY_MAX_INPUT_BYTES` if it is a positive whole number,
/// else [`DEFAULT_MAX_INPUT_BYTES`].
pub fn max_input_bytes() -> u64 {
    std::env::var("WARPRAY_MAX_INPUT_BYTES")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .filter(|&n| n > 0)
        .unwrap_or(DEFAULT_MAX_INPUT_BYTES)
}

/// Opens `path` for reading if it is a regular file (symlinks followed).
pub(crate) fn open_regular(path: &Path) -> Result<File> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a directory"
        } else {
            #[cfg(unix)]
            {
                use std::os::unix::fs::FileTypeExt;
                let t = meta.file_type();
                if t.is_fifo() {
                    "a FIFO (named pipe)"
                } else if t.is_char_device() || t.is_block_device() {
                    "a device"
                } else if t.is_socket() {
                    "a socket"
                } else {
                    "not a regular file"
                }
            }
            #[cfg(not(unix))]
            {
                "not a regular file"
            }
        };
        return Err(Error::NotRegularFile { path: path.into(), what });
    }
    File::open(path).map_err(|e| Error::io(path, e))
}

/// A reader that fails once more than `limit` bytes have passed through it, and
/// remembers that it did (so a caller whose parser swallows I/O errors can still tell).
pub(crate) struct Limited<'a, R> {
    inner: R,
    left: u64,
    exceeded: &'a Cell<bool>,
}

impl<'a, R: Read> Limited<'a, R> {
    pub(crate) fn new(inner: R, limit: u64, exceeded: &'a Cell<bool>) -> Self {
        Limited { inner, left: limit, exceeded }
    }
}

impl<R: Read> Read for Limited<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.left == 0 {
            // One byte more tells a file of exactly the limit from a longer one.
            let mut probe = [0u8; 1];
            if self.inner.read(&mut probe)? == 0 {
                return Ok(0);
            }
            self.exceeded.set(true);
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, "input larger than the limit"));
        }
        let want = buf.len().min(self.left.min(usize::MAX as u64) as usize);
        let n = self.inner.read(&mut buf[..want])?;
        self.left -= n as u64;
        Ok(n)
    }
}

/// Reads a whole regular text file of at most `limit` bytes.
pub(crate) fn read_text(path: &Path, limit: u64) -> Result<String> {
    let exceeded = Cell::new(false);
    let mut text = String::new();
    let read = Limited::new(open_regular(path)?, limit, &exceeded).read_to_string(&mut text);
    if exceeded.get() {
        return Err(Error::TooLarge { path: path.into(), limit });
    }
    read.map_err(|e| Error::io(path, e))?;
    Ok(text)
}

/// Checks an MTL file's numbers before tobj sees them (tobj panics on a colour with two
/// components, and accepts NaN or negative values), and writes single-value colours
/// (`Kd 0.5`, which the MTL format allows) out as three. Every error names the file,
/// line and field.
pub(crate) fn check_mtl(path: &Path, text: &str) -> Result<String> {
    let mut out = String::with_capacity(text.len() + 64);
    for (i, line) in text.lines().enumerate() {
        let at = crate::error::Location::new(path, i + 1);
        let bad = |msg: String| Error::MalformedMtl { at: at.clone(), msg };
        // A `#` starts a comment, also after the values.
        let mut words = line.split_whitespace().take_while(|w| !w.starts_with('#'));
        let key = words.next().unwrap_or("");
        let args: Vec<&str> = words.collect();
        let numbers = || -> Result<Vec<f32>> {
            args.iter()
                .map(|w| w.parse::<f32>().map_err(|_| bad(format!("{key}: '{w}' is not a number"))))
                .collect::<Result<Vec<f32>>>()
                .and_then(|v| match v.iter().find(|x| !x.is_finite()) {
                    Some(x) => Err(bad(format!("{key}: {x} is not finite"))),
                    None => Ok(v),
                })
        };
        match key {
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" | "Kt" => {
                // `Kd spectral …` and `Kd xyz …` forms are not supported by tobj either.
                let v = numbers()?;
                let rgb = match v.len() {
                    1 => [v[0]; 3],
                    3 => [v[0], v[1], v[2]],
                    n => return Err(bad(format!("{key} needs one or three numbers, found {n}"))),
                };
                if rgb.iter().any(|&c| c < 0.0) {
                    return Err(bad(format!("{key} must not be negative: {} {} {}", rgb[0], rgb[1], rgb[2])));
                }
                out.push_str(&format!("{key} {} {} {}\n", rgb[0], rgb[1], rgb[2]));
                continue;
            }
            "Ni" | "Ns" | "d" | "Tr" => {
                let v = numbers()?;
                let [x] = v[..] else { return Err(bad(format!("{key} needs one number, found {}", v.len()))) };
                let ok = match key {
                    "Ni" => x > 0.0,
                    "Ns" => x >= 0.0,
                    _ => (0.0..=1.0).contains(&x),
                };
                if !ok {
                    let range = match key {
                        "Ni" => "greater than 0",
                        "Ns" => "at least 0",
                        _ => "between 0 and 1",
                    };
                    return Err(bad(format!("{key} {x} is out of range (must be {range})")));
                }
            }
            _ => {}
        }
        out.push_str(line);
        out.push('\n');
    }
    Ok(out)
}
