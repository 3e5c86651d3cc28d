//! The actor and critic networks in burn, over one flat host parameter vector.
//!
//! The flat vector holds, in order: the actor's dense layers in the `common::policy` layout
//! (weight `[in][out]` row-major, then bias `[out]`), its state-independent log-std `[act]`,
//! then the critic's dense layers (same convention, one output). The actor part is therefore
//! the policy wire format minus the leading observation statistics, so publishing weights is
//! a copy. Every forward pass builds its tensors from this vector (one matrix per dense layer,
//! bias folded in: [`NetShape::tensors`]): gradient-tracked leaves on the autodiff device for
//! a minibatch, plain tensors on the inner device otherwise.
//!
//! Both networks are MLPs with tanh hidden layers (SPEC S6, interpretation: ML-Agents'
//! 2 × 128) and a linear output. The tanh is this module's own ([`tanh`]): burn's is a scalar
//! libm loop whose backward recomputes it, and it dominated the update.

use burn::tensor::{Device, Tensor, TensorData};
use common::Rng;
use common::policy::{PolicyLayout, fast_tanh};

use crate::LearnerError;

/// What a parameter tensor is, which decides how it is initialised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Role {
    /// A dense weight with its orthogonal-init gain.
    Weight {
        gain: f64,
    },
    /// A dense bias; `fan_in` is its layer's input width.
    Bias {
        fan_in: usize,
    },
    LogStd,
}

/// One parameter tensor's place in the flat vector: a `[rows, cols]` block at `offset`
/// (biases and the log-std are `[1, n]` rows).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamBlock {
    pub offset: usize,
    pub rows: usize,
    pub cols: usize,
    pub role: Role,
}

impl ParamBlock {
    pub fn range(&self) -> std::ops::Range<usize> {
        self.offset..self.offset + self.rows * self.cols
    }
}

/// Where the actor's, log-std's and critic's tensors sit in the flat parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct NetShape {
    pub layout: PolicyLayout,
    /// Weight and bias blocks of each dense layer, actor first, then the log-std, then the critic.
    pub blocks: Vec<ParamBlock>,
}

impl NetShape {
    /// The actor follows `layout`; the critic has the same hidden widths and one output.
    /// Orthogonal-init gains are CleanRL's: √2 hidden, 0.01 policy head, 1 value head.
    pub fn new(layout: &PolicyLayout) -> Self {
        let mut blocks = Vec::new();
        let mut at = 0;
        let mut push = |rows: usize, cols: usize, role: Role| {
            blocks.push(ParamBlock {
                offset: at,
                rows,
                cols,
                role,
            });
            at += rows * cols;
        };
        for (outputs, head_gain) in [(layout.act_dim, Some(0.01)), (1, None)] {
            let mut inputs = layout.obs_dim;
            for (l, &o) in layout.hidden.iter().chain([&outputs]).enumerate() {
                let gain = if l < layout.hidden.len() {
                    std::f64::consts::SQRT_2
                } else {
                    head_gain.unwrap_or(1.0)
                };
                push(inputs, o, Role::Weight { gain });
                push(1, o, Role::Bias { fan_in: inputs });
                inputs = o;
            }
            if head_gain.is_some() {
                push(1, layout.act_dim, Role::LogStd);
            }
        }
        Self {
            layout: layout.clone(),
            blocks,
        }
    }

    /// Index of the log-std block; actor dense blocks come before it, critic blocks after.
    pub fn log_std_block(&self) -> usize {
        2 * (self.layout.hidden.len() + 1)
    }

    /// Floats in the flat parameter vector.
    pub fn len(&self) -> usize {
        self.blocks.last().map_or(0, |s| s.range().end)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Floats of the actor (dense layers and log-std): the policy vector minus its obs stats.
    pub fn actor_len(&self) -> usize {
        self.blocks[self.log_std_block()].range().end
    }

    /// Initial parameters: orthogonal weights with zero biases (SPEC S6 option, CleanRL), or
    /// PyTorch's default `U(±1/√fan_in)` for both; the log-std starts at `init_log_std`.
    pub fn init(&self, orthogonal_init: bool, init_log_std: f32, rng: &mut Rng) -> Vec<f32> {
        let mut params = vec![0.0f32; self.len()];
        for block in &self.blocks {
            let out = &mut params[block.range()];
            match (block.role, orthogonal_init) {
                (Role::LogStd, _) => out.fill(init_log_std),
                (Role::Weight { gain }, true) => {
                    out.copy_from_slice(&orthogonal(block.rows, block.cols, gain, rng));
                }
                (Role::Bias { .. }, true) => out.fill(0.0),
                (Role::Weight { .. }, false) => uniform_fan_in(out, block.rows, rng),
                (Role::Bias { fan_in }, false) => uniform_fan_in(out, fan_in, rng),
            }
        }
        params
    }

    /// The (weight, bias) block pairs of the actor's dense layers, or the critic's.
    pub(crate) fn dense(
        &self,
        critic: bool,
    ) -> impl Iterator<Item = (ParamBlock, ParamBlock)> + '_ {
        let at = if critic { self.log_std_block() + 1 } else { 0 };
        let n = self.layout.hidden.len() + 1;
        (0..n).map(move |l| (self.blocks[at + 2 * l], self.blocks[at + 2 * l + 1]))
    }

