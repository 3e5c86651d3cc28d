//! The lavatube learner: PPO (SPEC S6) on rollouts from the simulator, its update on the fused
//! engine (a hand-derived backward pass on worker threads, `ppo::fused`) or on burn's autodiff,
//! publishing the actor as a flat f32 vector in the `common::policy` layout, with crash-safe
//! checkpoints.
//!
//! Depends on `common` (transitions, config, policy layout, RNG), burn's CPU backend (`flex`),
//! `gemm` for the fused engine's products and `pulp` for its vector loops; links no other
//! process crate.
//!
//! Invariants:
//! - [`Learner::policy_weights`] is exactly what `common::Policy` evaluates: the same
//!   observation normalisation, layer order and tanh activations (tested to 1e-5).
//! - An update either completes or leaves the learner unchanged.
//! - Training is a pure function of seed, config and rollouts, whatever `ppo.threads`: a
//!   learner resumed from the checkpoint after update k produces bit-identical weights at
//!   update k + 1.
//! - A checkpoint file is whole or refused; saving never destroys the previous good one.
//!
//! The runtime's loop, one rollout chunk at a time, is [`serve::serve`]: resume or start,
//! update, append a metrics row, checkpoint when due, publish the weights, and after a
//! checkpoint redraw the learning curves ([`curves`]).

pub mod adam;
pub mod checkpoint;
pub mod cli;
pub mod curves;
mod error;
pub mod gae;
pub mod loss;
pub mod metrics;
pub mod net;
pub mod obs_norm;
pub mod ppo;
pub mod rounds;
pub mod serve;
mod simd;
mod writes;

pub use checkpoint::Checkpoint;
pub use cli::{Command, run};
pub use error::LearnerError;
pub use metrics::{EpisodeOutcome, MetricsLog, UpdateMetrics};
pub use ppo::{Counters, Learner, Rollout, SampledAction};

/// Tunes glibc's allocator for the update's allocation pattern; call once at process start.
///
/// Every tensor op allocates its output, and a minibatch of a 128-wide network allocates
/// blocks of 256 KiB and more. By default glibc serves such blocks by `mmap` and returns
/// freed heap tops to the kernel, so every minibatch page-faults its activations in afresh
/// (measured: 128-128 at minibatch 512 ran at ~95k samples/s instead of ~135k). Fixed
/// thresholds (32 MiB for `mmap`, 256 MiB before trimming) keep those pages mapped.
pub fn tune_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; it is called before any thread of ours
    // allocates concurrently, and glibc rejects out-of-range values by returning 0.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}
