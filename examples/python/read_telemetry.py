"""Print sin(pitch) per env from a running lavatube run's telemetry, over shared memory.

    pip install ./python
    python examples/python/read_telemetry.py RUN_ID   # the id `lavatube run` prints
"""

import sys

import lavatube

try:
    for tick in lavatube.telemetry(sys.argv[1]):
        print(tick.tick, " ".join(f"{s:+.4f}" for s in tick.sin_pitch), flush=True)
except KeyboardInterrupt:
    pass
