//! Nsight Compute's per-instruction counters (its source view), split by what each
//! global memory instruction reads or writes.
//!
//! Collect with `--section SourceCounters --import-source yes` and export with
//! `ncu -i REPORT --page source --csv --print-source cuda,sass` (`cuda/source_counters.sh`).
//! The export lists, for every profiled launch, each CUDA source line with the SASS
//! instructions compiled from it: warp instructions executed, thread instructions
//! executed, address space, access operation and the sectors it touched (Nsight's "L2
//! Theoretical Sectors Global", which adds up to `l1tex__t_sectors_pipe_lsu_mem_global_op_*`).
//! An instruction that inlining attributes to several lines is counted once, under the
//! line of our own sources (`.cu`, `.cuh`) that names it.
//!
//! Splitting a kernel's global memory instructions by the array each one accesses shows
//! which of them the `simt` model sees: the emulated CIS shading kernel reads the pool
//! and the light vertex cache through `simt` views, and the scene (materials, triangles,
//! lights) through plain references ([`CIS_CLASSES`]).

use super::ncu::split_csv;
use std::collections::HashMap;
use std::fmt::Write;

/// One SASS instruction's counters in one launch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Instruction {
    /// The kernel, as the export names it (`cis::shade_sorted(cis::ShadeArgs)`).
    pub kernel: String,
    /// Launch number in the export, from 0.
    pub launch: usize,
    /// Source file name (no folders).
    pub file: String,
    /// Line of the instruction in that file.
    pub line: u32,
    /// That line's text.
    pub text: String,
    /// `Global`, `Local`, `Shared`, or empty.
    pub space: String,
    /// `Load`, `Store`, `Atomic`…, or empty (as for a global reduction, `REDG`).
    pub op: String,
    /// The SASS instruction (`LDG.E.128 R4, desc[UR4][R2.64]`).
    pub sass: String,
    /// Its address in the kernel's code.
    pub address: String,
    /// Warp instructions executed (for a global access: its requests).
    pub warp: f64,
    /// Thread instructions executed.
    pub thread: f64,
    /// Sectors the instruction touched.
    pub sectors: f64,
}

/// A count as Nsight writes it (`1,320`), or `None` if it is none.
fn count(s: &str) -> Option<f64> {
    let plain: String = s.chars().filter(|&c| c != ',').collect();
    plain.parse().ok()
}

fn number(s: &str) -> f64 {
    count(s).unwrap_or(0.0)
}

fn ours(file: &str) -> bool {
    file.ends_with(".cu") || file.ends_with(".cuh")
}

