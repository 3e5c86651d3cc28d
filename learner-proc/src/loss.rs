//! PPO's loss terms in burn (SPEC S6: clip ε 0.2, entropy coefficient 5e-4), and the diagonal
//! Gaussian policy they are taken under. Batch quantities are `[batch, 1]` columns so that no
//! reshapes enter the autodiff graph.

use burn::tensor::Tensor;
use common::policy::HALF_LN_2PI;

/// `log N(action; mean, diag(exp(log_std)²))`, summed over action dimensions.
/// `mean`, `action`: `[batch, act]`; `log_std`: `[1, act]`. Returns `[batch, 1]`.
pub fn gaussian_logprob(mean: Tensor<2>, log_std: Tensor<2>, action: Tensor<2>) -> Tensor<2> {
    let act = log_std.dims()[1] as f32;
    let z = (action - mean) * log_std.clone().neg().exp();
    z.square()
        .sum_dim(1)
        .mul_scalar(-0.5)
        .sub(log_std.sum_dim(1).add_scalar(act * HALF_LN_2PI))
}

/// Entropy of the state-independent Gaussian, `Σ (½ + ½·ln 2π + log σ)`, the same for every
/// observation. `log_std`: `[1, act]`. Returns `[1, 1]`.
pub fn gaussian_entropy(log_std: Tensor<2>) -> Tensor<2> {
    let act = log_std.dims()[1] as f32;
    log_std.sum_dim(1).add_scalar(act * (0.5 + HALF_LN_2PI))
}

/// The clipped surrogate objective as a loss: `mean(max(−A·r, −A·clip(r, 1 − ε, 1 + ε)))`.
/// `ratio`, `advantages`: `[batch, 1]`. Returns `[1]`.
pub fn clipped_surrogate(ratio: Tensor<2>, advantages: Tensor<2>, clip_coef: f32) -> Tensor<1> {
    let neg_adv = advantages.neg();
    let pg_loss1 = neg_adv.clone() * ratio.clone();
    let pg_loss2 = neg_adv * ratio.clamp(1.0 - clip_coef, 1.0 + clip_coef);
    pg_loss1.max_pair(pg_loss2).mean()
}

/// `½·mean((V − R)²)`, or with `clip = Some(ε)` the pessimistic
/// `½·mean(max((V − R)², (V_old + clip(V − V_old, ±ε) − R)²))` (CleanRL's `clip_vloss`).
/// All inputs `[batch, 1]`. Returns `[1]`.
pub fn value_loss(
    newvalue: Tensor<2>,
    b_values: Tensor<2>,
    b_returns: Tensor<2>,
    clip: Option<f32>,
) -> Tensor<1> {
    let v_loss_unclipped = (newvalue.clone() - b_returns.clone()).square();
    let v_loss = match clip {
        None => v_loss_unclipped,
        Some(eps) => {
            let v_clipped = b_values.clone() + (newvalue - b_values).clamp(-eps, eps);
            let v_loss_clipped = (v_clipped - b_returns).square();
            v_loss_unclipped.max_pair(v_loss_clipped)
        }
    };
    v_loss.mean().mul_scalar(0.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::read;
    use burn::tensor::{Device, TensorData};

    fn column(xs: &[f32], device: &Device) -> Tensor<2> {
        Tensor::from_data(TensorData::new(xs.to_vec(), [xs.len(), 1]), device)
    }

    fn scalar(t: Tensor<1>) -> f32 {
        read(t, "test")
            .expect("read")
            .first()
            .copied()
            .expect("one value")
    }

    /// ratio 0.5, 1.0, 1.5, 1.5 with advantages 1, 2, 1, −1 and ε = 0.2:
    /// max(−0.5, −0.8) = −0.5; −2; max(−1.5, −1.2) = −1.2; max(1.5, 1.2) = 1.5; mean −0.55.
    /// Gradients (÷4): the unclipped picks get −A/4, the clipped pick (r = 1.5, A = 1) none.
    #[test]
    fn clipped_surrogate_by_hand() {
        let device = Device::flex().autodiff();
        let ratio = column(&[0.5, 1.0, 1.5, 1.5], &device).require_grad();
        let adv = column(&[1.0, 2.0, 1.0, -1.0], &device);
        let loss = clipped_surrogate(ratio.clone(), adv, 0.2);
        assert!((scalar(loss.clone()) + 0.55).abs() < 1e-6);
        let grads = loss.backward();
        let g = read(ratio.grad(&grads).expect("grad"), "grad").expect("read");
        assert!(
            (g[0] + 0.25).abs() < 1e-7 && g[2] == 0.0 && (g[3] - 0.25).abs() < 1e-7,
            "{g:?}"
        );
    }

    /// V = 1, 3; V_old = 2, 2; R = 0, 0; ε = 0.5.
    /// Unclipped: 1, 9 → ½·5 = 2.5. Clipped values 1.5, 2.5 → 2.25, 6.25; max 2.25, 9 → 2.8125.
    #[test]
    fn value_loss_by_hand() {
        let device = Device::flex();
        let v = || column(&[1.0, 3.0], &device);
        let old = || column(&[2.0, 2.0], &device);
        let ret = || column(&[0.0, 0.0], &device);
        assert!((scalar(value_loss(v(), old(), ret(), None)) - 2.5).abs() < 1e-6);
        assert!((scalar(value_loss(v(), old(), ret(), Some(0.5))) - 2.8125).abs() < 1e-6);
    }

    /// mean (0, 1), σ = (1, 2), action (1, 1): z = (1, 0),
    /// log p = −½·1 − ln 2 − 2·½·ln 2π = −3.031024; entropy = ln 2 + 2·(½ + ½·ln 2π) = 3.531024.
    #[test]
    fn gaussian_logprob_and_entropy_by_hand() {
        let device = Device::flex();
        let mean = Tensor::<2>::from_data(TensorData::new(vec![0.0f32, 1.0], [1, 2]), &device);
        let log_std_host = [0.0f32, std::f32::consts::LN_2];
        let log_std =
            Tensor::<2>::from_data(TensorData::new(log_std_host.to_vec(), [1, 2]), &device);
        let action = Tensor::<2>::from_data(TensorData::new(vec![1.0f32, 1.0], [1, 2]), &device);
        let lp = read(gaussian_logprob(mean, log_std.clone(), action), "logprob").expect("read");
        let want = -0.5 - std::f64::consts::LN_2 - (2.0 * std::f64::consts::PI).ln();
        assert!((f64::from(lp[0]) - want).abs() < 1e-6, "{lp:?} vs {want}");
        let ent = read(gaussian_entropy(log_std), "entropy").expect("read")[0];
        let want = std::f64::consts::LN_2 + 1.0 + (2.0 * std::f64::consts::PI).ln();
        assert!((f64::from(ent) - want).abs() < 1e-6);
    }
}
