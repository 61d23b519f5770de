//! What a benchmark reports beside its figures: the machine a measurement ran on (the
//! CPU's model, the vector extensions it has, the ones this binary was compiled to use)
//! and the median of interleaved rounds. Benchmarks print the machine beside their
//! tables (`dacrt_tables`, `animated`), so that every figure carries it.

/// The machine a benchmark runs on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Machine {
    /// The CPU's model name (`/proc/cpuinfo`), or "unknown".
    pub cpu: String,
    /// Logical CPUs the operating system offers this process.
    pub cpus: usize,
    /// x86 vector extensions the CPU has (run-time detection).
    pub extensions: Vec<&'static str>,
    /// Vector extensions this binary was compiled to assume (`target-cpu`/`target-feature`).
    pub compiled_for: Vec<&'static str>,
}

impl Machine {
    /// Reads this machine.
    pub fn this() -> Machine {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| s.lines().find(|l| l.starts_with("model name")).map(|l| l.to_string()))
            .and_then(|l| l.split_once(':').map(|(_, v)| v.trim().to_string()))
            .unwrap_or_else(|| "unknown".into());
        Machine {
            cpu,
            cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            extensions: detected(),
            compiled_for: compiled_for(),
        }
    }

    /// One JSON object (keys `cpu, cpus, extensions, compiled_for`).
    pub fn json(&self) -> String {
        let list = |v: &[&str]| v.iter().map(|e| format!("\"{e}\"")).collect::<Vec<_>>().join(",");
        format!(
            "{{\"cpu\":\"{}\",\"cpus\":{},\"extensions\":[{}],\"compiled_for\":[{}]}}",
            self.cpu.replace(['"', '\\'], "'"),
            self.cpus,
            list(&self.extensions),
            list(&self.compiled_for)
        )
    }
}

impl std::fmt::Display for Machine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let list = |v: &[&str]| if v.is_empty() { "baseline".to_string() } else { v.join(" ") };
        write!(
            f,
            "{} ({} CPUs; vector extensions: {}; binary compiled for: {})",
            self.cpu,
            self.cpus,
            list(&self.extensions),
            list(&self.compiled_for)
        )
    }
}

/// The median of a list of measurements (the mean of the middle two for an even
/// count; NaN for none).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(target_arch = "x86_64")]
fn detected() -> Vec<&'static str> {
    let mut v = Vec::new();
    macro_rules! probe {
        ($($f:tt),*) => { $( if std::arch::is_x86_feature_detected!($f) { v.push($f); } )* };
    }
    probe!("sse4.2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512vl");
    v
}

#[cfg(not(target_arch = "x86_64"))]
fn detected() -> Vec<&'static str> {
    Vec::new()
}

fn compiled_for() -> Vec<&'static str> {
    let mut v = Vec::new();
    macro_rules! compiled {
        ($($f:tt),*) => { $( if cfg!(target_feature = $f) { v.push($f); } )* };
    }
    compiled!("sse4.2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512vl");
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn describes_this_machine_as_valid_json() {
        let m = Machine::this();
        assert!(m.cpus >= 1);
        // Whatever the binary was compiled for, the CPU running it has.
        assert!(m.compiled_for.iter().all(|f| m.extensions.contains(f)), "{m}");
        let j = m.json();
        assert!(j.starts_with("{\"cpu\":\"") && j.ends_with("]}"), "{j}");
        assert!(m.to_string().contains("CPUs"));
    }

    #[test]
    fn median_of_odd_even_and_empty_lists() {
        assert_eq!(median(vec![5.0, 1.0, 3.0]), 3.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(Vec::new()).is_nan());
    }
}
