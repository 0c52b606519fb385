//! Memory limits, so that a request too big for the machine is refused with an
//! estimate before it starts instead of being killed half-way.

/// How much memory the engine may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Bytes for the state space plus one empowerment table.
    pub max_bytes: usize,
}

impl Default for Limits {
    /// `FULCRUM_MAX_MEMORY` (bytes, or with a unit: `512MiB`, `8GiB`) when set; else half
    /// of the memory available now (`MemAvailable` in /proc/meminfo), or 4 GiB where that
    /// cannot be read.
    fn default() -> Self {
        if let Some(b) = std::env::var("FULCRUM_MAX_MEMORY")
            .ok()
            .and_then(|v| parse_bytes(&v))
        {
            return Limits { max_bytes: b };
        }
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

/// Parse `123`, `64KiB`, `512MiB`, `8GiB` (also KB/MB/GB as powers of 1024).
pub fn parse_bytes(text: &str) -> Option<usize> {
    let t = text.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: usize = num.parse().ok()?;
    let mul: usize = match unit.trim() {
        "" | "B" => 1,
        "KiB" | "KB" | "K" => 1 << 10,
        "MiB" | "MB" | "M" => 1 << 20,
        "GiB" | "GB" | "G" => 1 << 30,
        _ => return None,
    };
    n.checked_mul(mul)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_sizes() {
        assert_eq!(parse_bytes("64MiB"), Some(64 << 20));
        assert_eq!(parse_bytes("2GiB"), Some(2 << 30));
        assert_eq!(parse_bytes("1000"), Some(1000));
        assert_eq!(parse_bytes("lots"), None);
        assert_eq!(human_bytes(64 << 20), "64.0 MiB");
    }
}
