"""The shared-memory message types of `common/src/wire.rs` and `common/src/rollout.rs`.

Each class is the ctypes twin of a `repr(C)` Rust struct, with the iceoryx2 type name of its
`#[type_name(...)]`: iceoryx2 refuses to connect a port whose type name, size or alignment
differs from the writer's. `layouts.json` beside this file holds the Rust compiler's sizes,
alignments and field offsets; a Rust test and a Python test check both sides against it.
"""

import ctypes

u8, u32, u64, f32 = ctypes.c_uint8, ctypes.c_uint32, ctypes.c_uint64, ctypes.c_float

#: Observation size and action size (SPEC S5, S2); the widest hidden-layer list of a policy.
OBS_DIM = 10
ACT_DIM = 2
MAX_HIDDEN = 4

#: Episode event bits of `EnvTick.events`.
EVENT_TERMINATED = 1
EVENT_TRUNCATED = 2
EVENT_SUCCESS = 4
EVENT_FAULT = 8
EVENT_PLACED = 16

#: `TerrainEstimate.class` before the estimator has seen enough ticks.
CLASS_UNKNOWN = 255

#: Bytes of a path in a `SwapRequest`, and of a `SwapReply`'s message.
SWAP_PATH_BYTES = 1024
SWAP_MESSAGE_BYTES = 512

#: Event id on `control.ready`: the launcher asks every process of the run to stop.
CONTROL_SHUTDOWN = 1


class Wire(ctypes.Structure):
    """Base of the message types: `type_name()` is what iceoryx2 compares across languages."""

    TYPE_NAME = ""

    @classmethod
    def type_name(cls) -> str:
        """The Rust `#[type_name(...)]` of this type."""
        return cls.TYPE_NAME


# ---- sim → learner: `rollout` ----------------------------------------------------------------


class RolloutHeader(Wire):
    """Header of a rollout chunk: `steps × envs` Transitions, then `envs` bootstrap ones."""

    TYPE_NAME = "lavatube.RolloutHeader.v3"
    _fields_ = [("chunk", u64), ("env_steps", u64), ("steps", u32), ("envs", u32),
                ("source", u32), ("_reserved", u32)]


class Transition(Wire):
    """One env's decision step, as the sim recorded it and the learner trains on it."""

    TYPE_NAME = "lavatube.Transition.v1"
    _fields_ = [("obs", f32 * OBS_DIM), ("action", f32 * ACT_DIM),
                ("final_obs", f32 * OBS_DIM), ("logprob", f32), ("reward", f32),
                ("policy_version", u32), ("env", u32), ("terminated", u8), ("truncated", u8),
                ("success", u8), ("area", u8), ("estimated_class", u8), ("slot", u8),
                ("_reserved", u8 * 2)]


# ---- learner → sim: `policy/<slot>` (the slice is the flat actor, f32) ------------------------


class PolicyHeader(Wire):
    """Header of a policy message: version, network shape and the learner's counters."""

    TYPE_NAME = "lavatube.PolicyHeader.v3"
    _fields_ = [("version", u32), ("slot", u32), ("obs_dim", u32), ("act_dim", u32),
                ("n_hidden", u32), ("hidden", u32 * MAX_HIDDEN), ("obs_clip", f32),
                ("updates", u64), ("env_steps", u64), ("chunks_seen", u64), ("learner", u32),
                ("write_failures", u32)]


# ---- sim → estimator, monitors: `telemetry` ---------------------------------------------------


class TickHeader(Wire):
    """Header of one telemetry tick; `sent_ns` is CLOCK_MONOTONIC (`time.monotonic_ns()`)."""

    TYPE_NAME = "lavatube.TickHeader.v2"
    _fields_ = [("tick", u64), ("env_steps", u64), ("policy_version", u32), ("envs", u32),
                ("episodes", u64), ("successes", u64), ("sent_ns", u64), ("reach_ticks", u64),
                ("reach_ticks_sq", u64)]


class EnvTick(Wire):
    """One env at one tick: true area, `EVENT_*` bits, acting slot, pose, sin θx, reward,
    target (x, z), the IMU filter's Euler angles and sin θx (NaN without an IMU), and the
    wheel commands (left, right) the step ran with."""

    TYPE_NAME = "lavatube.EnvTick.v4"
    _fields_ = [("env", u32), ("area", u8), ("events", u8), ("slot", u8), ("_reserved", u8),
                ("pos", f32 * 3), ("euler", f32 * 3), ("sin_pitch", f32), ("reward", f32),
                ("target", f32 * 2), ("imu_euler", f32 * 3), ("imu_sin_pitch", f32),
                ("command", f32 * 2)]


