"""`lavatube.gym` against real runs: Gymnasium's env checker, the same trajectories as
`sim-proc` replaying the same actions, and clients killed mid-run."""

import csv
import signal
import subprocess
import sys
import textwrap
import time
import uuid
import warnings
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lavatube.gym

ROOT = Path(__file__).resolve().parents[2]
GYM = ROOT / "configs" / "gym.toml"
#: Seconds for a run to come up and for each answer (debug binaries on a busy machine).
TIMEOUT_S = 60


def overrides(tmp_path, **sim):
    """configs/gym.toml with its run directory under tmp_path and one sim thread."""
    return {"run": {"out-dir": str(tmp_path)}, "sim": {"threads": 1, **sim}}


def test_the_single_env_view_passes_gymnasiums_env_checker(tmp_path, bin_dir):
    env = lavatube.gym.Env(GYM, area="rough", overrides=overrides(tmp_path),
                           timeout=TIMEOUT_S, bin_dir=bin_dir)
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            check_env(env, skip_render_check=True)
        # What it may say: the paper's action bounds (±3 rad/s) are not [-1, 1], and the
        # target's position in the robot frame is unbounded.
        allowed = ("symmetric and normalized", "infinity")
        assert [str(w.message) for w in said if not any(a in str(w.message) for a in allowed)] == []
        obs, info = env.reset(seed=3)
        assert obs in env.observation_space and info == {"area": 1}
    finally:
        env.close()


