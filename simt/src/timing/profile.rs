//! What the time model knows of one GPU ([`GpuProfile`]) and the text files that hold
//! it (`simt/profiles/`, written by `gpu_check calibrate`; each value's source in a
//! comment after it).

use std::fmt::Write;

/// What the time model knows of one GPU. Rates are per second; sizes in bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuProfile {
    /// The GPU's name (`NVIDIA H200`).
    pub name: String,
    /// Streaming multiprocessors.
    pub sms: f64,
    /// SM clock while the kernels run, Hz.
    pub clock_hz: f64,
    /// Resident warps per SM at most.
    pub max_warps_per_sm: f64,
    /// Resident blocks per SM at most.
    pub max_blocks_per_sm: f64,
    /// Shared memory per SM, bytes.
    pub shared_per_sm_bytes: f64,
    /// 32-bit registers per SM (allocated per warp, 8 per thread at a time).
    pub registers_per_sm: f64,
    /// L2 cache, bytes.
    pub l2_bytes: f64,
    /// Warp instructions one SM issues per cycle with every scheduler busy.
    pub issue_per_cycle_per_sm: f64,
    /// Code, in bytes, that warps jumping about it no longer find in the SM's
    /// instruction cache: the smallest code the instruction-fetch probe found fetch-bound.
    pub fetch_thrash_code_bytes: f64,
    /// Warp instructions one SM issues per cycle at most from code of
    /// `fetch_thrash_code_bytes` that its warps jump about, whatever their number.
    pub fetch_issue_per_cycle_per_sm: f64,
    /// Cycles between two dependent arithmetic instructions of one warp.
    pub alu_latency_cycles: f64,
    /// Global-memory sectors one SM's L1 serves per cycle.
    pub l1_sectors_per_cycle_per_sm: f64,
    /// L2 bandwidth, bytes per second, for sectors read whole (coalesced requests).
    pub l2_bytes_per_s: f64,
    /// L2 bandwidth for sectors each request touches one word of (scattered 4-byte
    /// lanes), counted as whole sectors: bytes per second.
    pub l2_scattered_bytes_per_s: f64,
    /// HBM bandwidth, bytes per second.
    pub hbm_bytes_per_s: f64,
    /// Latency of a load served by L2, seconds.
    pub l2_latency_s: f64,
    /// Latency of a load served by HBM, seconds.
    pub hbm_latency_s: f64,
    /// Latency of an atomic whose old value is waited for, served by L2, seconds.
    pub atomic_latency_s: f64,
    /// Latency of a memory fence (`__threadfence`) after one stored sector, seconds.
    pub fence_latency_s: f64,
    /// What each further sector the fence waits for adds to its latency, seconds.
    pub fenced_sector_latency_s: f64,
    /// Warp fences the whole GPU completes per second with every SM fencing, not
    /// counting the sectors they wait for.
    pub fences_per_s: f64,
    /// Sectors written before a fence that the whole GPU's fences see through per
    /// second, every SM fencing (what a fence waits for costs beside the fence).
    pub fenced_sectors_per_s: f64,
    /// Atomic lane operations per second on distinct words.
    pub atomics_per_s: f64,
    /// Atomic lane operations per second on one word.
    pub same_address_atomics_per_s: f64,
    /// Block-wide barriers one SM completes per second.
    pub barriers_per_s_per_sm: f64,
    /// Cost of dispatching one block on one SM, seconds.
    pub block_dispatch_s: f64,
    /// Duration of an empty launch, seconds.
    pub launch_s: f64,
    /// How much of the smaller of a launch's memory bound and its issue bound its warps
    /// fail to hide under the larger when they run free of barriers (0: all of it
    /// hidden, a roofline; 1: none, the two add).
    pub exposed_free: f64,
    /// How much of the smaller of a launch's memory and execution bounds is not hidden
    /// where each SM holds one block whose barriers keep its warps in one phase, loads
    /// or arithmetic, at a time.
    pub exposed_one_block: f64,
    /// The same with many such blocks a SM (R blocks: this plus the one block's excess
    /// over it divided by R).
    pub exposed_many_blocks: f64,
}

/// The profiles shipped with simt, by name.
pub const PROFILES: &[(&str, &str)] = &[("h200", include_str!("../../profiles/h200.toml"))];

