//! Limits shared by the scene loaders and the renderer, kept below both so that
//! neither has to import the other for them.

/// Longest time budget a render accepts, seconds (about 116 days; a `Duration` of
/// 1e30 s does not exist).
pub const MAX_SECONDS: f64 = 1.0e7;

/// Longest full path (light and camera vertices together) the bidirectional
/// integrators handle: `max_depth + 2` vertices, so the deepest `max_depth` every
/// integrator supports is `MAX_PATH_VERTICES - 2`.
pub const MAX_PATH_VERTICES: usize = 64;

/// Bytes a loaded scene takes per triangle with a caster built: 480, peak resident
/// memory (`/usr/bin/time -f %M`, 16² path render) with the hungriest caster, obvhs'
/// BVH: the dragon (871K triangles) 329 MB (188 MB with the default BVH4, 132 MB with
/// DACRT); the bunny (69K) 39 MB; rounded up by a quarter.
pub const BYTES_PER_TRIANGLE: u64 = 480;

/// The environment variable that sets the memory budget: bytes, or a number with a
/// suffix K, M, G or T (powers of 1024), e.g. `WARPRAY_MEMORY_BUDGET=32G`.
pub const MEMORY_BUDGET_VAR: &str = "WARPRAY_MEMORY_BUDGET";

/// What an input would need beyond the memory budget: the estimate and the budget, in
/// bytes. Callers say which input (a file and line, a render's size).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OverBudget {
    /// Estimated bytes needed.
    pub need: u64,
    /// The budget, bytes.
    pub budget: u64,
}

impl std::fmt::Display for OverBudget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "needs about {}, more than the memory budget of {} ({MEMORY_BUDGET_VAR} sets it; by default three \
             quarters of this machine's memory)",
            gib(self.need),
            gib(self.budget)
        )
    }
}

fn gib(bytes: u64) -> String {
    format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
}

/// The memory budget in bytes: [`MEMORY_BUDGET_VAR`] when set, else three quarters of
/// the machine's memory (the smaller of `/proc/meminfo`'s total and a cgroup limit),
/// else 8 GiB where neither can be read. A set variable that is not a size is an error
/// naming it.
pub fn memory_budget() -> Result<u64, String> {
    match std::env::var(MEMORY_BUDGET_VAR) {
        Ok(v) => parse_size(&v).ok_or_else(|| {
            format!("{MEMORY_BUDGET_VAR}={v:?} is not a size (bytes, or a number with K, M, G or T, e.g. 32G)")
        }),
        Err(_) => Ok(machine_memory().map_or(8 << 30, |m| m / 4 * 3)),
    }
}

/// Checks that `need` bytes fit the memory budget; the error says by how much not.
pub fn check_memory(need: u64) -> Result<(), String> {
    let budget = memory_budget()?;
    if need > budget { Err(OverBudget { need, budget }.to_string()) } else { Ok(()) }
}

/// Checks that a scene of `triangles` triangles ([`BYTES_PER_TRIANGLE`] each) fits the
/// memory budget.
pub fn check_triangles(triangles: u64) -> Result<(), String> {
    check_memory(triangles.saturating_mul(BYTES_PER_TRIANGLE))
}

/// A size in bytes: digits, optionally with a fraction, and an optional suffix K, M, G
/// or T (or KiB … TiB, KB … TB, all powers of 1024).
fn parse_size(s: &str) -> Option<u64> {
    let s = s.trim();
    let split = s.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(s.len());
    let (num, unit) = s.split_at(split);
    let x: f64 = num.parse().ok()?;
    let shift = match unit.trim().to_ascii_uppercase().trim_end_matches("IB").trim_end_matches('B') {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return None,
    };
    let bytes = x * (1u64 << shift) as f64;
    (bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64).then_some(bytes as u64)
}

/// The machine's memory in bytes, where Linux says: the smaller of `MemTotal` and the
/// cgroup's `memory.max`.
fn machine_memory() -> Option<u64> {
    static MEMORY: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    *MEMORY.get_or_init(read_machine_memory)
}

/// [`machine_memory`], read from the files (once per process).
fn read_machine_memory() -> Option<u64> {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|m| {
        let line = m.lines().find(|l| l.starts_with("MemTotal:"))?;
        line.split_whitespace().nth(1)?.parse::<u64>().ok().map(|kib| kib << 10)
    })?;
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok().and_then(|s| s.trim().parse::<u64>().ok());
    Some(cgroup.map_or(total, |c| c.min(total)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_and_without_units() {
        assert_eq!(parse_size("1024"), Some(1024));
        assert_eq!(parse_size("32G"), Some(32 << 30));
        assert_eq!(parse_size("1.5 GiB"), Some(3 << 29));
        assert_eq!(parse_size("512mb"), Some(512 << 20));
        for bad in ["", "G", "-1G", "1Q", "nan", "inf", "0", "1e30T", "99999999999999999999T"] {
            assert_eq!(parse_size(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn over_budget_says_both_sizes() {
        let e = OverBudget { need: 18 << 30, budget: 12 << 30 }.to_string();
        assert!(e.contains("18.0 GiB") && e.contains("12.0 GiB") && e.contains(MEMORY_BUDGET_VAR), "{e}");
    }
}
