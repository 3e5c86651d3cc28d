//! PPO's loss (SPEC S6) on a shard of a minibatch and its gradient with respect to the networks'
//! outputs, derived by hand (the burn engine's autodiff computes the same from
//! [`crate::loss`]): the clipped surrogate under the diagonal Gaussian policy, the
//! (optionally clipped) value loss. Means are over the whole minibatch, so the shards'
//! gradients add up to the minibatch's.

use common::ACT_DIM;
use common::policy::HALF_LN_2PI;

/// One shard's rows of a minibatch, gathered from the batch.
pub(super) struct ShardRows<'a> {
    pub actions: &'a [f32],
    pub logprobs: &'a [f32],
    /// Normalised over the whole minibatch when `ppo.norm-adv`.
    pub advantages: &'a [f32],
    pub values: &'a [f32],
    pub returns: &'a [f32],
}

/// The loss settings and the minibatch's size `m`, the divisor of every mean.
#[derive(Clone, Copy)]
pub(super) struct HeadSettings {
    pub clip_coef: f32,
    pub clip_vloss: bool,
    pub vf_coef: f32,
    pub m: usize,
}

/// A shard's sums, added over shards in shard order and divided by the minibatch size.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct ShardSums {
    pub pg_loss: f64,
    /// Σ (V − R)², or its pessimistic clipped form; the loss is half its mean.
    pub v_loss: f64,
    pub old_approx_kl: f64,
    pub approx_kl: f64,
    pub clipped: f64,
    /// The policy's entropy, from the minibatch's first shard.
    pub entropy: Option<f64>,
}

impl ShardSums {
    pub(super) fn add(&mut self, o: &Self) {
        self.pg_loss += o.pg_loss;
        self.v_loss += o.v_loss;
        self.old_approx_kl += o.old_approx_kl;
        self.approx_kl += o.approx_kl;
        self.clipped += o.clipped;
        self.entropy = self.entropy.or(o.entropy);
    }
}

/// The policy head: `mean` `[rows, act]` and `log_std` give each row's log-probability; writes
/// `d_mean` and returns the surrogate's gradient on the log-std (without the entropy bonus,
/// which belongs to the minibatch once).
pub(super) fn policy_head(
    rows: &ShardRows,
    mean: &[f32],
    log_std: &[f32],
    s: HeadSettings,
    d_mean: &mut [f32],
    sums: &mut ShardSums,
) -> [f32; ACT_DIM] {
    let inv_std: [f32; ACT_DIM] = std::array::from_fn(|a| (-log_std[a]).exp());
    let norm = log_std.iter().sum::<f32>() + ACT_DIM as f32 * HALF_LN_2PI;
    let m = s.m as f32;
    let mut d_log_std = [0.0f32; ACT_DIM];
    for (i, (mu, dmu)) in mean
        .chunks_exact(ACT_DIM)
        .zip(d_mean.chunks_exact_mut(ACT_DIM))
        .enumerate()
    {
        let z: [f32; ACT_DIM] =
            std::array::from_fn(|a| (rows.actions[i * ACT_DIM + a] - mu[a]) * inv_std[a]);
        let logprob = -0.5 * z.iter().map(|z| z * z).sum::<f32>() - norm;
        let logratio = logprob - rows.logprobs[i];
        let ratio = logratio.exp();
        let lr = f64::from(logratio);
        let r = lr.exp();
        sums.old_approx_kl -= lr;
        sums.approx_kl += (r - 1.0) - lr;
        if (r - 1.0).abs() > f64::from(s.clip_coef) {
            sums.clipped += 1.0;
        }
        let adv = rows.advantages[i];
        let unclipped = -adv * ratio;
        let clipped = -adv * ratio.clamp(1.0 - s.clip_coef, 1.0 + s.clip_coef);
        sums.pg_loss += f64::from(unclipped.max(clipped));
        // Where the clipped term wins, the ratio is outside the clip range and has no
        // gradient; inside it the two terms agree.
        let d_ratio = if unclipped >= clipped { -adv / m } else { 0.0 };
        let d_logprob = d_ratio * ratio;
        for a in 0..ACT_DIM {
            dmu[a] = d_logprob * z[a] * inv_std[a];
            d_log_std[a] += d_logprob * (z[a] * z[a] - 1.0);
        }
    }
    d_log_std
}