/// Every SASS instruction of every launch in a `--print-source cuda,sass` export.
/// Errors name the line of the export.
pub fn parse(text: &str) -> Result<Vec<Instruction>, String> {
    let mut out: Vec<Instruction> = Vec::new();
    // Per launch: instruction address -> index in `out`.
    let mut at: HashMap<String, usize> = HashMap::new();
    let (mut kernel, mut launch) = (String::new(), None::<usize>);
    let (mut file, mut line, mut source) = (String::new(), 0u32, String::new());
    let mut header: Option<HashMap<String, usize>> = None;
    // A launch lists each source file once: a file seen again, or another function,
    // starts the next launch (a "Kernel Name" row, where the export has one, too).
    let mut files: Vec<String> = Vec::new();
    let next_launch = |launch: &mut Option<usize>, at: &mut HashMap<String, usize>, files: &mut Vec<String>| {
        *launch = Some(launch.map_or(0, |l| l + 1));
        at.clear();
        files.clear();
    };
    for (n, raw) in text.lines().enumerate() {
        let row = split_csv(raw);
        match row.first().map(String::as_str) {
            None => continue,
            Some("Kernel Name") => {
                kernel = row.get(1).cloned().unwrap_or_default();
                next_launch(&mut launch, &mut at, &mut files);
                continue;
            }
            Some("Function Name") => {
                let name = row.get(1).cloned().unwrap_or_default();
                if name != kernel {
                    // Another kernel whose first file was taken for the last launch's.
                    if !kernel.is_empty() && files.len() > 1 {
                        next_launch(&mut launch, &mut at, &mut files);
                        files.push(file.clone());
                    }
                    kernel = name;
                }
                continue;
            }
            Some("File Path") => {
                file = row.get(1).map(|p| p.rsplit('/').next().unwrap_or(p).to_string()).unwrap_or_default();
                if launch.is_none() || files.contains(&file) {
                    next_launch(&mut launch, &mut at, &mut files);
                }
                files.push(file.clone());
                continue;
            }
            Some("Line No") => {
                header = Some(row.iter().enumerate().map(|(i, c)| (c.clone(), i)).collect());
                continue;
            }
            Some("") => {}
            Some(no) => {
                line = no.parse().map_err(|_| format!("line {}: '{no}' is not a line number", n + 1))?;
                source = row.get(1).map(|s| s.trim().to_string()).unwrap_or_default();
                continue;
            }
        }
        let Some(h) = &header else { return Err(format!("line {}: an instruction before any header", n + 1)) };
        let Some(launch) = launch else { return Err(format!("line {}: an instruction before any kernel", n + 1)) };
        let col = |name: &str| -> Result<&str, String> {
            let i = *h.get(name).ok_or_else(|| format!("the export has no '{name}' column"))?;
            Ok(row.get(i).map_or("", String::as_str))
        };
        let address = row.get(2).cloned().unwrap_or_default();
        let inst = Instruction {
            kernel: kernel.clone(),
            launch,
            file: file.clone(),
            line,
            text: source.clone(),
            space: col("Address Space")?.trim_matches('-').to_string(),
            op: col("Access Operation")?.trim_matches('-').to_string(),
            sass: row.get(3).map(|x| x.trim().to_string()).unwrap_or_default(),
            address: address.clone(),
            warp: number(col("Instructions Executed")?),
            thread: number(col("Thread Instructions Executed")?),
            sectors: number(col("L2 Theoretical Sectors Global")?),
        };
        match at.get(&address) {
            // Listed again under another line: keep the first line of our own sources.
            Some(&i) => {
                if !ours(&out[i].file) && ours(&inst.file) {
                    out[i] = inst;
                }
            }
            None => {
                at.insert(address, out.len());
                out.push(inst);
            }
        }
    }
    if out.is_empty() {
        return Err(
            "no instructions found (is this an `ncu --page source --csv --print-source cuda,sass` export?)".into()
        );
    }
    Ok(out)
}

/// Warp instructions executed in all, from a `--page source --csv --print-source sass`
/// export (one row an instruction, each listed once): the sum of its "Instructions
/// Executed" column. A `cuda,sass` export lists an instruction under several source
/// lines and is refused ([`parse`] counts those).
pub fn executed_warp_instructions(text: &str) -> Result<f64, String> {
    let (mut column, mut total, mut rows) = (None, 0.0, 0usize);
    for (n, raw) in text.lines().enumerate() {
        let row = split_csv(raw);
        if row.first().is_some_and(|c| c == "Line No") {
            return Err(format!("line {}: a cuda,sass export (count its instructions with source::parse)", n + 1));
        }
        if let Some(i) = row.iter().position(|c| c == "Instructions Executed") {
            column = Some(i);
            continue;
        }
        let Some(v) = column.and_then(|i| row.get(i)) else { continue };
        total += count(v).ok_or_else(|| format!("line {}: '{v}' is not an instruction count", n + 1))?;
        rows += 1;
    }
    if rows == 0 {
        return Err("no instruction rows under an \"Instructions Executed\" column".into());
    }
    Ok(total)
}

/// What CIS-LBDPT's shading kernel accesses, recognised by the text of the source line
/// in `cuda/cis_device.cuh` (first match wins). Classes named `pool…` and `cache…` are
/// read through `simt` views in the emulated kernel; `scene…` are not.
pub const CIS_CLASSES: &[(&str, &[&str])] = &[
    ("pool: order, active, hits", &["order[", "active[", "hits[", "a.order"]),
    ("pool: slots", &["slots["]),
    ("pool: camera vertices", &["vertices["]),
    ("pool: pending", &["pending[", "out[next"]),
    ("cache: entries", &["cache_entries"]),
    ("cache: vertices", &["push(", "cache_vert"]),
    ("scene: material index", &["material_of"]),
    ("scene: triangles", &["t[0]", "t[3]", "t[6]", "sc.tris", "vertices_of("]),
    ("scene: emission", &["e[0]", "emission"]),
    (
        "scene: lights",
        &[
            "light_cdf",
            "light_of_tri",
            "sc.lights",
            "l.normal",
            "l.value",
            "l.position",
            "l.kind",
            "l.area",
            "l.tri",
            "return true;",
        ],
    ),
    ("scene: materials", &["m.", "(m)", "materials", "two_sided", "scene_bsdf"]),
];

