"""lavatube's simulator as a Gymnasium vector env, stepped over the run's shared memory.

    import lavatube.gym
    envs = lavatube.gym.VectorEnv("configs/gym.toml")
    obs, info = envs.reset(seed=1)
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    envs.close()

`VectorEnv(config)` starts `lavatube run` on the config, turned into a gym run (no learners,
`sim.acting = "external"`), and steps its envs: each step writes the actions into an iceoryx2
sample and reads every env's observation, reward and flags back from one, with no
serialisation. `VectorEnv(run_id=...)` joins a run started by hand instead. `Env` is a
one-env `gymnasium.Env` view for code and checkers that want a single env.

Episodes follow Gymnasium 1.x's same-step autoreset (`AutoresetMode.SAME_STEP`): an env whose
episode ends in a step returns the next episode's first observation at once, with the ended
one's last in `info["final_obs"]` and its `success` and `episode_steps` in
`info["final_info"]`. `reset(seed=s)` rebuilds every env as a run with `run.seed = s` builds
them (the same trajectories as `sim-proc --seed s --controller replay`); `reset()` without a
seed starts every env's next episode from a new random pose.
"""

import ctypes
import json
import os
import signal
import subprocess
import tempfile
import time
import uuid
from pathlib import Path

import gymnasium
import iceoryx2 as iox2
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from . import wire
from .ipc import _RUN_ID

#: Observation bounds (SPEC S5): the target in the robot frame and its ground distance are
#: unbounded; the six attitude terms are cosines and sines.
_OBS_LOW = np.array([-np.inf] * 3 + [0.0] + [-1.0] * 6, dtype=np.float32)
_OBS_HIGH = np.array([np.inf] * 4 + [1.0] * 6, dtype=np.float32)
#: The longest sleep between two looks at whether the sim is still there.
_POLL = iox2.Duration.from_millis(50)
#: Linux's prctl(PR_SET_PDEATHSIG): a launcher this process starts is told to stop (SIGTERM)
#: when this process dies, even by SIGKILL.
_PR_SET_PDEATHSIG = 1


class VectorEnv(gymnasium.vector.VectorEnv):
    """The envs of one lavatube run, stepped together.

    config: a lavatube config file, started as a new run, with `overrides` laid over it by
      section (e.g. `{"sim": {"envs": {"flat": 8}}, "run": {"out-dir": "/tmp/runs"}}`); or run_id:
      a run already serving gym clients (`lavatube run --config configs/gym.toml`), joined.
    timeout: seconds to wait for the sim to come up and for each answer.
    bin_dir: where the `lavatube` binaries are; default `$LAVATUBE_BIN_DIR`, else `PATH`.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, config: str | os.PathLike | None = None, *, run_id: str | None = None,
                 overrides: dict[str, dict] | None = None, timeout: float = 60.0,
                 bin_dir: str | os.PathLike | None = None):
        if (config is None) == (run_id is None):
            raise ValueError("give either config (a new run) or run_id (a running one)")
        self._launcher = None
        if config is not None:
            run_id = f"gym-{uuid.uuid4().hex[:12]}"
            self._launcher = _Launcher(Path(config), run_id, overrides or {}, bin_dir)
        elif not _RUN_ID.fullmatch(run_id):
            raise ValueError(f"run id {run_id!r} must be 1-32 characters of A-Z a-z 0-9 -")
        self.run_id = run_id
        try:
            self._sim = _Client(run_id, timeout, self._launcher)
        except BaseException:
            if self._launcher is not None:
                self._launcher.stop(grace=0.0)
            raise
        self.num_envs = self._sim.envs
        limit = self._sim.action_limit
        self.single_observation_space = gymnasium.spaces.Box(_OBS_LOW, _OBS_HIGH,
                                                             dtype=np.float32)
        self.single_action_space = gymnasium.spaces.Box(-limit, limit, shape=(wire.ACT_DIM,),
                                                        dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._actions = np.zeros((self.num_envs, wire.ACT_DIM), dtype=np.float32)

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        """Every env's first observation, and `info["area"]` (the ground's code, from the
        terrain-kinds table of docs/CONFIG.md): rebuilt from
        `seed` (an int s, or the per-env list [s, s+1, …] Gymnasium makes of it), or with
        none each env's next episode from a new pose. `options` is unused."""
        seed = _one_seed(seed, self.num_envs)
        if seed is not None:
            self._np_random, self._np_random_seed = gymnasium.utils.seeding.np_random(int(seed))
        table = self._sim.request(wire.GYM_RESET, seed=seed)
        return table["obs"], {"area": table["area"], "_area": np.ones(self.num_envs, dtype=bool)}

    def step(self, actions):
        """One decision step of every env: `actions` (num_envs, 2) wheel commands, clipped by
        the sim to the action space. Returns observations, rewards, terminated, truncated and
        infos (`area`; for envs whose episode ended, `final_obs` and `final_info`)."""
        self._actions[:] = actions
        table = self._sim.request(wire.GYM_STEP, actions=self._actions)
        terminated = table["terminated"].astype(bool)
        truncated = table["truncated"].astype(bool)
        infos = {"area": table["area"], "_area": np.ones(self.num_envs, dtype=bool)}
        ended = terminated | truncated
        if ended.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(ended):
                final_obs[i] = table["final_obs"][i]
            infos.update(final_obs=final_obs, _final_obs=ended, _final_info=ended,
                         final_info={"success": table["success"].astype(bool), "_success": ended,
                                     "episode_steps": table["episode_steps"].astype(np.int64),
                                     "_episode_steps": ended})
        return table["obs"], table["reward"].astype(np.float64), terminated, truncated, infos

    def close_extras(self, **kwargs):
        """Leaves the run; a run this env started ends with it."""
        if hasattr(self, "_sim"):  # not when the constructor failed
            self._sim.close()
            if self._launcher is not None:
                self._launcher.stop()


