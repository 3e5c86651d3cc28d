//! How much of a run a recording keeps: the two knobs that set a file's size.

/// Logging every 10th tick keeps a default run (9 envs, 2.5 M env steps: ≈ 278 k ticks,
/// ≈ 27.8 k logged) at ≈ 22 MB: ≈ 2.3 MB of floor mesh, then ≈ 730 bytes per logged tick
/// with trails of [`DEFAULT_TRAIL`] points (measured by replaying a sim telemetry CSV through
/// [`crate::Recording`] with estimates). Every tick would be ≈ 10× that.
pub const DEFAULT_EVERY: u64 = 10;
/// Trail points per robot: its last this many logged positions. At the default `every`,
/// 500 ticks, longer than the longest default episode (400 ticks), so a trail shows the
/// episode's whole path (trails start over with each episode).
pub const DEFAULT_TRAIL: usize = 50;

/// What a recording keeps, shared by `serve` and `convert`.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct RecordOptions {
    /// Log every this-many-th tick (the first tick seen in each block of this many), 1 ..= 1000000.
    #[arg(long, default_value_t = DEFAULT_EVERY, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub every: u64,
    /// Positions in each robot's trail (its last logged positions), 2 ..= 10000.
    #[arg(long, default_value_t = DEFAULT_TRAIL, value_parser = parse_trail)]
    pub trail: usize,
}

impl Default for RecordOptions {
    fn default() -> Self {
        Self {
            every: DEFAULT_EVERY,
            trail: DEFAULT_TRAIL,
        }
    }
}

/// A trail length: an integer in 2..=10000 (one point draws no line).
fn parse_trail(s: &str) -> Result<usize, String> {
    common::cli::parse_count(s, "trail length", (2, 10_000))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trail_lengths_are_checked() {
        assert_eq!(parse_trail("50"), Ok(50));
        assert!(parse_trail("1").is_err());
        assert!(parse_trail("x").is_err());
    }
}
