//! One MLP's forward and backward pass over a shard of rows, on host buffers allocated once:
//! dense layers `x·W + b` (weights `[in][out]` row-major, as the flat parameter vector holds
//! them), tanh between them ([`fast_tanh`], the burn engine's), a linear output.

use crate::net::ParamBlock;
use crate::simd::vectorized;
use common::policy::fast_tanh;

use super::matmul::{Mat, matmul};

/// A network's dense layers: each one's weight and bias blocks in the flat parameter vector,
/// whose span of it starts at `origin`.
pub(super) struct Mlp {
    layers: Vec<(ParamBlock, ParamBlock)>,
    origin: usize,
}

/// The buffers of one pass over at most `rows` rows: each layer's output (after tanh for a
/// hidden layer, which is also what its derivative needs), and two gradient rows.
pub(super) struct Activations {
    outs: Vec<Vec<f32>>,
    delta: Vec<f32>,
    spare: Vec<f32>,
}

impl Mlp {
    pub(super) fn new(layers: Vec<(ParamBlock, ParamBlock)>, origin: usize) -> Self {
        assert!(!layers.is_empty(), "an MLP needs a layer");
        assert!(layers.iter().all(|(w, b)| w.offset.min(b.offset) >= origin));
        Self { layers, origin }
    }

    /// Where `block` sits in a buffer that holds this network's span only.
    fn local(&self, block: ParamBlock) -> std::ops::Range<usize> {
        let r = block.range();
        r.start - self.origin..r.end - self.origin
    }

    pub(super) fn buffers(&self, rows: usize) -> Activations {
        let widest = self
            .layers
            .iter()
            .map(|(w, _)| w.rows.max(w.cols))
            .max()
            .unwrap_or(0);
        Activations {
            outs: self
                .layers
                .iter()
                .map(|(w, _)| vec![0.0; rows * w.cols])
                .collect(),
            delta: vec![0.0; rows * widest],
            spare: vec![0.0; rows * widest],
        }
    }

    /// The network's outputs for the `rows × in` inputs `x`, `[rows, out]` row-major.
    pub(super) fn forward<'a>(
        &self,
        params: &[f32],
        x: &[f32],
        rows: usize,
        acts: &'a mut Activations,
    ) -> &'a [f32] {
        let last = self.layers.len() - 1;
        for (l, &(w, b)) in self.layers.iter().enumerate() {
            let (done, rest) = acts.outs.split_at_mut(l);
            let input = if l == 0 { x } else { &done[l - 1] };
            let out = &mut rest[0][..rows * w.cols];
            let bias = &params[b.range()];
            out.chunks_exact_mut(w.cols)
                .for_each(|row| row.copy_from_slice(bias));
            matmul(
                out,
                Mat::new(input, rows, w.rows),
                Mat::new(&params[w.range()], w.rows, w.cols),
                true,
            );
            if l < last {
                vectorized(|| out.iter_mut().for_each(|v| *v = fast_tanh(*v)));
            }
        }
        &acts.outs[last][..rows * self.layers[last].0.cols]
    }

    /// Writes into `grads` (this network's span of the parameters, from `origin`) the gradient
    /// of a loss whose gradient with respect to the outputs of the last [`Self::forward`] (same
    /// `x`, `rows`) is `d_out`, `[rows, out]`. Values of the span outside the dense layers are
    /// left as they are.
    pub(super) fn backward(
        &self,
        params: &[f32],
        x: &[f32],
        rows: usize,
        acts: &mut Activations,
        d_out: &[f32],
        grads: &mut [f32],
    ) {
        let Activations { outs, delta, spare } = acts;
        delta[..d_out.len()].copy_from_slice(d_out);
        for (l, &(w, b)) in self.layers.iter().enumerate().rev() {
            let input = if l == 0 {
                x
            } else {
                &outs[l - 1][..rows * w.rows]
            };
            let d = Mat::new(delta, rows, w.cols);
            matmul(
                &mut grads[self.local(w)],
                Mat::new(input, rows, w.rows).t(),
                d,
                false,
            );
            let db = &mut grads[self.local(b)];
            db.fill(0.0);
            vectorized(|| {
                for row in delta[..rows * w.cols].chunks_exact(w.cols) {
                    db.iter_mut().zip(row).for_each(|(g, d)| *g += d);
                }
            });
            if l == 0 {
                break;
            }
            // Through the weights, then through the tanh that made `input`: 1 − tanh².
            let back = &mut spare[..rows * w.rows];
            matmul(
                back,
                d,
                Mat::new(&params[w.range()], w.rows, w.cols).t(),
                false,
            );
            vectorized(|| {
                back.iter_mut()
                    .zip(input)
                    .for_each(|(g, h)| *g *= 1.0 - h * h);
            });
            std::mem::swap(delta, spare);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::Role;

    /// A 2 → 2 → 1 network by hand: W1 = [[1, 0], [0, 2]], b1 = [0, 0.5], W2 = [[1], [−1]],
    /// b2 = [0.25]; x = [0.5, 0.25]. Hidden pre-activations [0.5, 1.0], h = tanh of them,
    /// y = h1 − h2 + 0.25. With dL/dy = 1: dW2 = h, db2 = 1, dh = [1, −1],
    /// dz = dh·(1 − h²), dW1 = xᵀ·dz, db1 = dz.
    #[test]
    fn forward_and_backward_by_hand() {
        let block = |offset, rows, cols| ParamBlock {
            offset,
            rows,
            cols,
            role: Role::Bias { fan_in: 0 },
        };
        // The network's span starts at 1: a parameter before it is not the network's.
        let mlp = Mlp::new(
            vec![
                (block(1, 2, 2), block(5, 1, 2)),
                (block(7, 2, 1), block(9, 1, 1)),
            ],
            1,
        );
        let params = [f32::NAN, 1.0, 0.0, 0.0, 2.0, 0.0, 0.5, 1.0, -1.0, 0.25];
        let x = [0.5, 0.25];
        let mut acts = mlp.buffers(1);
        let y = mlp.forward(&params, &x, 1, &mut acts)[0];
        let h = [0.5f32.tanh(), 1.0f32.tanh()];
        assert!((y - (h[0] - h[1] + 0.25)).abs() < 1e-6, "{y}");
        let mut grads = [f32::NAN; 9];
        mlp.backward(&params, &x, 1, &mut acts, &[1.0], &mut grads);
        let dz = [1.0 - h[0] * h[0], -(1.0 - h[1] * h[1])];
        let want = [
            0.5 * dz[0],
            0.5 * dz[1],
            0.25 * dz[0],
            0.25 * dz[1],
            dz[0],
            dz[1],
            h[0],
            h[1],
            1.0,
        ];
        for (g, w) in grads.iter().zip(want) {
            assert!((g - w).abs() < 1e-6, "{grads:?} vs {want:?}");
        }
    }
}