/// Keys of a profile file, in the order they are written, with the field each sets.
const KEYS: &[&str] = &[
    "sms",
    "clock_ghz",
    "max_warps_per_sm",
    "max_blocks_per_sm",
    "shared_per_sm_bytes",
    "registers_per_sm",
    "l2_bytes",
    "issue_per_cycle_per_sm",
    "fetch_thrash_code_kib",
    "fetch_issue_per_cycle_per_sm",
    "alu_latency_cycles",
    "l1_sectors_per_cycle_per_sm",
    "l2_gb_per_s",
    "l2_scattered_gb_per_s",
    "hbm_gb_per_s",
    "l2_latency_ns",
    "hbm_latency_ns",
    "atomic_latency_ns",
    "fence_latency_ns",
    "fenced_sector_latency_ns",
    "fences_per_ns",
    "fenced_sectors_per_ns",
    "atomics_per_ns",
    "same_address_atomics_per_ns",
    "barriers_per_us_per_sm",
    "block_dispatch_ns",
    "launch_us",
    "overlap_exposed_free",
    "overlap_exposed_one_block",
    "overlap_exposed_many_blocks",
];

/// Keys whose values are shares, from 0 to 1 (every other key is a positive amount).
const SHARES: &[&str] = &["overlap_exposed_free", "overlap_exposed_one_block", "overlap_exposed_many_blocks"];

impl GpuProfile {
    /// A shipped profile by name (`h200`).
    pub fn named(name: &str) -> Result<GpuProfile, String> {
        let (_, text) = PROFILES.iter().find(|(n, _)| *n == name).ok_or_else(|| {
            let known: Vec<&str> = PROFILES.iter().map(|(n, _)| *n).collect();
            format!("no GPU profile named '{name}' (known: {})", known.join(", "))
        })?;
        GpuProfile::parse(text).map_err(|e| format!("simt/profiles/{name}.toml: {e}"))
    }

    /// A shipped profile by name, or else a profile file at that path (what the
    /// command line's `--gpu-profile` and `gpu_check time --gpu-profile` take).
    pub fn load(name_or_path: &str) -> Result<GpuProfile, String> {
        if std::path::Path::new(name_or_path).is_file() {
            let text = std::fs::read_to_string(name_or_path).map_err(|e| format!("{name_or_path}: {e}"))?;
            GpuProfile::parse(&text).map_err(|e| format!("{name_or_path}: {e}"))
        } else {
            GpuProfile::named(name_or_path)
        }
    }