    /// The tensors of both networks built from `params` on `device`; gradient-tracked leaves
    /// when `track` (the device must then have autodiff enabled).
    ///
    /// Each dense layer is one `[in + 1, out (+ 1)]` matrix: its weight with the bias as an
    /// extra row, fed by an input row that ends in a constant 1 (the "bias unit"); a hidden
    /// layer has one more, all-zero column, which [`tanh`] turns into the next layer's bias
    /// unit. One matmul per layer instead of matmul, broadcast add and their backward passes:
    /// on these small networks every tensor op's fixed cost counts.
    pub fn tensors(&self, params: &[f32], device: &Device, track: bool) -> NetTensors {
        let leaf = |data: Vec<f32>, shape: [usize; 2]| {
            let t = Tensor::<2>::from_data(TensorData::new(data, shape), device);
            if track { t.require_grad() } else { t }
        };
        let network = |critic: bool| -> Vec<Tensor<2>> {
            let last = self.layout.hidden.len();
            self.dense(critic)
                .enumerate()
                .map(|(l, (w, b))| {
                    let cols = w.cols + usize::from(l < last);
                    let mut m = vec![0.0f32; (w.rows + 1) * cols];
                    for (r, row) in m.chunks_exact_mut(cols).enumerate() {
                        let src = if r < w.rows {
                            w.offset + r * w.cols
                        } else {
                            b.offset
                        };
                        row[..w.cols].copy_from_slice(&params[src..src + w.cols]);
                    }
                    leaf(m, [w.rows + 1, cols])
                })
                .collect()
        };
        let log_std = self.blocks[self.log_std_block()];
        NetTensors {
            actor: network(false),
            log_std: leaf(params[log_std.range()].to_vec(), [1, log_std.cols]),
            critic: network(true),
        }
    }

    /// Copies each tracked leaf's gradient back into the blocks of `out` (zero where none
    /// flowed); the constant bias-unit columns have no parameters and are dropped.
    pub fn gradients(
        &self,
        tensors: &NetTensors,
        grads: &burn::tensor::Gradients,
        out: &mut [f32],
    ) -> Result<(), LearnerError> {
        let layers = self
            .dense(false)
            .zip(&tensors.actor)
            .chain(self.dense(true).zip(&tensors.critic));
        for ((w, b), leaf) in layers {
            let Some(g) = leaf.grad(grads) else {
                out[w.range()].fill(0.0);
                out[b.range()].fill(0.0);
                continue;
            };
            let cols = g.dims()[1];
            let g = read(g, "gradient")?;
            for (r, row) in g.chunks_exact(cols).enumerate() {
                let dst = if r < w.rows {
                    w.offset + r * w.cols
                } else {
                    b.offset
                };
                out[dst..dst + w.cols].copy_from_slice(&row[..w.cols]);
            }
        }
        let dst = &mut out[self.blocks[self.log_std_block()].range()];
        match tensors.log_std.grad(grads) {
            Some(g) => dst.copy_from_slice(&read(g, "gradient")?),
            None => dst.fill(0.0),
        }
        Ok(())
    }
}

/// Both networks' tensors on one device (see [`NetShape::tensors`]).
pub struct NetTensors {
    actor: Vec<Tensor<2>>,
    log_std: Tensor<2>,
    critic: Vec<Tensor<2>>,
}

impl NetTensors {
    /// Action means, `[batch, act]`, from normalised observations with the bias unit,
    /// `[batch, obs + 1]`.
    pub fn actor_mean(&self, obs: Tensor<2>) -> Result<Tensor<2>, LearnerError> {
        mlp(obs, &self.actor)
    }

    /// The log standard deviation, `[1, act]`.
    pub fn log_std(&self) -> Tensor<2> {
        self.log_std.clone()
    }

    /// State values, `[batch, 1]`, from `[batch, obs + 1]` as [`Self::actor_mean`].
    pub fn value(&self, obs: Tensor<2>) -> Result<Tensor<2>, LearnerError> {
        mlp(obs, &self.critic)
    }
}