def _one_seed(seed, envs: int) -> int | None:
    """The one seed the sim rebuilds every env from: `seed` itself, or the first of a per-env
    list that counts up from it by one, as Gymnasium's vector envs seed theirs."""
    if seed is None or isinstance(seed, (int, np.integer)):
        return None if seed is None else int(seed)
    seeds = list(seed)
    if (len(seeds) == envs and isinstance(seeds[0], (int, np.integer))
            and seeds == [seeds[0] + i for i in range(envs)]):
        return int(seeds[0])
    raise ValueError(f"the sim seeds all {envs} envs from one seed: give an int s or the list "
                     f"[s, s+1, …], not {seed!r}")


class Env(gymnasium.Env):
    """One env of lavatube's simulator as a `gymnasium.Env` (a one-env `VectorEnv` underneath).

    config, overrides: as `VectorEnv`'s; area: where the env drives, a terrain kind (`flat`,
    `rough`, or another kind with an area in the config) or `mixed`; the launcher refuses
    any other name before the run starts.
    An episode's last step returns its last observation; the next `reset()` returns the next
    episode's first (which the sim has already begun, from where the robot stands, SPEC S3).
    """

    metadata = {"render_modes": []}

    def __init__(self, config: str | os.PathLike, *, area: str = "flat",
                 overrides: dict[str, dict] | None = None, timeout: float = 60.0,
                 bin_dir: str | os.PathLike | None = None):
        overrides = {section: dict(values) for section, values in (overrides or {}).items()}
        overrides.setdefault("sim", {})["envs"] = {area: 1}
        self._vec = VectorEnv(config, overrides=overrides, timeout=timeout, bin_dir=bin_dir)
        self.observation_space = self._vec.single_observation_space
        self.action_space = self._vec.single_action_space
        self._next = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None and self._next is not None:
            obs, info = self._next
        else:
            obs, info = self._vec.reset(seed=seed)
            obs, info = obs[0], {"area": int(info["area"][0])}
        self._next = None
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self._vec.step(np.asarray(action)[None])
        obs, step_info = obs[0], {"area": int(info["area"][0])}
        if terminated[0] or truncated[0]:
            self._next = obs, step_info
            final = info["final_info"]
            obs = info["final_obs"][0]
            step_info = {"success": bool(final["success"][0]),
                         "episode_steps": int(final["episode_steps"][0])}
        return obs, float(reward[0]), bool(terminated[0]), bool(truncated[0]), step_info

    def close(self):
        self._vec.close()


def _toml(value) -> str:
    """A value as TOML: a dict as an inline table, anything else as JSON (which TOML reads
    alike for strings, numbers, booleans and lists)."""
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {_toml(v)}" for k, v in value.items()) + " }"
    return json.dumps(value)


class _Launcher:
    """`lavatube run` on `config` made a gym run, started by this process."""

    def __init__(self, config: Path, run_id: str, overrides: dict[str, dict], bin_dir):
        if not config.is_file():
            raise FileNotFoundError(f"config {config} not found")
        self._dir = tempfile.TemporaryDirectory(prefix="lavatube-gym-")
        overlay = Path(self._dir.name) / "gym.toml"
        tables = {"run": {"learners": []}, "sim": {"acting": "external"}}
        for section, values in overrides.items():
            tables.setdefault(section, {}).update(values)
        lines = [f"extends = {json.dumps(str(config.resolve()))}"]
        for section, values in tables.items():
            lines += [f"[{section}]"] + [f"{k} = {_toml(v)}" for k, v in values.items()]
        overlay.write_text("\n".join(lines) + "\n")
        bin_dir = bin_dir or os.environ.get("LAVATUBE_BIN_DIR")
        launcher = str(Path(bin_dir) / "lavatube") if bin_dir else "lavatube"
        self.log = Path(self._dir.name) / "launcher.log"
        with self.log.open("w") as out:
            self.proc = subprocess.Popen(
                [launcher, "run", "--config", str(overlay), "--run-id", run_id, "--quiet"],
                stdout=out, stderr=subprocess.STDOUT, preexec_fn=_stop_with_parent)

    def failed(self) -> str | None:
        """Why the run ended before its time (its launcher's output), if it did."""
        if self.proc.poll() is None:
            return None
        return f"lavatube run exited with {self.proc.returncode}: {self.log.read_text().strip()}"

    def stop(self, grace: float = 30.0):
        """Waits `grace` seconds for the run to end (its sim ends when the client closes),
        then stops it."""
        try:
            self.proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=30.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._dir.cleanup()


