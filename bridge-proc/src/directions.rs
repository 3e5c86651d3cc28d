//! A bridge's two directions: each on its own thread, both ending when either ends, and
//! what went through each.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Frames and bytes through one direction of a bridge.
#[derive(Debug, Default, Clone, Copy)]
pub struct Counts {
    pub frames: u64,
    pub bytes: u64,
}

impl Counts {
    pub(crate) fn add(&mut self, bytes: usize) {
        self.frames += 1;
        self.bytes += bytes as u64;
    }
}

/// Set when either of a bridge's two threads ends, so the other ends too.
#[derive(Debug, Default, Clone)]
pub struct Stop(Arc<AtomicBool>);

impl Stop {
    pub(crate) fn set(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    pub(crate) fn is_set(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// Runs `beside` on a thread named `name` and `here` on this one, each until it ends or the
/// other has ended (a bridge's two directions); fails if either failed.
pub(crate) fn both_directions(
    name: &str,
    beside: impl FnOnce(&Stop) -> anyhow::Result<()> + Send + 'static,
    here: impl FnOnce(&Stop) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let stop = Stop::default();
    let thread = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                let r = beside(&stop);
                stop.set();
                r
            })?
    };
    let r = here(&stop);
    stop.set();
    let other = thread
        .join()
        .map_err(|_| anyhow::anyhow!("the {name} thread panicked"))?;
    r.and(other)
}
