"""Print sin(pitch) per env from a running lavatube run's telemetry, over shared memory.

    pip install iceoryx2==0.10.0
    python examples/python/read_telemetry.py RUN_ID   # the id `lavatube run` prints
"""

import ctypes
import sys

import iceoryx2 as iox2


class TickHeader(ctypes.Structure):
    """common::wire::TickHeader (repr(C)); the type name must match the Rust one."""

    _fields_ = [("tick", ctypes.c_uint64), ("env_steps", ctypes.c_uint64),
                ("policy_version", ctypes.c_uint32), ("envs", ctypes.c_uint32),
                ("episodes", ctypes.c_uint64), ("successes", ctypes.c_uint64),
                ("sent_ns", ctypes.c_uint64),  # CLOCK_MONOTONIC (time.monotonic_ns()) at send
                # Sums over successful episodes of their length in ticks, and of its square.
                ("reach_ticks", ctypes.c_uint64), ("reach_ticks_sq", ctypes.c_uint64)]

    @staticmethod
    def type_name() -> str:
        return "lavatube.TickHeader.v2"


class EnvTick(ctypes.Structure):
    """common::wire::EnvTick (repr(C))."""

    _fields_ = [("env", ctypes.c_uint32), ("area", ctypes.c_uint8), ("events", ctypes.c_uint8),
                ("slot", ctypes.c_uint8), ("_reserved", ctypes.c_uint8),
                ("pos", ctypes.c_float * 3), ("euler", ctypes.c_float * 3),
                ("sin_pitch", ctypes.c_float), ("reward", ctypes.c_float)]

    @staticmethod
    def type_name() -> str:
        return "lavatube.EnvTick.v1"


run = sys.argv[1]
config = iox2.config.default()
config.global_cfg.prefix = iox2.FileName.new(f"lavatube_{run}_")  # every run has its own prefix
node = iox2.NodeBuilder.new().config(config).create(iox2.ServiceType.Ipc)
service = (node.service_builder(iox2.ServiceName.new(f"lavatube/{run}/telemetry"))
           .publish_subscribe(iox2.Slice[EnvTick]).user_header(TickHeader).open())
subscriber = service.subscriber_builder().create()
try:
    while True:
        node.wait(iox2.Duration.from_millis(100))
        while (sample := subscriber.receive()) is not None:
            header = sample.user_header().contents
            # 0.10.0's Slice.len() counts bytes, so use the header's env count.
            ticks = [sample.payload()[i] for i in range(header.envs)]
            print(header.tick, " ".join(f"{t.sin_pitch:+.4f}" for t in ticks), flush=True)
except iox2.NodeWaitFailure:
    pass  # Ctrl-C