/// The value head: `½·vf_coef·mean((V − R)²)` (or CleanRL's clipped form); writes `d_value`.
pub(super) fn value_head(
    rows: &ShardRows,
    value: &[f32],
    s: HeadSettings,
    d_value: &mut [f32],
    sums: &mut ShardSums,
) {
    let scale = s.vf_coef / s.m as f32;
    for (i, (&v, d)) in value.iter().zip(d_value.iter_mut()).enumerate() {
        let (old, ret) = (rows.values[i], rows.returns[i]);
        let unclipped = (v - ret) * (v - ret);
        let (loss, grad) = if s.clip_vloss {
            let eps = s.clip_coef;
            let v_clipped = old + (v - old).clamp(-eps, eps);
            let clipped = (v_clipped - ret) * (v_clipped - ret);
            if unclipped >= clipped {
                (unclipped, v - ret)
            } else {
                let inside = (v - old).abs() < eps;
                (clipped, if inside { v_clipped - ret } else { 0.0 })
            }
        } else {
            (unclipped, v - ret)
        };
        sums.v_loss += f64::from(loss);
        *d = scale * grad;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(m: usize, clip_vloss: bool) -> HeadSettings {
        HeadSettings {
            clip_coef: 0.2,
            clip_vloss,
            vf_coef: 0.5,
            m,
        }
    }

    /// Mean 0, σ = 1, action (0.5, 0): z = (0.5, 0), log p = −0.125 − ln 2π = −1.962877.
    /// Behaviour log p −2.1 gives ratio e^0.137123 = 1.146967 (inside 1 ± 0.2), so with
    /// A = 2 and m = 2: loss −A·r / m summed = −1.146967, d ratio = −1, d log p = −1.146967,
    /// d mean = d log p · z = (−0.573484, 0), d log-std = d log p · (z² − 1) = (0.860225, 1.146967).
    #[test]
    fn policy_head_by_hand() {
        let rows = ShardRows {
            actions: &[0.5, 0.0],
            logprobs: &[-2.1],
            advantages: &[2.0],
            values: &[0.0],
            returns: &[0.0],
        };
        // Mean 0 and log-std 0 for both action dimensions, minibatch of 2.
        let head = |rows: &ShardRows| {
            let (mut d_mean, mut sums) = ([0.0; 2], ShardSums::default());
            let d_ls = policy_head(
                rows,
                &[0.0; 2],
                &[0.0; 2],
                settings(2, false),
                &mut d_mean,
                &mut sums,
            );
            (d_mean, d_ls, sums)
        };
        let (d_mean, d_ls, sums) = head(&rows);
        let close = |a: f32, b: f64| (f64::from(a) - b).abs() < 1e-5;
        let r = 1.146_967;
        assert!((sums.pg_loss + 2.0 * r).abs() < 1e-5, "{sums:?}");
        assert!(close(d_mean[0], -0.5 * r) && d_mean[1] == 0.0, "{d_mean:?}");
        assert!(close(d_ls[0], 0.75 * r) && close(d_ls[1], r), "{d_ls:?}");
        assert_eq!(sums.clipped, 0.0);
        assert!((sums.old_approx_kl + 0.137_123).abs() < 1e-5);
        // Far outside the clip range with a positive advantage the clipped term wins: no
        // gradient, and the row counts as clipped.
        let rows = ShardRows {
            logprobs: &[-3.0],
            ..rows
        };
        let (d_mean, d_ls, sums) = head(&rows);
        assert_eq!((d_mean, d_ls, sums.clipped), ([0.0; 2], [0.0; 2], 1.0));
        assert!((sums.pg_loss + 2.0 * 1.2).abs() < 1e-6);
    }

    /// V = 1, 3; V_old = 2, 2; R = 0, 0; ε = 0.2, vf 0.5, m = 2, so gradients are
    /// 0.25·(V − R). Unclipped: losses 1 + 9, gradients 0.25, 0.75. Clipped values 1.8, 2.2
    /// give 3.24, 4.84: the first row's clipped term wins (3.24 > 1) and its V is outside
    /// the clip range, so no gradient; the second row's unclipped 9 wins.
    #[test]
    fn value_head_by_hand() {
        let rows = ShardRows {
            actions: &[],
            logprobs: &[],
            advantages: &[],
            values: &[2.0, 2.0],
            returns: &[0.0, 0.0],
        };
        for (clip, want_d, want_loss) in [(false, [0.25, 0.75], 10.0), (true, [0.0, 0.75], 12.24)] {
            let mut d = [f32::NAN; 2];
            let mut sums = ShardSums::default();
            value_head(&rows, &[1.0, 3.0], settings(2, clip), &mut d, &mut sums);
            assert_eq!(d, want_d, "clip {clip}");
            assert!(
                (sums.v_loss - want_loss).abs() < 1e-5,
                "clip {clip}: {sums:?}"
            );
        }
        // V = 2.1 inside the clip range, R = 3, m = 1: both terms agree, gradient ½·(V − R).
        let rows = ShardRows {
            values: &[2.0],
            returns: &[3.0],
            ..rows
        };
        let (mut d, mut sums) = ([f32::NAN], ShardSums::default());
        value_head(&rows, &[2.1], settings(1, true), &mut d, &mut sums);
        assert!((d[0] + 0.45).abs() < 1e-6, "{d:?}");
        assert!((sums.v_loss - 0.81).abs() < 1e-6);
    }
}
