"""`lavatube export`'s ONNX actor in the runtimes robot teams use: onnx's checker accepts
it, and onnxruntime takes the simulator's actions on 10,000 observations (the check rows
`lavatube export` writes with lavatube's own forward pass), clipped extremes included."""

import struct
import subprocess

import numpy as np
import onnx
import onnxruntime as ort

ROWS = 10_000


def write_policy(path, hidden=(64, 64), obs=10, act=2, seed=3):
    """A seeded actor in lavatube's `.policy` format, with normalisation stats of its own."""
    rng = np.random.default_rng(seed)
    widths = [obs, *hidden, act]
    mean = rng.uniform(-0.5, 0.5, obs)
    var = rng.uniform(0.01, 4.0, obs)
    layers = [np.concatenate([rng.normal(0, 0.4, i * o), rng.normal(0, 0.4, o)])
              for i, o in zip(widths, widths[1:])]
    weights = np.concatenate([mean, var, *layers, np.zeros(act)]).astype("<f4")
    head = struct.pack("<8sIII", b"LTPOLICY", 1, obs, len(hidden))
    head += struct.pack(f"<{len(hidden)}II", *hidden, act)
    head += struct.pack("<fI", 5.0, len(weights))
    path.write_bytes(head + weights.tobytes())


def test_onnxruntime_takes_the_simulators_actions(tmp_path, bin_dir):
    policy, out = tmp_path / "actor.policy", tmp_path / "export"
    write_policy(policy)
    subprocess.run([bin_dir / "lavatube", "export", policy, "--out", out,
                    "--check-rows", str(ROWS)], check=True, capture_output=True)
    model = onnx.load(str(out / "general.onnx"))
    onnx.checker.check_model(model, full_check=True)
    meta = {p.key: p.value for p in model.metadata_props}
    assert meta["lavatube.slot"] == "general" and meta["action.unit"] == "rad/s"

    rows = np.loadtxt(out / "general.check.csv", delimiter=",", skiprows=1, dtype=np.float32)
    assert rows.shape == (ROWS, 12)
    actor = ort.InferenceSession(str(out / "general.onnx"), providers=["CPUExecutionProvider"])
    assert [i.name for i in actor.get_inputs()] == ["obs"]
    (actions,) = actor.run(["action"], {"obs": rows[:, :10]})
    assert np.abs(actions - rows[:, 10:]).max() <= 1e-5
    # Both clips are exercised: actions at the limit, observations far past the normaliser's.
    assert (np.abs(rows[:, 10:]) == 3.0).any(axis=1).mean() > 0.05
    assert (np.abs(rows[:, :10]) > 20).any(axis=1).mean() > 0.2
