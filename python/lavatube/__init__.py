"""Read a live lavatube run from Python, out of its iceoryx2 shared memory.

    for tick in lavatube.telemetry("demo"):
        print(tick.tick, tick.sin_pitch)

`telemetry`, `terrain` and `policy_headers` follow a run by its id (the one `lavatube run`
prints); `lavatube.wire` holds the ctypes twins of the Rust message types.
"""

from . import wire
from .reader import SLOTS, Policy, Terrain, Tick, policy_headers, telemetry, terrain

__all__ = ["SLOTS", "Policy", "Terrain", "Tick", "policy_headers", "telemetry", "terrain", "wire"]
