"""A real run of `configs/smoke.toml` (conftest.py's `run` fixture), read while it runs."""

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import lavatube

LAYOUTS = json.loads(
    (Path(__file__).resolve().parents[1] / "lavatube" / "layouts.json").read_text())
#: Seconds for the run's services to appear (debug binaries on a busy machine).
APPEAR_S = 30


def test_a_live_run_reads_back_through_the_package(run):
    with ThreadPoolExecutor(2) as pool:
        policies = pool.submit(list, lavatube.policy_headers(run.id, timeout=APPEAR_S))
        estimates = pool.submit(list, lavatube.terrain(run.id, timeout=APPEAR_S))
        ticks = list(lavatube.telemetry(run.id, timeout=APPEAR_S))
    policies, estimates = policies.result(), estimates.result()
    assert run.proc.wait(timeout=APPEAR_S) == 0, "the run failed or was killed by the watchdog"

    assert ticks, "no telemetry tick arrived"
    assert (np.diff([t.tick for t in ticks]) > 0).all(), "tick numbers must rise"
    env_tick = LAYOUTS["types"]["EnvTick"]["size"]
    for t in ticks:
        assert t.envs == 4  # smoke.toml: 2 flat + 2 rough
        assert sorted(t.env) == list(range(t.envs))
        # The columns view one copy of the payload: `envs` EnvTicks as Rust lays them out.
        assert t.env.base.nbytes == t.envs * env_tick
        assert t.pos.shape == t.euler.shape == (t.envs, 3)
        np.testing.assert_allclose(t.sin_pitch, np.sin(t.euler[:, 0]), rtol=1e-6, atol=1e-7)
        # smoke.toml simulates no IMU: its filtered angles are NaN, not zeros.
        assert t.imu_euler.shape == (t.envs, 3)
        assert np.isnan(t.imu_euler).all() and np.isnan(t.imu_sin_pitch).all()

    assert policies, "no policy header arrived"
    assert np.all(np.diff([p.version for p in policies]) > 0), "policy versions must rise"
    assert {(p.obs_dim, p.act_dim, tuple(p.hidden[:p.n_hidden])) for p in policies} == {
        (lavatube.wire.OBS_DIM, lavatube.wire.ACT_DIM, (32, 32))}  # smoke.toml: [32, 32]

    assert estimates, "no terrain estimate arrived"
    for e in estimates:
        assert sorted(e.env) == list(range(e.envs))
        assert set(e.class_) <= {0, 1, lavatube.wire.CLASS_UNKNOWN}
