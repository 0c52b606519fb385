//! Memory limits, so that a request too big for the machine is refused with an
//! estimate before it starts instead of being killed half-way.

/// How much memory the engine may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Bytes for the state space plus one empowerment table.
    pub max_bytes: usize,
}

impl Default for Limits {
    /// Half of the memory available now (`MemAvailable` in /proc/meminfo), or 4 GiB where
    /// that cannot be read.
    fn default() -> Self {
        let avail = std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|t| {
                t.lines()
                    .find(|l| l.starts_with("MemAvailable:"))
                    .and_then(|l| l.split_whitespace().nth(1))
                    .and_then(|kb| kb.parse::<usize>().ok())
            })
            .map(|kb| kb * 1024);
        Limits {
            max_bytes: avail.map_or(4 << 30, |b| b / 2),
        }
    }
}

/// Bytes as a short human string (`1.5 GiB`).
pub fn human_bytes(b: usize) -> String {
    let b = b as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.1} GiB", b / (1u64 << 30) as f64)
    } else if b >= (1 << 20) as f64 {
        format!("{:.1} MiB", b / (1 << 20) as f64)
    } else {
        format!("{:.0} KiB", (b / 1024.0).ceil())
    }
}
