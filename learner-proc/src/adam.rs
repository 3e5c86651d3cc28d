//! Adam and global gradient-norm clipping over the learner's flat parameter vector.
//!
//! burn's optimizers clip each tensor on its own; PPO clips the norm of the whole gradient
//! (PyTorch's `clip_grad_norm_`), which changes the direction of the update when one tensor
//! dominates. The parameters live on the host as one f32 vector anyway (the wire format), so
//! the optimizer runs there: clipping sees every gradient at once, the moments are plain
//! vectors that checkpoint bit-exactly, and no tensor round trip is spent per parameter.

use serde::{Deserialize, Serialize};

/// Scales `grads` in place so their joint L2 norm is at most `max_norm`, as PyTorch's
/// `clip_grad_norm_` does (`coef = max_norm / (norm + 1e-6)`, applied when below 1).
/// Returns the norm before clipping.
pub fn clip_global_norm(grads: &mut [f32], max_norm: f32) -> f32 {
    let norm = crate::simd::sum_of_squares(grads).sqrt() as f32;
    if let Some(coef) = clip_coef(norm, max_norm) {
        grads.iter_mut().for_each(|g| *g *= coef);
    }
    norm
}

/// The factor that brings a gradient of L2 norm `norm` to at most `max_norm`, or `None` when
/// it is within the limit already.
pub fn clip_coef(norm: f32, max_norm: f32) -> Option<f32> {
    let coef = max_norm / (norm + 1e-6);
    (coef < 1.0).then_some(coef)
}

/// Adam (Kingma & Ba) with PyTorch's defaults β = (0.9, 0.999) and a configurable ε.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Adam {
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    /// Steps taken so far (the bias-correction exponent).
    pub step: u64,
    /// First moment, one per parameter.
    pub m: Vec<f32>,
    /// Second moment, one per parameter.
    pub v: Vec<f32>,
}

impl Adam {
    pub fn new(len: usize, eps: f32) -> Self {
        Self {
            beta1: 0.9,
            beta2: 0.999,
            eps,
            step: 0,
            m: vec![0.0; len],
            v: vec![0.0; len],
        }
    }

    /// CRC-32 of the step count and both moments: a short fingerprint that shows, in logs,
    /// which optimizer state a (resumed) learner holds.
    pub fn digest(&self) -> u32 {
        let mut h = crc32fast::Hasher::new();
        h.update(&self.step.to_le_bytes());
        for x in self.m.iter().chain(&self.v) {
            h.update(&x.to_le_bytes());
        }
        h.finalize()
    }

    /// One step: `params -= lr · m̂ / (sqrt(v̂) + ε)`.
    pub fn step(&mut self, params: &mut [f32], grads: &[f32], lr: f32) {
        debug_assert!(params.len() == self.m.len() && grads.len() == self.m.len());
        self.step += 1;
        self.at(self.step, lr)
            .apply(params, grads, 1.0, &mut self.m, &mut self.v);
    }

    /// The constants of step `t` (1-based) at learning rate `lr`, to apply to a part of the
    /// parameters with that part's moments.
    pub fn at(&self, t: u64, lr: f32) -> AdamStep {
        let t = i32::try_from(t).unwrap_or(i32::MAX);
        let bias1 = 1.0 - f64::from(self.beta1).powi(t);
        let bias2 = 1.0 - f64::from(self.beta2).powi(t);
        AdamStep {
            beta1: self.beta1,
            beta2: self.beta2,
            eps: self.eps,
            step_size: (f64::from(lr) / bias1) as f32,
            bias2_sqrt: bias2.sqrt() as f32,
        }
    }
}

/// One Adam step's constants ([`Adam::at`]); elementwise, so it can update the parameters a
/// part at a time.
#[derive(Debug, Clone, Copy)]
pub struct AdamStep {
    beta1: f32,
    beta2: f32,
    eps: f32,
    step_size: f32,
    bias2_sqrt: f32,
}