def _stop_with_parent():
    """In the launcher's process, before it runs: SIGTERM when this Python process dies."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


class _Client:
    """This process's ports on a run's `gym/act` and `gym/step` services."""

    def __init__(self, run_id: str, timeout: float, launcher: _Launcher | None):
        self.timeout, self._launcher = timeout, launcher
        config = iox2.config.default()
        config.global_cfg.prefix = iox2.FileName.new(f"lavatube_{run_id}_")
        act, step = f"lavatube/{run_id}/gym/act", f"lavatube/{run_id}/gym/step"
        deadline = time.monotonic() + timeout
        while not iox2.Service.does_exist(iox2.ServiceName.new(step), config,
                                          iox2.MessagingPattern.PublishSubscribe,
                                          iox2.ServiceType.Ipc):
            self._check(deadline, f"run {run_id!r} serves no gym client (no {step}); is its "
                                  'config sim.acting = "external"?', started=False)
            time.sleep(0.02)
        self._node = (iox2.NodeBuilder.new().name(iox2.NodeName.new("gym")).config(config)
                      .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
                      .create(iox2.ServiceType.Ipc))
        self._answers = self._open(step, wire.GymEnvStep, wire.GymStepHeader)
        self._subscriber = self._answers.subscriber_builder().create()
        self._woken = self._event(step).listener_builder().create()
        ready = None
        while ready is None:
            ready = self._subscriber.receive()
            if ready is None:
                self._check(deadline, f"run {run_id!r}: its sim sent nothing on {step}",
                            started=False)
                self._woken.timed_wait(_POLL)
        header = _header(ready)
        del ready
        self.envs, self.action_limit = header.envs, float(header.action_limit)
        self._requests = (self._open(act, ctypes.c_float, wire.GymActHeader)
                          .publisher_builder().initial_max_slice_len(self.envs * wire.ACT_DIM)
                          .create())
        self._wake = self._event(act).notifier_builder().create()
        # Numbers from a random start: an answer left from an earlier client never matches.
        self._request = int.from_bytes(os.urandom(7), "little")
        self._dtype = np.dtype(wire.GymEnvStep)

    def request(self, command: int, *, actions: np.ndarray | None = None,
                seed: int | None = None) -> np.ndarray:
        """Sends one request and returns the sim's answer, one GymEnvStep row per env."""
        self._request += 1
        n = 0 if actions is None else actions.size
        sample = self._requests.loan_slice_uninit(n)
        header = wire.GymActHeader(request=self._request, seed=seed or 0, command=command,
                                   flags=wire.GYM_SEEDED if seed is not None else 0)
        ctypes.memmove(sample.user_header_ptr, ctypes.addressof(header), ctypes.sizeof(header))
        if n:
            ctypes.memmove(sample.payload_ptr, actions.ctypes.data, actions.nbytes)
        sample.assume_init().send()
        self._wake.notify()
        deadline = time.monotonic() + self.timeout
        while True:
            answer = self._subscriber.receive()
            if answer is not None:
                header = _header(answer)
                if header.request == self._request:
                    if header.status != wire.GYM_OK:
                        raise RuntimeError(f"the sim refused the request (command "
                                           f"{command}); its log says why")
                    size = header.envs * self._dtype.itemsize
                    raw = (ctypes.c_byte * size).from_address(answer.payload_ptr)
                    return np.frombuffer(raw, self._dtype).copy()
                continue
            self._check(deadline, f"the sim did not answer within {self.timeout} s")
            self._woken.timed_wait(_POLL)

    def close(self):
        """Tells the sim this client leaves, then leaves the run's shared memory."""
        if self._answers.dynamic_config.number_of_publishers > 0:
            try:
                self.request(wire.GYM_CLOSE)
            except (RuntimeError, TimeoutError):
                pass
        del self._requests, self._wake, self._subscriber, self._woken, self._answers
        del self._node

    def _check(self, deadline: float, why: str, started: bool = True):
        """Raises when the run has ended, its sim is gone (once `started`), or `deadline` has
        passed."""
        failed = self._launcher.failed() if self._launcher is not None else None
        if failed:
            raise RuntimeError(failed)
        if started and self._answers.dynamic_config.number_of_publishers == 0:
            raise RuntimeError("the run's sim is gone (see the run's logs/sim.log)")
        if time.monotonic() > deadline:
            raise TimeoutError(why)

    def _open(self, name: str, element, header):
        return (self._node.service_builder(iox2.ServiceName.new(name))
                .publish_subscribe(iox2.Slice[element]).user_header(header).open())

    def _event(self, name: str):
        return self._node.service_builder(iox2.ServiceName.new(f"{name}.ready")).event().open()


def _header(sample) -> wire.GymStepHeader:
    """The sample's GymStepHeader, copied out of shared memory."""
    return wire.GymStepHeader.from_buffer_copy(
        ctypes.string_at(sample.user_header_ptr, ctypes.sizeof(wire.GymStepHeader)))