/// One class for every access (a kernel the emulator sees whole, such as PDACRT's).
pub const ALL_CLASSES: &[(&str, &[&str])] = &[("all", &[""])];

/// The class of a source line, or `"other"`.
pub fn classify<'a>(text: &str, classes: &[(&'a str, &[&str])]) -> &'a str {
    classes.iter().find(|(_, needles)| needles.iter().any(|n| text.contains(n))).map_or("other", |(name, _)| name)
}

/// Sums of one group of instructions.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sums {
    /// Warp instructions executed.
    pub warp: f64,
    /// Thread instructions executed.
    pub thread: f64,
    /// Sectors touched.
    pub sectors: f64,
}

impl Sums {
    pub(crate) fn add(&mut self, i: &Instruction) {
        self.warp += i.warp;
        self.thread += i.thread;
        self.sectors += i.sectors;
    }
    /// Thread instructions over 32 × warp instructions.
    pub fn simd_efficiency(&self) -> Option<f64> {
        (self.warp > 0.0).then(|| self.thread / (32.0 * self.warp))
    }
    /// Sectors per warp instruction (per request, for global accesses).
    pub fn sectors_per_request(&self) -> Option<f64> {
        (self.warp > 0.0).then(|| self.sectors / self.warp)
    }
}

/// One kernel's instructions split by class: every instruction, and the global loads
/// and stores per class (class names in the order given, then `other`).
#[derive(Clone, Debug, Default)]
pub struct Split {
    /// The kernel's short name (`cis::shade_sorted`).
    pub kernel: String,
    /// Launches summed.
    pub launches: usize,
    /// Every instruction.
    pub all: Sums,
    /// (operation, class, sums), operations `Load`, `Store` and `Atomic`.
    pub rows: Vec<(String, String, Sums)>,
}

impl Split {
    /// The sums of one operation over the classes whose names start with any of `prefixes`.
    pub fn of(&self, op: &str, prefixes: &[&str]) -> Sums {
        let mut s = Sums::default();
        for (o, c, r) in &self.rows {
            if o == op && prefixes.iter().any(|p| c.starts_with(p)) {
                s.warp += r.warp;
                s.thread += r.thread;
                s.sectors += r.sectors;
            }
        }
        s
    }
}

/// Each instruction with its kernel's short name and its launch's number within that
/// kernel (from 0).
pub(crate) fn numbered(insts: &[Instruction]) -> impl Iterator<Item = (String, usize, &Instruction)> {
    // (kernel, export launch) -> launch number within the kernel.
    let mut nth: HashMap<(String, usize), usize> = HashMap::new();
    let mut counts: HashMap<String, usize> = HashMap::new();
    insts.iter().map(move |i| {
        let name = super::ncu::short_name(&i.kernel);
        let k = *nth.entry((name.clone(), i.launch)).or_insert_with(|| {
            let c = counts.entry(name.clone()).or_default();
            *c += 1;
            *c - 1
        });
        (name, k, i)
    })
}

/// Per kernel (by short name), over the launches `keep` accepts (launch number within
/// that kernel, from 0).
pub fn split(insts: &[Instruction], classes: &[(&str, &[&str])], keep: impl Fn(&str, usize) -> bool) -> Vec<Split> {
    let mut out: Vec<Split> = Vec::new();
    for (name, k, i) in numbered(insts) {
        if !keep(&name, k) {
            continue;
        }
        let s = match out.iter().position(|s| s.kernel == name) {
            Some(p) => &mut out[p],
            None => {
                out.push(Split { kernel: name.clone(), ..Default::default() });
                out.last_mut().unwrap()
            }
        };
        s.launches = s.launches.max(k + 1);
        s.all.add(i);
        // Atomics with and without a result are one operation; the export labels a
        // global reduction (`REDG`) with no operation.
        let op = match i.op.as_str() {
            "Load" | "Store" => i.op.as_str(),
            "" if i.sass.starts_with("RED") || i.sass.starts_with("ATOM") => "Atomic",
            "" => continue,
            _ => "Atomic",
        };
        if i.space != "Global" {
            continue;
        }
        let class = classify(&i.text, classes);
        match s.rows.iter_mut().find(|(o, c, _)| *o == op && c == class) {
            Some((_, _, r)) => r.add(i),
            None => {
                let mut r = Sums::default();
                r.add(i);
                s.rows.push((op.to_string(), class.to_string(), r));
            }
        }
    }
    for s in &mut out {
        let order = |c: &str| classes.iter().position(|(n, _)| *n == c).unwrap_or(usize::MAX);
        s.rows.sort_by(|a, b| (a.0.as_str(), order(&a.1)).cmp(&(b.0.as_str(), order(&b.1))));
    }
    out
}