impl AdamStep {
    /// Updates `params` and their moments `m`, `v` with `grads` (all the same length), each
    /// gradient multiplied first by `scale` (a clipping factor, [`clip_coef`]; 1 leaves the
    /// gradient's bits as they are). One pass, where clipping then stepping would be two.
    pub fn apply(
        &self,
        params: &mut [f32],
        grads: &[f32],
        scale: f32,
        m: &mut [f32],
        v: &mut [f32],
    ) {
        let (b1, b2, eps) = (self.beta1, self.beta2, self.eps);
        crate::simd::vectorized(|| {
            for (((p, &g), m), v) in params.iter_mut().zip(grads).zip(m).zip(v) {
                let g = g * scale;
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                *p -= self.step_size * *m / (v.sqrt() / self.bias2_sqrt + eps);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn global_norm_clipping_scales_all_tensors_together() {
        // Two "tensors" [3] and [4]: joint norm 5. Per-tensor clipping at 0.5 would give
        // [0.5] and [0.5]; global clipping keeps the 3:4 direction.
        let mut g = [3.0, 4.0];
        let norm = clip_global_norm(&mut g, 0.5);
        assert_eq!(norm, 5.0);
        let coef = 0.5 / (5.0 + 1e-6);
        assert!((g[0] - 3.0 * coef).abs() < 1e-7 && (g[1] - 4.0 * coef).abs() < 1e-7);
        let mut small = [0.1, -0.2];
        clip_global_norm(&mut small, 0.5);
        assert_eq!(small, [0.1, -0.2], "under the limit nothing changes");
    }

    #[test]
    fn the_digest_covers_step_and_both_moments() {
        let mut a = Adam::new(2, 1e-5);
        let base = a.digest();
        assert_eq!(base, Adam::new(2, 1e-5).digest());
        a.v[1] = 1e-9;
        assert_ne!(a.digest(), base);
        a.v[1] = 0.0;
        a.step = 1;
        assert_ne!(a.digest(), base);
    }

    /// Scaling inside the step gives the bits of clipping first, then stepping.
    #[test]
    fn a_scaled_step_is_clipping_then_stepping() {
        let grads = [3.0f32, -4.0, 0.25];
        let mut clipped = grads;
        let norm = clip_global_norm(&mut clipped, 0.5);
        let coef = clip_coef(norm, 0.5).expect("over the limit");
        let (mut a, mut b) = (Adam::new(3, 1e-5), Adam::new(3, 1e-5));
        let (mut pa, mut pb) = ([1.0f32, 2.0, 3.0], [1.0f32, 2.0, 3.0]);
        let step = a.at(1, 0.01);
        step.apply(&mut pa, &clipped, 1.0, &mut a.m, &mut a.v);
        step.apply(&mut pb, &grads, coef, &mut b.m, &mut b.v);
        assert_eq!((pa, &a.m, &a.v), (pb, &b.m, &b.v));
        assert_ne!(pa, [1.0, 2.0, 3.0]);
    }

    /// Hand-computed: step 1 gives m̂ = g, v̂ = g², so each parameter moves by
    /// lr·g/(|g| + ε); step 2 with g = 0.5 then 1.0 on the same parameter:
    /// m = 0.1·0.5·0.9 + 0.1·1 = 0.145, v = 0.001·0.25·0.999 + 0.001·1 = 0.00124975,
    /// m̂ = 0.145/0.19, v̂ = 0.00124975/0.001999.
    #[test]
    fn adam_matches_hand_computed_steps() {
        let (lr, eps) = (0.01f32, 1e-5f32);
        let mut adam = Adam::new(2, eps);
        let mut p = [1.0f32, -2.0];
        adam.step(&mut p, &[0.5, -4.0], lr);
        assert!((p[0] - (1.0 - lr * 0.5 / (0.5 + eps))).abs() < 1e-7);
        assert!((p[1] - (-2.0 + lr * 4.0 / (4.0 + eps))).abs() < 1e-7);
        let p0 = p[0];
        adam.step(&mut p, &[1.0, 0.0], lr);
        let m_hat = 0.145f64 / 0.19;
        let v_hat = 0.001_249_75f64 / 0.001_999;
        let want = f64::from(p0) - f64::from(lr) * m_hat / (v_hat.sqrt() + f64::from(eps));
        assert!((f64::from(p[0]) - want).abs() < 1e-6, "{} vs {want}", p[0]);
        assert_eq!(adam.step, 2);
    }
}
