//! The critic's values for a whole rollout on the fused engine: fixed chunks of rows spread
//! over the update's workers, each chunk one forward pass, so the values (and the advantages
//! built from them) are the same bits for any thread count.

use common::OBS_DIM;

use super::mlp::Mlp;
use super::plan::Net;
use crate::ppo::{IN, Learner};

/// Rows per forward pass.
const CHUNK: usize = 256;

impl Learner {
    /// Values of network input rows `x` (`[rows, obs + 1]`, the last column the bias unit).
    pub(in crate::ppo) fn values_fused(&self, x: &[f32]) -> Vec<f32> {
        let rows = x.len() / IN;
        let critic = Mlp::new(
            self.shape.dense(true).collect(),
            Net::Critic.range(&self.shape).start,
        );
        let mut values = vec![0.0f32; rows];
        let chunks = rows.div_ceil(CHUNK);
        let threads = self.threads.clamp(1, chunks.max(1));
        let mut shares: Vec<Vec<(usize, &mut [f32])>> = (0..threads).map(|_| Vec::new()).collect();
        for (c, out) in values.chunks_mut(CHUNK).enumerate() {
            shares[c % threads].push((c, out));
        }
        let run = |share: Vec<(usize, &mut [f32])>| {
            let mut acts = critic.buffers(CHUNK);
            let mut input = Vec::with_capacity(CHUNK * OBS_DIM);
            for (c, out) in share {
                input.clear();
                for row in x[c * CHUNK * IN..].chunks_exact(IN).take(out.len()) {
                    input.extend_from_slice(&row[..OBS_DIM]);
                }
                out.copy_from_slice(critic.forward(&self.params, &input, out.len(), &mut acts));
            }
        };
        std::thread::scope(|s| {
            let mut shares = shares.into_iter();
            let mine = shares.next().unwrap_or_default();
            for share in shares {
                s.spawn(|| run(share));
            }
            run(mine);
        });
        values
    }
}
