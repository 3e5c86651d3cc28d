//! A barrier for the update's worker threads that spins before it yields: a minibatch's three
//! phases last tens of microseconds, less than a futex wake-up, and every worker is busy
//! while an update runs. A worker that panics poisons it, so the others return instead of
//! waiting for it forever.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Spins this many times before yielding the core (about 10–50 µs): long enough for a
/// phase's stragglers, short enough to hand the core back when a worker was preempted.
const SPINS: u32 = 20_000;

/// Another worker panicked: the update is abandoned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Poisoned;

pub struct SpinBarrier {
    parties: usize,
    arrived: AtomicUsize,
    generation: AtomicUsize,
    poisoned: AtomicBool,
}

impl SpinBarrier {
    pub fn new(parties: usize) -> Self {
        Self {
            parties: parties.max(1),
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            poisoned: AtomicBool::new(false),
        }
    }

    /// Waits until all parties have arrived. Whatever a party did before its `wait` happens
    /// before what any party does after its own.
    pub fn wait(&self) -> Result<(), Poisoned> {
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) + 1 == self.parties {
            self.arrived.store(0, Ordering::Relaxed);
            self.generation.fetch_add(1, Ordering::AcqRel);
        } else {
            let mut spins = 0;
            while self.generation.load(Ordering::Acquire) == generation {
                if self.poisoned.load(Ordering::Relaxed) {
                    return Err(Poisoned);
                }
                if spins < SPINS {
                    spins += 1;
                    std::hint::spin_loop();
                } else {
                    std::thread::yield_now();
                }
            }
        }
        if self.poisoned.load(Ordering::Relaxed) {
            return Err(Poisoned);
        }
        Ok(())
    }

    /// Poisons the barrier when dropped during a panic: hold one in each worker.
    pub fn guard(&self) -> PoisonOnPanic<'_> {
        PoisonOnPanic(self)
    }
}

pub struct PoisonOnPanic<'a>(&'a SpinBarrier);

impl Drop for PoisonOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.poisoned.store(true, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    /// Each round every thread adds its id to a counter, waits, and reads the round's total:
    /// no thread may see a partial sum, so the barrier orders the phases.
    #[test]
    fn phases_do_not_overlap() {
        let barrier = SpinBarrier::new(3);
        let total = AtomicU64::new(0);
        std::thread::scope(|s| {
            for id in 1..=3u64 {
                let (barrier, total) = (&barrier, &total);
                s.spawn(move || {
                    for round in 0..200u64 {
                        total.fetch_add(id, Ordering::Relaxed);
                        barrier.wait().expect("no panic");
                        assert_eq!(total.load(Ordering::Relaxed), 6 * (round + 1));
                        barrier.wait().expect("no panic");
                    }
                });
            }
        });
    }

    #[test]
    fn a_panicking_party_releases_the_others() {
        let barrier = SpinBarrier::new(2);
        let result = std::thread::scope(|s| {
            let b = &barrier;
            let worker = s.spawn(move || {
                let _guard = b.guard();
                panic!("worker fails");
            });
            let waited = b.wait();
            assert!(worker.join().is_err());
            waited
        });
        assert_eq!(result, Err(Poisoned));
    }
}
