//! The policy network's flat f32 weight layout and a plain-Rust forward pass.
//!
//! The learner flattens its actor into this layout and publishes it on the `policy` service;
//! the simulator evaluates it without linking burn. Layout, in order:
//!
//! 1. observation mean `[obs]`, observation variance `[obs]` (running normalisation stats);
//! 2. for each hidden layer `l` (inputs `i`, outputs `o`): weight `[i][o]` row-major (burn's
//!    `Linear` convention, `y = x·W + b`), then bias `[o]`;
//! 3. the mean head: weight `[h_last][act]`, bias `[act]`;
//! 4. the state-independent log standard deviation `[act]`.
//!
//! Hidden layers use tanh ([`fast_tanh`]); the mean head is linear. Observations are normalised as
//! `clamp((x - mean) / sqrt(var + 1e-8), ±obs_clip)` before the first layer.
//!
//! Actions are drawn from the diagonal Gaussian `N(mean, exp(log_std)²)` by
//! [`sample_gaussian`], the one sampler every process uses, so the simulator and the learner
//! agree on the draws and their log-probabilities.

use serde::{Deserialize, Serialize};

use crate::Rng;

/// Added to the variance before the square root when normalising observations.
pub const OBS_NORM_EPS: f32 = 1e-8;
/// Most hidden layers an architecture may have (the wire format reserves this many).
pub const MAX_HIDDEN: usize = 4;
/// `½·ln(2π)`: each dimension's constant term in a Gaussian log-density.
pub const HALF_LN_2PI: f32 = 0.918_938_5;

/// tanh without libm calls or branches (so loops over it vectorise), the hidden layers'
/// activation in the simulator's forward pass and in the learner's; within 2e-7 of
/// `f32::tanh` and within 1e-6 relative near zero: `(e^{2x} − 1)/(e^{2x} + 1)` with
/// `e^y − 1 = 2^n·(e^g − 1) + (2^n − 1)`, n = round(y / ln 2), |g| ≤ ln 2 / 2, and `e^g − 1`
/// from its Taylor series to g⁶ (relative error < 2e-7); no cancellation for small x, where n = 0.
#[inline]
pub fn fast_tanh(x: f32) -> f32 {
    // Round-to-nearest by the 1.5·2²³ trick (`f32::round` is a libm call on baseline x86-64);
    // afterwards the low mantissa bits of `z` hold n.
    const ROUNDER: f32 = 12_582_912.0;
    // ln 2 split so that n·LN2_HI is exact (Cody–Waite).
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    // tanh(±9) rounds to ±1 in f32; clamping keeps 2^n finite (and lets NaN through).
    let y = 2.0 * x.clamp(-9.0, 9.0);
    let z = y * std::f32::consts::LOG2_E + ROUNDER;
    let n = z - ROUNDER;
    let g = (y - n * LN2_HI) - n * LN2_LO;
    let mut p = 1.0 / 720.0;
    for c in [1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0] {
        p = p * g + c;
    }
    let scale = f32::from_bits(
        z.to_bits()
            .wrapping_sub(ROUNDER.to_bits())
            .wrapping_add(127)
            << 23,
    );
    let em1 = p * g * scale + (scale - 1.0);
    em1 / (em1 + 2.0)
}

/// Diagonal Gaussian log-density of `action` with mean `mean` and log-std `log_std`.
pub fn gaussian_log_prob(action: &[f32], mean: &[f32], log_std: &[f32]) -> f32 {
    action
        .iter()
        .zip(mean)
        .zip(log_std)
        .map(|((a, m), s)| {
            let z = (a - m) / s.exp();
            -0.5 * z * z - s - HALF_LN_2PI
        })
        .sum()
}

/// Draws `action` from `N(mean, exp(log_std)²)`, one standard normal per dimension in order,
/// and returns its log-probability. The result is unclipped: the simulator clips it.
pub fn sample_gaussian(mean: &[f32], log_std: &[f32], rng: &mut Rng, action: &mut [f32]) -> f32 {
    for ((a, m), s) in action.iter_mut().zip(mean).zip(log_std) {
        *a = m + s.exp() * rng.normal() as f32;
    }
    gaussian_log_prob(action, mean, log_std)
}

/// The shape of an actor network: what the flat weight vector must match.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PolicyLayout {
    pub obs_dim: usize,
    pub hidden: Vec<usize>,
    pub act_dim: usize,
}