# ---- estimator → sim, monitors: `terrain` -----------------------------------------------------


class TerrainHeader(Wire):
    """Header of one terrain estimate: the tick it answers, scoring counters, refits."""

    TYPE_NAME = "lavatube.TerrainHeader.v1"
    _fields_ = [("tick", u64), ("scored", u64), ("correct", u64), ("envs", u32),
                ("refits", u32)]


class TerrainEstimate(Wire):
    """The estimator's view of one env: class (0 flat, 1 rough, or CLASS_UNKNOWN)."""

    TYPE_NAME = "lavatube.TerrainEstimate.v1"
    _fields_ = [("env", u32), ("class", u8), ("_reserved", u8 * 3), ("posterior", f32),
                ("window_std", f32), ("window", u32)]


# ---- learner host's bridge → `lavatube status`: `hosts` ---------------------------------------


class HostsHeader(Wire):
    """Header of the sim hosts a learner host hears."""

    TYPE_NAME = "lavatube.HostsHeader.v1"
    _fields_ = [("sent_ns", u64), ("hosts", u32), ("_reserved", u32)]


class SimHost(Wire):
    """One sim host as the learner host's bridge sees it."""

    TYPE_NAME = "lavatube.SimHost.v1"
    _fields_ = [("source", u32), ("joined", u32), ("chunks", u64), ("last_chunk", u64),
                ("env_steps", u64), ("lost", u64), ("steps_per_s", f32), ("bytes_per_s", f32)]


# ---- `lavatube swap-learner` → launcher: `swap` (request-response) -----------------------------


class SwapRequest(Wire):
    """Replace a slot's learner: new config and/or checkpoint paths (UTF-8, absolute)."""

    TYPE_NAME = "lavatube.SwapRequest.v1"
    _fields_ = [("config_len", u32), ("checkpoint_len", u32), ("slot", u32), ("_reserved", u32),
                ("config", u8 * SWAP_PATH_BYTES), ("checkpoint", u8 * SWAP_PATH_BYTES)]


class SwapReply(Wire):
    """The launcher's answer to a SwapRequest: `ok` 1 when the new learner runs."""

    TYPE_NAME = "lavatube.SwapReply.v1"
    _fields_ = [("ok", u32), ("len", u32), ("message", u8 * SWAP_MESSAGE_BYTES)]


# ---- gym client ↔ sim: `gym/act`, `gym/step` (`sim.acting = "external"`) --------------------

#: `GymStepHeader.command` of the sim's first message, sent before any request.
GYM_READY = 0
#: `GymActHeader.command`: step every env; start every episode over; leave.
GYM_STEP = 1
GYM_RESET = 2
GYM_CLOSE = 3
#: `GymActHeader.flags` bit: a reset rebuilds every env from `seed`.
GYM_SEEDED = 1
#: `GymStepHeader.status`: carried out, or refused (the sim's log says why).
GYM_OK = 0
GYM_REFUSED = 1


class GymActHeader(Wire):
    """A gym client's request; a step's slice holds envs × ACT_DIM wheel commands (f32)."""

    TYPE_NAME = "lavatube.GymActHeader.v1"
    _fields_ = [("request", u64), ("seed", u64), ("command", u32), ("flags", u32)]


class GymStepHeader(Wire):
    """The sim's answer to a request (or its GYM_READY): a GymEnvStep per env after a reset or
    a step."""

    TYPE_NAME = "lavatube.GymStepHeader.v1"
    _fields_ = [("request", u64), ("tick", u64), ("env_steps", u64), ("envs", u32),
                ("command", u32), ("status", u32), ("action_limit", f32)]


class GymEnvStep(Wire):
    """One env after a reset or a step, an ended episode already replaced by the next."""

    TYPE_NAME = "lavatube.GymEnvStep.v1"
    _fields_ = [("obs", f32 * OBS_DIM), ("final_obs", f32 * OBS_DIM), ("reward", f32),
                ("episode_steps", u32), ("terminated", u8), ("truncated", u8), ("success", u8),
                ("area", u8), ("env", u32)]


#: Every message type, for layout checks.
ALL = (RolloutHeader, Transition, PolicyHeader, TickHeader, EnvTick, TerrainHeader,
       TerrainEstimate, HostsHeader, SimHost, SwapRequest, SwapReply, GymActHeader,
       GymStepHeader, GymEnvStep)