    /// Reads a profile: `key = value` lines (`name = "..."`, numbers), `#` comments.
    /// Every key must be present once, finite and positive; errors name the line.
    pub fn parse(text: &str) -> Result<GpuProfile, String> {
        let mut name = None;
        let mut values = vec![None; KEYS.len()];
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let (key, value) = line.split_once('=').ok_or_else(|| format!("line {}: expected 'key = value'", i + 1))?;
            let (key, value) = (key.trim(), value.trim());
            if key == "name" {
                name = Some(value.trim_matches('"').to_string());
                continue;
            }
            let k =
                KEYS.iter().position(|&k| k == key).ok_or_else(|| format!("line {}: unknown key '{key}'", i + 1))?;
            let v: f64 = value.parse().map_err(|_| format!("line {}: {key}: '{value}' is not a number", i + 1))?;
            if SHARES.contains(&key) {
                if !(0.0..=1.0).contains(&v) {
                    return Err(format!("line {}: {key}: {v} must be a share from 0 to 1", i + 1));
                }
            } else if !(v.is_finite() && v > 0.0) {
                return Err(format!("line {}: {key}: {v} must be finite and positive", i + 1));
            }
            if values[k].replace(v).is_some() {
                return Err(format!("line {}: {key} given twice", i + 1));
            }
        }
        let get = |k: &str| -> Result<f64, String> {
            values[KEYS.iter().position(|&x| x == k).unwrap()].ok_or_else(|| {
                if SHARES.contains(&k) {
                    // Profiles written before the overlap probes existed lack these.
                    format!("missing key '{k}' (run MODE=overlap sh cuda/microbench.sh and calibrate again)")
                } else if k.starts_with("fetch_") {
                    format!("missing key '{k}' (run MODE=icache sh cuda/microbench.sh and calibrate again)")
                } else {
                    format!("missing key '{k}'")
                }
            })
        };
        Ok(GpuProfile {
            name: name.ok_or("missing key 'name'")?,
            sms: get("sms")?,
            clock_hz: get("clock_ghz")? * 1e9,
            max_warps_per_sm: get("max_warps_per_sm")?,
            max_blocks_per_sm: get("max_blocks_per_sm")?,
            shared_per_sm_bytes: get("shared_per_sm_bytes")?,
            registers_per_sm: get("registers_per_sm")?,
            l2_bytes: get("l2_bytes")?,
            issue_per_cycle_per_sm: get("issue_per_cycle_per_sm")?,
            fetch_thrash_code_bytes: get("fetch_thrash_code_kib")? * 1024.0,
            fetch_issue_per_cycle_per_sm: get("fetch_issue_per_cycle_per_sm")?,
            alu_latency_cycles: get("alu_latency_cycles")?,
            l1_sectors_per_cycle_per_sm: get("l1_sectors_per_cycle_per_sm")?,
            l2_bytes_per_s: get("l2_gb_per_s")? * 1e9,
            l2_scattered_bytes_per_s: get("l2_scattered_gb_per_s")? * 1e9,
            hbm_bytes_per_s: get("hbm_gb_per_s")? * 1e9,
            l2_latency_s: get("l2_latency_ns")? * 1e-9,
            hbm_latency_s: get("hbm_latency_ns")? * 1e-9,
            atomic_latency_s: get("atomic_latency_ns")? * 1e-9,
            fence_latency_s: get("fence_latency_ns")? * 1e-9,
            fenced_sector_latency_s: get("fenced_sector_latency_ns")? * 1e-9,
            fences_per_s: get("fences_per_ns")? * 1e9,
            fenced_sectors_per_s: get("fenced_sectors_per_ns")? * 1e9,
            atomics_per_s: get("atomics_per_ns")? * 1e9,
            same_address_atomics_per_s: get("same_address_atomics_per_ns")? * 1e9,
            barriers_per_s_per_sm: get("barriers_per_us_per_sm")? * 1e6,
            block_dispatch_s: get("block_dispatch_ns")? * 1e-9,
            launch_s: get("launch_us")? * 1e-6,
            exposed_free: get("overlap_exposed_free")?,
            exposed_one_block: get("overlap_exposed_one_block")?,
            exposed_many_blocks: get("overlap_exposed_many_blocks")?,
        })
    }

    /// The profile as a file [`GpuProfile::parse`] reads back; `source` gives each
    /// key's provenance (a comment after its value), `header` the lines on top.
    pub fn to_text(&self, header: &str, source: impl Fn(&str) -> String) -> String {
        let mut s = String::new();
        for line in header.lines() {
            let _ = writeln!(s, "# {line}");
        }
        let _ = writeln!(s, "name = \"{}\"", self.name);
        let values = [
            self.sms,
            self.clock_hz / 1e9,
            self.max_warps_per_sm,
            self.max_blocks_per_sm,
            self.shared_per_sm_bytes,
            self.registers_per_sm,
            self.l2_bytes,
            self.issue_per_cycle_per_sm,
            self.fetch_thrash_code_bytes / 1024.0,
            self.fetch_issue_per_cycle_per_sm,
            self.alu_latency_cycles,
            self.l1_sectors_per_cycle_per_sm,
            self.l2_bytes_per_s / 1e9,
            self.l2_scattered_bytes_per_s / 1e9,
            self.hbm_bytes_per_s / 1e9,
            self.l2_latency_s * 1e9,
            self.hbm_latency_s * 1e9,
            self.atomic_latency_s * 1e9,
            self.fence_latency_s * 1e9,
            self.fenced_sector_latency_s * 1e9,
            self.fences_per_s / 1e9,
            self.fenced_sectors_per_s / 1e9,
            self.atomics_per_s / 1e9,
            self.same_address_atomics_per_s / 1e9,
            self.barriers_per_s_per_sm / 1e6,
            self.block_dispatch_s * 1e9,
            self.launch_s * 1e6,
            self.exposed_free,
            self.exposed_one_block,
            self.exposed_many_blocks,
        ];
        for (k, v) in KEYS.iter().zip(values) {
            let _ = writeln!(s, "{k} = {}  # {}", round4(v), source(k));
        }
        s
    }
}

/// Four significant digits, as plain text.
fn round4(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let digits = (3 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}
