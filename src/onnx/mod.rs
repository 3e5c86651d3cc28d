//! An actor as an ONNX model: the deterministic policy the simulator runs with
//! `sim.mean-actions`, from raw observation to clipped wheel command, for runtimes outside
//! lavatube (onnxruntime, tract, TensorRT).
//!
//! Graph (opset 17): `obs` `[batch, D]` → `(obs − mean) / √(var + 1e-8)` → clip to
//! ±obs-clip → per hidden layer `tanh(x·W + b)` → mean head `x·W + b` → clip to ±action
//! limit → `action` `[batch, A]`. The normaliser's divisor is computed in f32 exactly as the
//! simulator computes it. The hidden layers' tanh is ONNX's own; the simulator's agrees with
//! it within 2e-7 ([`common::policy::fast_tanh`]).

pub mod proto;

use common::Policy;
use common::policy::OBS_NORM_EPS;
use prost::Message;
use proto::{
    Dimension, DimensionValue, GraphProto, ModelProto, NodeProto, OperatorSetIdProto,
    StringStringEntryProto, TensorProto, TensorShapeProto, TensorType, TypeProto, ValueInfoProto,
};

/// The ONNX operator set the graph is written for, and the IR version that goes with it.
pub const OPSET: i64 = 17;
const IR_VERSION: i64 = 8;
/// The graph's input and output names.
pub const INPUT: &str = "obs";
pub const OUTPUT: &str = "action";

/// What the model file says about itself besides the graph: a description and metadata
/// entries (observation terms, units, control period, provenance).
#[derive(Debug, Clone, Default)]
pub struct Described {
    pub doc: String,
    pub metadata: Vec<(String, String)>,
}

/// The ONNX model (serialised `ModelProto`) of `policy`'s mean action clipped at
/// ±`action_limit`.
pub fn actor(policy: &Policy, action_limit: f32, described: &Described) -> Vec<u8> {
    let mut g = Graph::default();
    let l = policy.layout();
    let w = policy.weights();
    let mean = &w[l.obs_mean()..l.obs_mean() + l.obs_dim];
    let std: Vec<f32> = w[l.obs_var()..l.obs_var() + l.obs_dim]
        .iter()
        .map(|v| (v + OBS_NORM_EPS).sqrt())
        .collect();
    g.constant("obs_mean", vec![l.obs_dim as i64], mean.to_vec());
    g.constant("obs_std", vec![l.obs_dim as i64], std);
    g.node("Sub", &[INPUT, "obs_mean"], "centred");
    g.node("Div", &["centred", "obs_std"], "normalised");
    let mut x = g.clip("normalised", "obs_clip", policy.obs_clip(), "x0");
    let layers = l.dense_layers();
    let last = layers.len() - 1;
    for (k, d) in layers.iter().enumerate() {
        let (weight, bias) = (format!("layer{k}.weight"), format!("layer{k}.bias"));
        let dims = vec![d.inputs as i64, d.outputs as i64];
        g.constant(&weight, dims, w[d.weight..d.bias].to_vec());
        g.constant(
            &bias,
            vec![d.outputs as i64],
            w[d.bias..d.bias + d.outputs].to_vec(),
        );
        let pre = if k < last {
            format!("layer{k}.linear")
        } else {
            "mean".to_string()
        };
        g.node("Gemm", &[&x, &weight, &bias], &pre);
        x = if k < last {
            let out = format!("x{}", k + 1);
            g.node("Tanh", &[&pre], &out);
            out
        } else {
            pre
        };
    }
    g.clip(&x, "action_limit", action_limit, OUTPUT);
    model(g, l.obs_dim, l.act_dim, described).encode_to_vec()
}

/// Nodes and constants in the order they are added (which is topological).
#[derive(Default)]
struct Graph {
    nodes: Vec<NodeProto>,
    constants: Vec<TensorProto>,
}

impl Graph {
    fn constant(&mut self, name: &str, dims: Vec<i64>, data: Vec<f32>) {
        self.constants.push(TensorProto {
            dims,
            data_type: proto::FLOAT,
            float_data: data,
            name: name.to_string(),
        });
    }

    fn node(&mut self, op: &str, inputs: &[&str], output: &str) {
        self.nodes.push(NodeProto {
            input: inputs.iter().map(|s| (*s).to_string()).collect(),
            output: vec![output.to_string()],
            name: format!("{op}_{}", self.nodes.len()),
            op_type: op.to_string(),
        });
    }

    /// Clips `input` to ±`limit` (scalar constants `<name>_min`, `<name>_max`) into `output`.
    fn clip(&mut self, input: &str, name: &str, limit: f32, output: &str) -> String {
        let (lo, hi) = (format!("{name}_min"), format!("{name}_max"));
        self.constant(&lo, Vec::new(), vec![-limit]);
        self.constant(&hi, Vec::new(), vec![limit]);
        self.node("Clip", &[input, &lo, &hi], output);
        output.to_string()
    }
}

/// A `[batch, width]` float tensor's description.
fn batch_of(name: &str, width: usize, doc: &str) -> ValueInfoProto {
    let dim = |value| Dimension { value: Some(value) };
    ValueInfoProto {
        name: name.to_string(),
        r#type: Some(TypeProto {
            tensor_type: Some(TensorType {
                elem_type: proto::FLOAT,
                shape: Some(TensorShapeProto {
                    dim: vec![
                        dim(DimensionValue::DimParam("batch".to_string())),
                        dim(DimensionValue::DimValue(width as i64)),
                    ],
                }),
            }),
        }),
        doc_string: doc.to_string(),
    }
}

fn model(g: Graph, obs_dim: usize, act_dim: usize, described: &Described) -> ModelProto {
    ModelProto {
        ir_version: IR_VERSION,
        producer_name: "lavatube".to_string(),
        producer_version: env!("CARGO_PKG_VERSION").to_string(),
        domain: String::new(),
        model_version: 1,
        doc_string: described.doc.clone(),
        graph: Some(GraphProto {
            node: g.nodes,
            name: "actor".to_string(),
            initializer: g.constants,
            doc_string: String::new(),
            input: vec![batch_of(
                INPUT,
                obs_dim,
                "raw observations, one row per robot",
            )],
            output: vec![batch_of(OUTPUT, act_dim, "wheel commands, clipped")],
        }),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }],
        metadata_props: described
            .metadata
            .iter()
            .map(|(key, value)| StringStringEntryProto {
                key: key.clone(),
                value: value.clone(),
            })
            .collect(),
    }
}