/// PyTorch's default `Linear` init: `U(±1/√fan_in)`.
fn uniform_fan_in(out: &mut [f32], fan_in: usize, rng: &mut Rng) {
    let bound = 1.0 / (fan_in as f64).sqrt();
    out.iter_mut()
        .for_each(|p| *p = rng.range(-bound, bound) as f32);
}

/// Dense layers with folded biases (see [`NetShape::tensors`]), tanh between them, linear
/// output.
fn mlp(mut x: Tensor<2>, layers: &[Tensor<2>]) -> Result<Tensor<2>, LearnerError> {
    for (l, layer) in layers.iter().enumerate() {
        x = x.matmul(layer.clone());
        if l + 1 < layers.len() {
            x = tanh(x)?;
        }
    }
    Ok(x)
}

/// tanh for a hidden layer's `[batch, units + 1]` pre-activations, whose last column becomes
/// the next layer's bias unit: exactly 1, with no gradient.
///
/// burn's own tanh is a scalar libm loop, and its backward (like exp's and sigmoid's)
/// recomputes the function from the saved input; built from burn's exp it still cost two libm
/// exponentials and a dozen tensor passes per activation, a third of the update. So the value
/// is computed on the host by [`fast_tanh`] (a loop the compiler vectorises), and the tape
/// records only `x·s + (t − x·s)` with the constant slope `s = 1 − t²`: the value `t` to
/// rounding and exactly tanh's derivative, in two tensor ops. The bias unit is `s = 0, t = 1`.
pub fn tanh(x: Tensor<2>) -> Result<Tensor<2>, LearnerError> {
    let dims = x.dims();
    let device = x.device();
    let xs = read(x.clone().inner(), "activation")?;
    let mut t: Vec<f32> = xs.iter().map(|&v| fast_tanh(v)).collect();
    let bias_unit = |v: &mut [f32], value: f32| {
        v.chunks_exact_mut(dims[1])
            .for_each(|row| row[dims[1] - 1] = value);
    };
    bias_unit(&mut t, 1.0);
    let constant = |v: Vec<f32>| Tensor::<2>::from_data(TensorData::new(v, dims), &device);
    if !x.is_tracked() {
        return Ok(constant(t));
    }
    // Two exact-size passes: each collects into one allocation and vectorises.
    let mut slope: Vec<f32> = t.iter().map(|t| 1.0 - t * t).collect();
    bias_unit(&mut slope, 0.0);
    let offset: Vec<f32> = (xs.iter().zip(&t).zip(&slope))
        .map(|((x, t), s)| t - x * s)
        .collect();
    Ok(x * constant(slope) + constant(offset))
}

/// A tensor's values on the host, naming `what` if burn cannot read them.
pub fn read<const D: usize>(t: Tensor<D>, what: &'static str) -> Result<Vec<f32>, LearnerError> {
    t.try_into_vec_as::<f32>()
        .map_err(|e| LearnerError::Tensor {
            what,
            reason: e.to_string(),
        })
}

