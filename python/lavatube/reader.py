"""Reading a live run: telemetry ticks, terrain estimates and policy headers as numpy data.

A sample's header and slice are each copied out of shared memory in one piece and viewed
through a numpy structured dtype built from their ctypes type: no Python code runs per env.
"""

import ctypes
import functools
import keyword
from collections import namedtuple
from collections.abc import Iterator

import numpy as np

from . import wire
from .ipc import subscribe

#: Policy slots, each with its learner's `policy/<slot>` service.
SLOTS = ("general", "flat", "rough", "slope", "gravel", "sand")


@functools.cache
def _layout(ctype: type) -> tuple[np.dtype, list[str]]:
    """The numpy dtype of a ctypes struct, and its public (not `_reserved`) field names."""
    return np.dtype(ctype), [name for name, _ in ctype._fields_ if not name.startswith("_")]


def _record(name: str, *ctypes_: type, doc: str) -> type:
    """A namedtuple of the public fields of `ctypes_`; a Python keyword gets a trailing `_`."""
    fields = [f"{f}_" if keyword.iskeyword(f) else f for t in ctypes_ for f in _layout(t)[1]]
    record = namedtuple(name, fields)
    record.__doc__ = doc
    return record


Tick = _record("Tick", wire.TickHeader, wire.EnvTick, doc="""One telemetry tick.

TickHeader's fields (tick, env_steps, policy_version, envs, episodes, successes, sent_ns,
reach_ticks, reach_ticks_sq), then an array per EnvTick field with one row per env: env,
area (the ground's code, from the terrain-kinds table of docs/CONFIG.md), events (EVENT_* bits), slot, pos (n, 3), euler (n, 3),
sin_pitch, reward, target (n, 2), imu_euler (n, 3), imu_sin_pitch (NaN when the sim runs no IMU) and
command (n, 2), the wheel commands in rad/s.""")

Terrain = _record("Terrain", wire.TerrainHeader, wire.TerrainEstimate, doc="""One terrain
estimate.

TerrainHeader's fields (tick, scored, correct, envs, refits), then an array per
TerrainEstimate field with one row per env: env, class_ (0 flat, 1 rough, or CLASS_UNKNOWN),
posterior, window_std, window.""")

Policy = _record("Policy", wire.PolicyHeader, doc="""One published policy's header.

version, slot, obs_dim, act_dim, n_hidden, hidden (an array whose first n_hidden entries are
the layer widths), obs_clip, updates, env_steps, chunks_seen, learner (its pid),
write_failures.""")


def _header(sample, ctype: type) -> tuple:
    """The public fields of the sample's header, copied out of shared memory."""
    dtype, names = _layout(ctype)
    raw = ctypes.string_at(sample.user_header_ptr, dtype.itemsize)
    return np.frombuffer(raw, dtype)[names][0].item()


def _columns(sample, ctype: type) -> list[np.ndarray]:
    """One array per public field of the sample's slice of `ctype`, copied out of shared
    memory."""
    dtype, names = _layout(ctype)
    size = sample.header.number_of_elements * dtype.itemsize
    table = np.frombuffer((ctypes.c_byte * size).from_address(sample.payload_ptr), dtype).copy()
    return [table[name] for name in names]


def telemetry(run_id: str, timeout: float = 5.0) -> Iterator[Tick]:
    """Yield each telemetry tick of run `run_id` as a `Tick`, until the run ends.

    A reader more than 64 ticks behind loses the oldest, so `tick` may jump. Raises
    `TimeoutError` when the run's sim has not appeared within `timeout` seconds. The run ends
    when its launcher stops it, or `timeout` seconds after its sim is gone.
    """
    return subscribe(run_id, "telemetry", wire.EnvTick, wire.TickHeader, timeout,
                     lambda s: Tick(*_header(s, wire.TickHeader), *_columns(s, wire.EnvTick)))


def terrain(run_id: str, timeout: float = 5.0) -> Iterator[Terrain]:
    """Yield the terrain estimates of run `run_id` as `Terrain`s, until the run ends: the
    newest on connecting, then each one the estimator publishes. Timeouts as `telemetry`."""
    return subscribe(run_id, "terrain", wire.TerrainEstimate, wire.TerrainHeader, timeout,
                     lambda s: Terrain(*_header(s, wire.TerrainHeader),
                                       *_columns(s, wire.TerrainEstimate)))


def policy_headers(run_id: str, slot: str = "general", timeout: float = 5.0) -> Iterator[Policy]:
    """Yield the header of each policy that run `run_id`'s `slot` learner publishes, as a
    `Policy` (the newest on connecting, then each new one; the weights are not read), until
    the run ends. Timeouts as `telemetry`."""
    if slot not in SLOTS:
        raise ValueError(f"policy slot {slot!r} is none of {', '.join(SLOTS)}")
    return subscribe(run_id, f"policy/{slot}", ctypes.c_float, wire.PolicyHeader, timeout,
                     lambda s: Policy(*_header(s, wire.PolicyHeader)))
