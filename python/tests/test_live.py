"""A real run of `configs/smoke.toml`, started with the built launcher and read while it runs.

The launcher is `target/debug/lavatube` of this checkout, or the one in `$LAVATUBE_BIN_DIR`;
without it the test is skipped. The run directory goes to pytest's tmp_path.
"""

import json
import os
import re
import subprocess
import threading
import uuid
from collections import namedtuple
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

import lavatube

ROOT = Path(__file__).resolve().parents[2]
LAYOUTS = json.loads((ROOT / "python" / "lavatube" / "layouts.json").read_text())
#: Seconds for the run's services to appear (debug binaries on a busy machine), and for the
#: whole run, after which a watchdog kills the launcher (its processes follow it).
APPEAR_S, LIMIT_S = 30, 180

Run = namedtuple("Run", "id proc")


@pytest.fixture
def run(tmp_path):
    """A smoke run writing under tmp_path; the launcher is stopped at the end if still up."""
    launcher = Path(os.environ.get("LAVATUBE_BIN_DIR", ROOT / "target" / "debug")) / "lavatube"
    if not launcher.is_file():
        pytest.skip(f"no launcher at {launcher}: build the workspace or set LAVATUBE_BIN_DIR")
    # `run.out-dir` is relative to the working directory: point it at tmp_path instead.
    config, n = re.subn(r"(?m)^out-dir = .*$", f"out-dir = {json.dumps(str(tmp_path))}",
                        (ROOT / "configs" / "smoke.toml").read_text())
    assert n == 1, "configs/smoke.toml no longer sets run.out-dir"
    (tmp_path / "smoke.toml").write_text(config)
    run_id = f"py-{uuid.uuid4().hex[:12]}"
    log = tmp_path / "launcher.log"
    with log.open("w") as out:
        proc = subprocess.Popen([launcher, "run", "--config", tmp_path / "smoke.toml",
                                 "--run-id", run_id, "--quiet"],
                                cwd=tmp_path, stdout=out, stderr=subprocess.STDOUT)
    watchdog = threading.Timer(LIMIT_S, proc.kill)
    watchdog.start()
    try:
        yield Run(run_id, proc)
    finally:
        watchdog.cancel()
        proc.terminate()  # the launcher stops its processes and removes the run's memory
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        print(log.read_text())  # shown when the test fails


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

    assert policies, "no policy header arrived"
    assert np.all(np.diff([p.version for p in policies]) > 0), "policy versions must rise"
    assert {(p.obs_dim, p.act_dim, tuple(p.hidden[:p.n_hidden])) for p in policies} == {
        (lavatube.wire.OBS_DIM, lavatube.wire.ACT_DIM, (32, 32))}  # smoke.toml: [32, 32]

    assert estimates, "no terrain estimate arrived"
    for e in estimates:
        assert sorted(e.env) == list(range(e.envs))
        assert set(e.class_) <= {0, 1, lavatube.wire.CLASS_UNKNOWN}