pub(crate) fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.digits$}"))
}

/// A split as a markdown table: per operation and class, requests, their share of the
/// kernel's warp instructions, SIMD efficiency and sectors per request.
pub fn table(s: &Split) -> String {
    let mut t = format!(
        "{} ({} launches; {:.0} warp instructions, SIMD efficiency {}):\n\n",
        s.kernel,
        s.launches,
        s.all.warp,
        opt(s.all.simd_efficiency(), 3)
    );
    t.push_str("| operation | accesses | requests | share of warp inst. | SIMD eff. | sectors / request |\n");
    t.push_str("|---|---|---:|---:|---:|---:|\n");
    for (op, class, r) in &s.rows {
        let share = (s.all.warp > 0.0).then(|| r.warp / s.all.warp);
        let _ = writeln!(
            t,
            "| {op} | {class} | {:.0} | {} | {} | {} |",
            r.warp,
            opt(share, 4),
            opt(r.simd_efficiency(), 3),
            opt(r.sectors_per_request(), 2)
        );
    }
    t
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Two launches of one kernel; an instruction listed under a system header and again
    /// under our line; a local load that is not global.
    pub(crate) const SAMPLE: &str = concat!(
        "\"Kernel Name\",\"cis::shade_sorted(cis::ShadeArgs)\",\n",
        "\"File Path\",\"/usr/include/c++/13/cmath\"\n",
        "\"Function Name\",\"cis::shade_sorted(cis::ShadeArgs)\"\n",
        "\"Line No\",\"Source\",\"Address\",\"Source\",\"Instructions Executed\",\"Thread Instructions Executed\",\"Address Space\",\"Access Operation\",\"L2 Theoretical Sectors Global\"\n",
        "\"1123\",\"{ return x; }\",\"-\",\"-\",\"10\",\"100\",\"-\",\"-\",\"0\"\n",
        "\"\",\"\",\"0x10\",\"LDG.E R0\",\"10\",\"100\",\"Global\",\"Load\",\"20\"\n",
        "\"File Path\",\"/w/cuda/cis_device.cuh\"\n",
        "\"309\",\"HD V3 ma(const WrMaterial& m) { return m.a; }\",\"-\",\"-\",\"10\",\"100\",\"-\",\"-\",\"0\"\n",
        "\"\",\"\",\"0x10\",\"LDG.E R0\",\"10\",\"100\",\"Global\",\"Load\",\"20\"\n",
        "\"949\",\"Slot slot = slots[slot_id];\",\"-\",\"-\",\"4\",\"128\",\"-\",\"-\",\"0\"\n",
        "\"\",\"\",\"0x20\",\"LDG.E.128 R4\",\"4\",\"128\",\"Global\",\"Load\",\"128\"\n",
        "\"\",\"\",\"0x30\",\"LDL R8\",\"6\",\"96\",\"Local\",\"Load\",\"0\"\n",
        "\"\",\"\",\"0x40\",\"FADD R1\",\"1,000\",\"16,000\",\"-\",\"-\",\"0\"\n",
        "\"\",\"\",\"0x50\",\"REDG.E.MIN.64.STRONG.GPU desc[UR4][R2.64], R4\",\"3\",\"3\",\"Global\",\"-\",\"3\"\n",
        "\"Kernel Name\",\"cis::shade_sorted(cis::ShadeArgs)\",\n",
        "\"File Path\",\"/w/cuda/cis_device.cuh\"\n",
        "\"Line No\",\"Source\",\"Address\",\"Source\",\"Instructions Executed\",\"Thread Instructions Executed\",\"Address Space\",\"Access Operation\",\"L2 Theoretical Sectors Global\"\n",
        "\"949\",\"Slot slot = slots[slot_id];\",\"-\",\"-\",\"2\",\"64\",\"-\",\"-\",\"0\"\n",
        "\"\",\"\",\"0x20\",\"LDG.E.128 R4\",\"2\",\"64\",\"Global\",\"Load\",\"64\"\n",
        // The next launch without a "Kernel Name" row: its file comes again.
        "\"File Path\",\"/w/cuda/cis_device.cuh\"\n",
        "\"Function Name\",\"cis::shade_sorted(cis::ShadeArgs)\"\n",
        "\"949\",\"Slot slot = slots[slot_id];\",\"-\",\"-\",\"1\",\"32\",\"-\",\"-\",\"0\"\n",
        "\"\",\"\",\"0x20\",\"LDG.E.128 R4\",\"1\",\"32\",\"Global\",\"Load\",\"32\"\n",
    );

    #[test]
    fn instructions_are_counted_once_under_our_line() {
        let insts = parse(SAMPLE).unwrap();
        // Launch 0: 0x10 (once), 0x20, 0x30, 0x40, 0x50; launch 1: 0x20; launch 2: 0x20.
        assert_eq!(insts.len(), 7);
        assert_eq!((insts[0].file.as_str(), insts[0].line), ("cis_device.cuh", 309));
        assert_eq!((insts[5].launch, insts[6].launch), (1, 2));
        let s = split(&insts, CIS_CLASSES, |_, _| true);
        assert_eq!(s.len(), 1);
        let s = &s[0];
        assert_eq!((s.kernel.as_str(), s.launches), ("cis::shade_sorted", 3));
        assert_eq!(s.all.warp, 10.0 + 4.0 + 6.0 + 1000.0 + 3.0 + 2.0 + 1.0);
        // The reduction is an atomic, one lane each.
        assert_eq!(s.of("Atomic", &["pool"]).simd_efficiency(), Some(1.0 / 32.0));
        let slots = s.of("Load", &["pool"]);
        assert_eq!((slots.warp, slots.thread, slots.sectors), (7.0, 224.0, 224.0));
        assert_eq!(slots.simd_efficiency(), Some(1.0));
        let scene = s.of("Load", &["scene"]);
        assert_eq!((scene.warp, scene.sectors_per_request()), (10.0, Some(2.0)));
        // Only the second launch.
        let second = split(&insts, CIS_CLASSES, |_, k| k == 1);
        assert_eq!(second[0].all.warp, 2.0);
        assert!(table(s).contains("| Load | scene: materials | 10 |"));
    }

    #[test]
    fn lines_are_classified_by_what_they_access() {
        assert_eq!(classify("uint32_t m = sc.material_of[tri];", CIS_CLASSES), "scene: material index");
        assert_eq!(classify("if (m.kind == 5) {", CIS_CLASSES), "scene: materials");
        assert_eq!(classify("HD void push(const Vertex& x) { v[len++] = x; }", CIS_CLASSES), "cache: vertices");
        assert_eq!(
            classify("for (int k = 0; k < depth; k++) cam[k] = vertices[vbase + k];", CIS_CLASSES),
            "pool: camera vertices"
        );
        assert_eq!(classify("x = y + z;", CIS_CLASSES), "other");
    }

    #[test]
    fn a_sass_export_sums_its_instructions_once_each() {
        let sass = concat!(
            "\"Kernel Name\",\"void k(int)\"\n",
            "\"Address\",\"Source\",\"Instructions Executed\",\"Thread Instructions Executed\"\n",
            "\"0x10\",\"      LDC R1, c[0x0][0x28]\",\"132\",\"4224\"\n",
            "\"0x20\",\"      LOP3.LUT R2, R2, 0xff, RZ, 0xc0, !PT\",\"1,320\",\"42,240\"\n",
        );
        assert_eq!(executed_warp_instructions(sass).unwrap(), 1452.0);
        assert!(executed_warp_instructions(SAMPLE).unwrap_err().contains("cuda,sass"));
        assert!(executed_warp_instructions(&sass.replace("1,320", "x")).unwrap_err().contains("line 4"));
        assert!(executed_warp_instructions("\"Kernel Name\",\"k\"\n").is_err());
    }

    #[test]
    fn malformed_exports_are_errors() {
        assert!(parse("no export here").is_err());
        assert!(parse("\"Kernel Name\",\"k\"\n\"x12\",\"src\"\n").unwrap_err().contains("line 2"));
        assert!(parse("\"Kernel Name\",\"k\"\n\"\",\"\",\"0x1\",\"LDG\"\n").unwrap_err().contains("before any header"));
    }
}
