//! Which ticks a recording logs: one per block of `every` ticks, so a file's size follows
//! the run's length, not the sim's speed or how many ticks a slow reader missed.

/// Takes the first tick seen in each block `[k·every, (k+1)·every)`: normally the ticks
/// that are multiples of `every`, and still one per block when ticks were dropped.
#[derive(Debug, Clone)]
pub struct Every {
    every: u64,
    last_block: Option<u64>,
}

impl Every {
    /// `every` is at least 1 (0 is taken as 1: log every tick).
    pub fn new(every: u64) -> Self {
        Self {
            every: every.max(1),
            last_block: None,
        }
    }

    /// Whether `tick` is logged; records it when it is.
    pub fn take(&mut self, tick: u64) -> bool {
        let block = tick / self.every;
        if self.last_block == Some(block) {
            return false;
        }
        self.last_block = Some(block);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_tick_per_block_even_when_ticks_are_missed() {
        let mut e = Every::new(10);
        let taken: Vec<u64> = (0..35).filter(|&t| e.take(t)).collect();
        assert_eq!(taken, [0, 10, 20, 30]);
        let mut e = Every::new(10);
        let taken: Vec<u64> = [3, 7, 12, 19, 41, 42]
            .into_iter()
            .filter(|&t| e.take(t))
            .collect();
        assert_eq!(taken, [3, 12, 41]);
        let mut every_tick = Every::new(0);
        assert!((0..5).all(|t| every_tick.take(t)));
    }
}