/// Where one dense layer's parameters sit in the flat vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DenseLayer {
    pub inputs: usize,
    pub outputs: usize,
    /// Offset of the `[inputs][outputs]` weight block.
    pub weight: usize,
    /// Offset of the `[outputs]` bias.
    pub bias: usize,
}

impl PolicyLayout {
    pub fn new(obs_dim: usize, hidden: &[usize], act_dim: usize) -> Self {
        Self {
            obs_dim,
            hidden: hidden.to_vec(),
            act_dim,
        }
    }

    /// Offset of the observation mean; the variance follows it.
    pub fn obs_mean(&self) -> usize {
        0
    }

    pub fn obs_var(&self) -> usize {
        self.obs_dim
    }

    /// The dense layers in evaluation order, the mean head last.
    pub fn dense_layers(&self) -> Vec<DenseLayer> {
        let mut at = 2 * self.obs_dim;
        let mut inputs = self.obs_dim;
        let mut layers = Vec::with_capacity(self.hidden.len() + 1);
        for &outputs in self.hidden.iter().chain(std::iter::once(&self.act_dim)) {
            layers.push(DenseLayer {
                inputs,
                outputs,
                weight: at,
                bias: at + inputs * outputs,
            });
            at += inputs * outputs + outputs;
            inputs = outputs;
        }
        layers
    }

    pub fn log_std(&self) -> usize {
        self.len() - self.act_dim
    }

    /// Number of f32 in the flat vector.
    pub fn len(&self) -> usize {
        let dense: usize = self
            .dense_layers()
            .iter()
            .map(|d| d.inputs * d.outputs + d.outputs)
            .sum();
        2 * self.obs_dim + dense + self.act_dim
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The widest layer, for sizing scratch buffers.
    pub fn max_width(&self) -> usize {
        self.hidden
            .iter()
            .copied()
            .chain([self.obs_dim, self.act_dim])
            .max()
            .unwrap_or(0)
    }
}

/// A policy ready to evaluate: its layout and weights. Evaluating it reads them only, so
/// several threads can act with one policy, each with its own [`Scratch`].
#[derive(Debug, Clone)]
pub struct Policy {
    layout: PolicyLayout,
    layers: Vec<DenseLayer>,
    weights: Vec<f32>,
    obs_clip: f32,
}

/// The activations of one evaluation, reused from one call to the next; sized on first use
/// by the widest layer it meets.
#[derive(Debug, Clone, Default)]
pub struct Scratch {
    a: Vec<f32>,
    b: Vec<f32>,
}

/// The flat vector's length does not match the layout.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("policy weights have {got} floats but the layout {layout:?} needs {want}")]
pub struct LayoutMismatch {
    pub layout: PolicyLayout,
    pub want: usize,
    pub got: usize,
}

impl Policy {
    pub fn new(
        layout: PolicyLayout,
        weights: Vec<f32>,
        obs_clip: f32,
    ) -> Result<Self, LayoutMismatch> {
        let want = layout.len();
        if weights.len() != want {
            return Err(LayoutMismatch {
                layout,
                want,
                got: weights.len(),
            });
        }
        Ok(Self {
            layers: layout.dense_layers(),
            layout,
            weights,
            obs_clip,
        })
    }

    pub fn layout(&self) -> &PolicyLayout {
        &self.layout
    }

    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// Replaces the weights in place (same layout), reusing the allocation.
    pub fn set_weights(&mut self, weights: &[f32]) -> Result<(), LayoutMismatch> {
        if weights.len() != self.weights.len() {
            return Err(LayoutMismatch {
                layout: self.layout.clone(),
                want: self.weights.len(),
                got: weights.len(),
            });
        }
        self.weights.copy_from_slice(weights);
        Ok(())
    }

    /// The clip of normalised observations, ±this.
    pub fn obs_clip(&self) -> f32 {
        self.obs_clip
    }

    pub fn log_std(&self) -> &[f32] {
        let at = self.layout.log_std();
        &self.weights[at..at + self.layout.act_dim]
    }

    /// The action mean for one observation, written to `mean` (`[act]`).
    pub fn mean_action(&self, obs: &[f32], mean: &mut [f32], s: &mut Scratch) {
        debug_assert_eq!(mean.len(), self.layout.act_dim);
        self.forward(obs, s);
        mean.copy_from_slice(&s.a[..self.layout.act_dim]);
    }

