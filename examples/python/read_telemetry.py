"""Print sin(pitch) per env from a running lavatube run's telemetry, over shared memory: the
simulator's true value and, when the run simulates an IMU (`sim.observation = "imu"`,
`estimator.signal = "imu"` or `sim.imu.simulate = true`), the IMU filter's beside it.

    pip install ./python
    python examples/python/read_telemetry.py RUN_ID   # the id `lavatube run` prints
"""

import math
import sys

import lavatube


def column(true: float, imu: float) -> str:
    """One env's sin(pitch), true then filtered (the filtered one only with an IMU)."""
    return f"{true:+.4f}" if math.isnan(imu) else f"{true:+.4f}/{imu:+.4f}"


try:
    for tick in lavatube.telemetry(sys.argv[1]):
        pairs = zip(tick.sin_pitch, tick.imu_sin_pitch)
        print(tick.tick, " ".join(column(t, i) for t, i in pairs), flush=True)
except KeyboardInterrupt:
    pass