def test_random_steps_match_sim_proc_replaying_the_same_actions(tmp_path, bin_dir):
    steps, seed = 1000, 5
    envs = lavatube.gym.VectorEnv(GYM, overrides=overrides(tmp_path, envs={"flat": 4, "rough": 4}),
                                  timeout=TIMEOUT_S, bin_dir=bin_dir)
    try:
        assert envs.num_envs == 8 and envs.metadata["autoreset_mode"].name == "SAME_STEP"
        envs.action_space.seed(seed)
        first, _ = envs.reset(seed=seed)
        actions, obs, rewards, terminated, truncated, final_obs = [], [first], [], [], [], {}
        for t in range(steps):
            a = envs.action_space.sample()
            o, r, te, tr, info = envs.step(a)
            assert o in envs.observation_space
            actions.append(a), obs.append(o), rewards.append(r)
            terminated.append(te), truncated.append(tr)
            for i in np.flatnonzero(info.get("_final_obs", [])):
                final_obs[t, i] = info["final_obs"][i]
        # Gymnasium's per-env seeds [s, s+1, …] name the same envs as s; other lists cannot.
        again, _ = envs.reset(seed=list(range(seed, seed + 8)))
        np.testing.assert_array_equal(again, first)
        with pytest.raises(ValueError, match="one seed"):
            envs.reset(seed=[seed] * 8)
    finally:
        envs.close()
    assert envs._launcher.proc.returncode == 0, envs._launcher.log.read_text()
    ended = np.array(terminated) | np.array(truncated)
    assert ended.sum() > 0 and len(final_obs) == ended.sum(), "episodes ended, final obs given"

    # The same config, seed and actions, stepped by sim-proc alone.
    with (tmp_path / "actions.csv").open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["tick", "env", "left", "right"])
        for t, a in enumerate(actions):
            out.writerows([t, i, repr(float(l)), repr(float(r))] for i, (l, r) in enumerate(a))
    config = tmp_path / "replay.toml"
    config.write_text(f'extends = "{GYM}"\n[sim]\nenvs = {{ flat = 4, rough = 4 }}\nthreads = 1\n')
    subprocess.run([bin_dir / "sim-proc", "--config", config, "--seed", str(seed),
                    "--controller", "replay", "--actions", tmp_path / "actions.csv",
                    "--steps", str(steps), "--telemetry", tmp_path / "telemetry.csv",
                    "--observations", tmp_path / "obs.csv"], check=True, timeout=TIMEOUT_S)
    replayed = np.loadtxt(tmp_path / "obs.csv", delimiter=",", skiprows=1, dtype=np.float32)
    np.testing.assert_array_equal(replayed[:, 2:].reshape(steps, 8, 10), np.array(obs[1:]))
    with (tmp_path / "telemetry.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == steps * 8
    field = lambda name, kind: np.array([kind(r[name]) for r in rows]).reshape(steps, 8)
    flag = lambda v: v == "true"
    np.testing.assert_array_equal(field("reward", np.float32), np.array(rewards, np.float32))
    np.testing.assert_array_equal(field("terminated", flag), np.array(terminated))
    np.testing.assert_array_equal(field("truncated", flag), np.array(truncated))
    # An ended episode's last observation is the state the replay's telemetry row describes:
    # its pitch and roll terms are cos/sin of that row's angles.
    for (t, i), o in final_obs.items():
        row = rows[t * 8 + i]
        np.testing.assert_allclose(o[4:6], [np.cos(float(row["theta_x"])),
                                            np.sin(float(row["theta_x"]))], atol=1e-6)


CLIENT = textwrap.dedent("""
    import sys, lavatube.gym
    envs = lavatube.gym.VectorEnv(run_id=sys.argv[1], timeout=60)
    envs.reset(seed=1)
    for _ in range(20):
        envs.step(envs.action_space.sample())
    print("stepping", flush=True)
    while True:
        envs.step(envs.action_space.sample())
""")


def start_run(tmp_path, bin_dir, stay_up: bool):
    """`lavatube run` on configs/gym.toml with a one-second client timeout."""
    config = tmp_path / "gym.toml"
    config.write_text(f'extends = "{GYM}"\n[run]\nout-dir = "{tmp_path}"\n[sim]\nthreads = 1\n'
                      f'[sim.external]\ntimeout-s = 1.0\nstay-up = {str(stay_up).lower()}\n')
    run_id = f"gym-{uuid.uuid4().hex[:12]}"
    log = (tmp_path / "launcher.log").open("w")
    proc = subprocess.Popen([bin_dir / "lavatube", "run", "--config", config, "--run-id", run_id,
                             "--quiet"], stdout=log, stderr=subprocess.STDOUT)
    return run_id, proc


def kill_a_client_mid_run(run_id):
    """A client in its own process that steps the run until it is killed with SIGKILL."""
    client = subprocess.Popen([sys.executable, "-c", CLIENT, run_id], stdout=subprocess.PIPE,
                              text=True)
    try:
        assert client.stdout.readline().strip() == "stepping"
    finally:
        client.send_signal(signal.SIGKILL)
        client.wait()


def test_a_killed_client_ends_the_run_with_an_error_not_a_hang(tmp_path, bin_dir):
    run_id, launcher = start_run(tmp_path, bin_dir, stay_up=False)
    try:
        kill_a_client_mid_run(run_id)
        assert launcher.wait(timeout=TIMEOUT_S) != 0
    finally:
        launcher.kill()
        launcher.wait()
    sim_log = (tmp_path / run_id / "logs" / "sim.log").read_text()
    assert "no request from the gym client for 1 s" in sim_log, sim_log


def test_a_sim_that_stays_up_serves_the_next_client_after_one_is_killed(tmp_path, bin_dir):
    run_id, launcher = start_run(tmp_path, bin_dir, stay_up=True)
    try:
        kill_a_client_mid_run(run_id)
        sim_log = tmp_path / run_id / "logs" / "sim.log"
        deadline = time.monotonic() + TIMEOUT_S
        while "waiting for the next client" not in sim_log.read_text():
            assert time.monotonic() < deadline, sim_log.read_text()
            assert launcher.poll() is None, "the run ended"
            time.sleep(0.1)
        envs = lavatube.gym.VectorEnv(run_id=run_id, timeout=TIMEOUT_S)
        try:
            obs, _ = envs.reset(seed=2)
            obs2, *_ = envs.step(np.zeros((envs.num_envs, 2), dtype=np.float32))
            assert obs.shape == obs2.shape == (8, 10)
        finally:
            envs.close()
        assert launcher.poll() is None, "a sim that stays up outlives its clients"
    finally:
        launcher.send_signal(signal.SIGTERM)
        assert launcher.wait(timeout=TIMEOUT_S) == 128 + signal.SIGINT, "stopped as by Ctrl-C"