/// A `rows × cols` row-major matrix whose shorter side is orthonormal, times `gain`: the Q of
/// a Gaussian matrix's QR decomposition (Gram–Schmidt), as `torch.nn.init.orthogonal_`.
pub fn orthogonal(rows: usize, cols: usize, gain: f64, rng: &mut Rng) -> Vec<f32> {
    let (long, short) = (rows.max(cols), rows.min(cols));
    let mut q: Vec<Vec<f64>> = (0..short)
        .map(|_| (0..long).map(|_| rng.normal()).collect())
        .collect();
    for i in 0..short {
        let (done, rest) = q.split_at_mut(i);
        let v = &mut rest[0];
        // Two passes of modified Gram–Schmidt keep the basis orthogonal to rounding error.
        for _ in 0..2 {
            for u in done.iter() {
                let d: f64 = u.iter().zip(v.iter()).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(x, a)| *x -= d * a);
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x /= norm);
    }
    let mut w = vec![0.0f32; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            let x = if rows >= cols { q[c][r] } else { q[r][c] };
            w[r * cols + c] = (gain * x) as f32;
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_follow_the_policy_layout() {
        let layout = PolicyLayout::new(10, &[128, 128], 2);
        let shape = NetShape::new(&layout);
        let d = layout.dense_layers();
        let stats = 2 * layout.obs_dim;
        for (l, dense) in d.iter().enumerate() {
            assert_eq!(shape.blocks[2 * l].offset + stats, dense.weight);
            assert_eq!(shape.blocks[2 * l + 1].offset + stats, dense.bias);
        }
        assert_eq!(
            shape.blocks[shape.log_std_block()].offset + stats,
            layout.log_std()
        );
        assert_eq!(shape.actor_len() + stats, layout.len());
        let critic = (10 * 128 + 128) + (128 * 128 + 128) + (128 + 1);
        assert_eq!(shape.len(), shape.actor_len() + critic);
        assert_eq!(shape.blocks.len(), 13);
    }

    #[test]
    fn orthogonal_matrices_have_orthonormal_short_sides() {
        let mut rng = Rng::new(3);
        for (rows, cols) in [(10, 64), (64, 64), (64, 2)] {
            let gain = 1.5;
            let w = orthogonal(rows, cols, gain, &mut rng);
            // Gram matrix of the shorter side's vectors.
            let short = rows.min(cols);
            let at = |i: usize, k: usize| -> f64 {
                let (r, c) = if rows >= cols { (k, i) } else { (i, k) };
                f64::from(w[r * cols + c])
            };
            for i in 0..short {
                for j in 0..short {
                    let dot: f64 = (0..rows.max(cols)).map(|k| at(i, k) * at(j, k)).sum();
                    let want = if i == j { gain * gain } else { 0.0 };
                    assert!((dot - want).abs() < 1e-5, "{rows}x{cols} ({i},{j}) {dot}");
                }
            }
        }
    }

    #[test]
    fn init_uses_cleanrl_gains_and_zero_biases() {
        let layout = PolicyLayout::new(10, &[64, 64], 2);
        let shape = NetShape::new(&layout);
        let p = shape.init(true, -0.5, &mut Rng::new(1));
        let norm = |s: ParamBlock| {
            p[s.range()]
                .iter()
                .map(|x| f64::from(*x).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        // Frobenius norm of an orthogonal block = gain · sqrt(short side).
        assert!((norm(shape.blocks[0]) - 2f64.sqrt() * 10f64.sqrt()).abs() < 1e-4);
        assert!(
            (norm(shape.blocks[4]) - 0.01 * 2f64.sqrt()).abs() < 1e-6,
            "policy head"
        );
        let critic_head = shape.blocks[shape.blocks.len() - 2];
        assert!((norm(critic_head) - 1.0).abs() < 1e-5, "value head");
        assert!(p[shape.blocks[1].range()].iter().all(|&b| b == 0.0));
        assert!(p[shape.blocks[6].range()].iter().all(|&x| x == -0.5));
        let plain = shape.init(false, 0.0, &mut Rng::new(1));
        let bound = 1.0 / 64f32.sqrt();
        assert!(
            plain[shape.blocks[3].range()]
                .iter()
                .all(|b| b.abs() <= bound)
        );
        assert!(plain[shape.blocks[3].range()].iter().any(|&b| b != 0.0));
    }

    /// The tape sees tanh's value and exactly its derivative 1 − tanh²; the last column is the
    /// bias unit, 1 without gradient.
    #[test]
    fn tensor_tanh_has_tanh_value_and_gradient() {
        let xs: Vec<f32> = (-40..=40).map(|i| i as f32 * 0.2).collect();
        let device = Device::flex().autodiff();
        let x = Tensor::<2>::from_data(TensorData::new(xs.clone(), [1, xs.len()]), &device)
            .require_grad();
        let y = tanh(x.clone()).expect("tanh");
        let ys = read(y.clone(), "tanh").expect("read");
        let grads = y.sum().backward();
        let g = read(x.grad(&grads).expect("grad"), "grad").expect("read");
        let last = xs.len() - 1;
        for ((x, y), g) in xs.iter().zip(&ys).zip(&g).take(last) {
            assert!((x.tanh() - y).abs() < 3e-7, "tanh({x}) = {y}");
            assert!(
                (1.0 - fast_tanh(*x).powi(2) - g).abs() < 1e-7,
                "tanh'({x}) = {g}"
            );
        }
        assert_eq!((ys[last], g[last]), (1.0, 0.0));
    }

    /// Folding biases into the weight matrices and back loses nothing.
    #[test]
    fn gradients_land_in_their_blocks() {
        let layout = PolicyLayout::new(3, &[4], 2);
        let shape = NetShape::new(&layout);
        let params: Vec<f32> = (0..shape.len()).map(|i| i as f32).collect();
        let device = Device::flex().autodiff();
        let net = shape.tensors(&params, &device, true);
        // d/dθ of Σ θ² over all leaves is 2θ, bias units excluded (they hold zeros).
        let loss = net
            .actor
            .iter()
            .chain(&net.critic)
            .chain([&net.log_std])
            .map(|t| t.clone().square().sum())
            .reduce(|a, b| a + b)
            .expect("leaves");
        let mut grads = vec![f32::NAN; shape.len()];
        shape
            .gradients(&net, &loss.backward(), &mut grads)
            .expect("gradients");
        let want: Vec<f32> = params.iter().map(|p| 2.0 * p).collect();
        assert_eq!(grads, want);
    }
}