    /// An unclipped action for one observation, written to `action` (`[act]`), and its
    /// log-probability: a draw from the policy's Gaussian with `rng`, its mean without.
    pub fn sample(
        &self,
        obs: &[f32],
        rng: Option<&mut Rng>,
        action: &mut [f32],
        s: &mut Scratch,
    ) -> f32 {
        debug_assert_eq!(action.len(), self.layout.act_dim);
        self.forward(obs, s);
        let (mean, log_std) = (&s.a[..self.layout.act_dim], self.log_std());
        match rng {
            Some(rng) => sample_gaussian(mean, log_std, rng, action),
            None => {
                action.copy_from_slice(mean);
                gaussian_log_prob(mean, mean, log_std)
            }
        }
    }

    /// Evaluates the network on one observation, leaving the action mean in `s.a[..act]`.
    fn forward(&self, obs: &[f32], s: &mut Scratch) {
        let l = &self.layout;
        debug_assert_eq!(obs.len(), l.obs_dim);
        let width = l.max_width();
        if s.a.len() < width {
            s.a.resize(width, 0.0);
            s.b.resize(width, 0.0);
        }
        let (mu, var) = (
            &self.weights[l.obs_mean()..l.obs_mean() + l.obs_dim],
            &self.weights[l.obs_var()..l.obs_var() + l.obs_dim],
        );
        for i in 0..l.obs_dim {
            let z = (obs[i] - mu[i]) / (var[i] + OBS_NORM_EPS).sqrt();
            s.a[i] = z.clamp(-self.obs_clip, self.obs_clip);
        }
        let last = self.layers.len() - 1;
        for (n, d) in self.layers.iter().enumerate() {
            let w = &self.weights[d.weight..d.weight + d.inputs * d.outputs];
            let out = &mut s.b[..d.outputs];
            out.copy_from_slice(&self.weights[d.bias..d.bias + d.outputs]);
            for (i, &x) in s.a[..d.inputs].iter().enumerate() {
                let row = &w[i * d.outputs..(i + 1) * d.outputs];
                for (o, &wij) in out.iter_mut().zip(row) {
                    *o += x * wij;
                }
            }
            if n < last {
                for o in out.iter_mut() {
                    *o = fast_tanh(*o);
                }
            }
            std::mem::swap(&mut s.a, &mut s.b);
        }
    }
}

/// Magic bytes of a policy file (`.policy`): an exported actor for `sim-proc --controller policy`.
const POLICY_MAGIC: &[u8; 8] = b"LTPOLICY";
const POLICY_FILE_VERSION: u32 = 1;

/// A policy file could not be read or does not describe a valid network.
#[derive(Debug, thiserror::Error)]
#[error("policy file {path}: {reason}")]
pub struct PolicyFileError {
    pub path: std::path::PathBuf,
    pub reason: String,
}

/// The widest layer a policy file may describe (the config allows 4096).
const MAX_WIDTH: usize = 1 << 16;

impl Policy {
    /// Serialises layout, observation clip and weights: magic, version, obs, hidden count,
    /// hidden widths, act, clip, weight count, weights (all little-endian u32/f32).
    pub fn to_bytes(&self) -> Vec<u8> {
        let l = &self.layout;
        let mut out = Vec::with_capacity(40 + 4 * self.weights.len());
        out.extend_from_slice(POLICY_MAGIC);
        let mut words = vec![POLICY_FILE_VERSION, l.obs_dim as u32, l.hidden.len() as u32];
        words.extend(l.hidden.iter().map(|&h| h as u32));
        words.push(l.act_dim as u32);
        for w in words {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out.extend_from_slice(&self.obs_clip.to_le_bytes());
        out.extend_from_slice(&(self.weights.len() as u32).to_le_bytes());
        for w in &self.weights {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out
    }

    /// Parses [`Policy::to_bytes`]'s format; `path` only labels errors.
    pub fn from_bytes(bytes: &[u8], path: &std::path::Path) -> Result<Self, PolicyFileError> {
        let err = |reason: String| PolicyFileError {
            path: path.to_path_buf(),
            reason,
        };
        if bytes.len() < 8 || &bytes[..8] != POLICY_MAGIC {
            return Err(err("not a lavatube policy file (bad magic)".into()));
        }
        let mut at = 8;
        let mut word = || -> Result<[u8; 4], PolicyFileError> {
            let w = bytes
                .get(at..at + 4)
                .ok_or_else(|| err(format!("truncated at byte {at}")))?;
            at += 4;
            Ok([w[0], w[1], w[2], w[3]])
        };
        let version = u32::from_le_bytes(word()?);
        if version != POLICY_FILE_VERSION {
            return Err(err(format!(
                "format version {version}, expected {POLICY_FILE_VERSION}"
            )));
        }
        let obs_dim = u32::from_le_bytes(word()?) as usize;
        let n_hidden = u32::from_le_bytes(word()?) as usize;
        if n_hidden > MAX_HIDDEN {
            return Err(err(format!(
                "{n_hidden} hidden layers, at most {MAX_HIDDEN}"
            )));
        }
        let hidden = (0..n_hidden)
            .map(|_| word().map(|w| u32::from_le_bytes(w) as usize))
            .collect::<Result<Vec<_>, _>>()?;
        let act_dim = u32::from_le_bytes(word()?) as usize;
        // Sizes no network has would overflow the layout's arithmetic.
        if let Some(d) = [obs_dim, act_dim]
            .iter()
            .chain(&hidden)
            .find(|&&d| d > MAX_WIDTH)
        {
            return Err(err(format!("a layer of {d} units, at most {MAX_WIDTH}")));
        }
        let obs_clip = f32::from_le_bytes(word()?);
        let n = u32::from_le_bytes(word()?) as usize;
        let weights = (0..n)
            .map(|_| word().map(f32::from_le_bytes))
            .collect::<Result<Vec<_>, _>>()?;
        if weights.iter().any(|w| !w.is_finite()) {
            return Err(err("contains non-finite weights".into()));
        }
        Policy::new(
            PolicyLayout {
                obs_dim,
                hidden,
                act_dim,
            },
            weights,
            obs_clip,
        )
        .map_err(|e| err(e.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_offsets_for_a_tiny_net() {
        let l = PolicyLayout::new(2, &[3], 1);
        let d = l.dense_layers();
        // obs stats 4, layer 2x3+3 = 9, head 3x1+1 = 4, log_std 1.
        assert_eq!(
            d[0],
            DenseLayer {
                inputs: 2,
                outputs: 3,
                weight: 4,
                bias: 10
            }
        );
        assert_eq!(
            d[1],
            DenseLayer {
                inputs: 3,
                outputs: 1,
                weight: 13,
                bias: 16
            }
        );
        assert_eq!(l.log_std(), 17);
        assert_eq!(l.len(), 18);
        // The paper's default: 10 -> 128 -> 128 -> 2.
        let paper = PolicyLayout::new(10, &[128, 128], 2);
        assert_eq!(
            paper.len(),
            20 + (10 * 128 + 128) + (128 * 128 + 128) + (128 * 2 + 2) + 2
        );
    }

    #[test]
    fn fast_tanh_matches_std_tanh() {
        let mut worst = 0.0f32;
        for i in -130_000..=130_000 {
            let x = i as f32 * 1e-4;
            let (got, want) = (fast_tanh(x), x.tanh());
            worst = worst.max((got - want).abs());
            if x.abs() < 0.2 && x != 0.0 {
                assert!(((got - want) / want).abs() < 1e-6, "relative error at {x}");
            }
        }
        assert!(worst < 2e-7, "max error {worst}");
        for x in [1e-30f32, 50.0, -1e30, f32::INFINITY, f32::NEG_INFINITY] {
            assert!((fast_tanh(x) - x.tanh()).abs() < 1e-7, "{x}");
        }
        assert!(fast_tanh(f32::NAN).is_nan());
    }

    #[test]
    fn forward_matches_a_hand_computation() {
        let l = PolicyLayout::new(2, &[2], 1);
        #[rustfmt::skip]
        let w = vec![
            1.0, 2.0,          // obs mean
            4.0 - 1e-8, 1.0 - 1e-8, // obs var -> std 2, 1
            0.5, -1.0,         // W1 row for input 0
            0.25, 2.0,         // W1 row for input 1
            0.1, -0.2,         // b1
            1.0, -1.0,         // head weights
            0.3,               // head bias
            -0.5,              // log std
        ];
        let p = Policy::new(l, w, 5.0).expect("layout");
        let mut out = [0.0];
        p.mean_action(&[3.0, 1.0], &mut out, &mut Scratch::default());
        // z = ((3-1)/2, (1-2)/1) = (1, -1)
        // z0·W[0][0] + z1·W[1][0] + b0 and z0·W[0][1] + z1·W[1][1] + b1, with z = (1, −1).
        let h0 = (0.5f32 - 0.25 + 0.1).tanh();
        let h1 = (-1.0f32 - 2.0 - 0.2).tanh();
        assert!((out[0] - (h0 - h1 + 0.3)).abs() < 1e-6);
        assert_eq!(p.log_std(), &[-0.5]);
    }

    #[test]
    fn observation_clip_and_length_check() {
        let l = PolicyLayout::new(1, &[], 1);
        // mean 0, var 1, head weight 1, bias 0, log std 0
        let p = Policy::new(l.clone(), vec![0.0, 1.0, 1.0, 0.0, 0.0], 2.0).expect("layout");
        let mut out = [0.0];
        p.mean_action(&[100.0], &mut out, &mut Scratch::default());
        assert!((out[0] - 2.0).abs() < 1e-6);
        let err = Policy::new(l, vec![0.0; 3], 2.0).expect_err("short");
        assert_eq!((err.want, err.got), (5, 3));
    }

    #[test]
    fn gaussian_log_prob_matches_hand_values() {
        // N(0, 1) at 0: −½·ln(2π) = −0.918939; two dims: −1.837877.
        assert!(
            (gaussian_log_prob(&[0.0, 0.0], &[0.0, 0.0], &[0.0, 0.0]) + 1.837_877).abs() < 1e-5
        );
        // σ = e^0.5 at z = 1: −½ − 0.5 − 0.918939.
        let lp = gaussian_log_prob(&[1.0f32.mul_add(0.5f32.exp(), 0.0)], &[0.0], &[0.5]);
        assert!((lp + 1.918_939).abs() < 1e-5, "{lp}");
    }

    #[test]
    fn sampling_draws_one_normal_per_dimension_in_order() {
        // Rng::new(3)'s first two standard normals are −0.194472 and 1.127222.
        let mut rng = Rng::new(3);
        let mut action = [0.0; 2];
        // mean (1, −2), σ = (1, 2): action = (1 − 0.194472, −2 + 2·1.127222).
        let lp = sample_gaussian(
            &[1.0, -2.0],
            &[0.0, std::f32::consts::LN_2],
            &mut rng,
            &mut action,
        );
        assert!((action[0] - 0.805_528).abs() < 1e-6, "{action:?}");
        assert!((action[1] - 0.254_445).abs() < 1e-6, "{action:?}");
        // −½·(0.194472² + 1.127222²) − ln 2 − 2·½·ln(2π) = −3.185249.
        assert!((lp + 3.185_249).abs() < 1e-5, "{lp}");
        let mut replay = Rng::new(3);
        replay.normal();
        replay.normal();
        assert_eq!(rng, replay, "exactly two normals drawn");
    }

    #[test]
    fn policy_sample_is_the_mean_without_rng_and_a_gaussian_draw_with_it() {
        // obs 1 → mean (2·1.5 + 0.5, −1·1.5) = (3.5, −1.5); σ = (1, 2).
        let l = PolicyLayout::new(1, &[], 2);
        let w = vec![0.0, 1.0, 2.0, -1.0, 0.5, 0.0, 0.0, std::f32::consts::LN_2];
        let p = Policy::new(l, w, 5.0).expect("layout");
        let mut action = [0.0; 2];
        let mut s = Scratch::default();
        let lp = p.sample(&[1.5], None, &mut action, &mut s);
        assert_eq!(action, [3.5, -1.5]);
        // −ln 2 − 2·½·ln(2π) = −2.531024.
        assert!((lp + 2.531_024).abs() < 1e-5, "{lp}");

        let mut rng = Rng::new(1);
        let lp = p.sample(&[1.5], Some(&mut rng), &mut action, &mut s);
        let mut want = [0.0; 2];
        let want_lp = sample_gaussian(
            &[3.5, -1.5],
            &[0.0, std::f32::consts::LN_2],
            &mut Rng::new(1),
            &mut want,
        );
        assert_eq!((action, lp), (want, want_lp));
    }

    #[test]
    fn policy_file_round_trips_and_rejects_damage() {
        let l = PolicyLayout::new(3, &[4, 2], 2);
        let w: Vec<f32> = (0..l.len()).map(|i| i as f32 * 0.01).collect();
        let p = Policy::new(l, w, 7.0).expect("layout");
        let bytes = p.to_bytes();
        let path = std::path::Path::new("p.policy");
        let q = Policy::from_bytes(&bytes, path).expect("round trip");
        assert_eq!(
            (q.layout(), q.weights(), q.obs_clip),
            (p.layout(), p.weights(), 7.0)
        );
        let e = Policy::from_bytes(&bytes[..bytes.len() - 2], path).expect_err("truncated");
        assert!(e.to_string().starts_with("policy file p.policy: "), "{e}");
        let e = Policy::from_bytes(b"NOTAPOLICY", path).expect_err("magic");
        assert!(e.to_string().contains("bad magic"));
    }
}
