"""A run's publish-subscribe services over iceoryx2, named as `common::ipc` names them.

Every resource of run `R` carries the file prefix `lavatube_R_`; every service is named
`lavatube/R/<service>` and paired with the event service `lavatube/R/<service>.ready` on
which its writer signals new samples. The launcher asks a run to stop on `control.ready`.
"""

import re
import time
from collections.abc import Callable, Iterator
from typing import TypeVar

import iceoryx2 as iox2

from .wire import CONTROL_SHUTDOWN

T = TypeVar("T")

#: What `common::ipc::validate_run_id` accepts.
_RUN_ID = re.compile(r"[A-Za-z0-9-]{1,32}")
#: Open errors that mean the run has not created the service (yet).
_NOT_YET = {"DoesNotExist", "HangsInCreation"}
#: The longest sleep between two looks for samples (and for Ctrl-C).
_POLL = iox2.Duration.from_millis(100)


def subscribe(run_id: str, service: str, element: type, header: type, timeout: float,
              convert: Callable[[iox2.Sample], T]) -> Iterator[T]:
    """Yield `convert(sample)` for each sample of `lavatube/<run_id>/<service>`, a slice of
    `element` under a `header`, until the run ends.

    The run ends when its launcher asks it to stop, or when the service has had no writer
    for `timeout` seconds (a launcher killed outright). The samples already received are
    still yielded, after this reader has left the run's shared memory so that the launcher
    can remove it. Raises `TimeoutError` when the service, or a writer on it, does not
    appear within `timeout` seconds, and `RuntimeError` when it carries other message types.
    """
    if not _RUN_ID.fullmatch(run_id):
        raise ValueError(f"run id {run_id!r} must be 1-32 characters of A-Z a-z 0-9 -")
    config = iox2.config.default()
    config.global_cfg.prefix = iox2.FileName.new(f"lavatube_{run_id}_")
    name = f"lavatube/{run_id}/{service}"
    start = time.monotonic()
    # Look before joining: a node would leave files behind for a run that never comes.
    while not iox2.Service.does_exist(iox2.ServiceName.new(name), config,
                                      iox2.MessagingPattern.PublishSubscribe,
                                      iox2.ServiceType.Ipc):
        if time.monotonic() > start + timeout:
            raise TimeoutError(f"run {run_id!r}: no service {name} (is the run started?)")
        time.sleep(0.05)
    node = (iox2.NodeBuilder.new().name(iox2.NodeName.new("python")).config(config)
            .signal_handling_mode(iox2.SignalHandlingMode.Disabled)  # Ctrl-C stays Python's
            .create(iox2.ServiceType.Ipc))

    def event(service_name: str):
        return node.service_builder(iox2.ServiceName.new(f"{service_name}.ready")).event().open()

    pubsub = _open(lambda: node.service_builder(iox2.ServiceName.new(name))
                   .publish_subscribe(iox2.Slice[element]).user_header(header).open(),
                   run_id, name, start + timeout)
    ready = _open(lambda: event(name), run_id, name, start + timeout)
    control = _open(lambda: event(f"lavatube/{run_id}/control"), run_id, name, start + timeout)
    subscriber = pubsub.subscriber_builder().create()
    signals = ready.listener_builder().create()
    stop = control.listener_builder().create()
    had_writer, writer_seen = False, start
    while True:
        signals.timed_wait(_POLL)
        stopping = any(e.id.as_value == CONTROL_SHUTDOWN for e in stop.try_wait())
        batch = [convert(sample) for sample in iter(subscriber.receive, None)]
        if pubsub.dynamic_config.number_of_publishers > 0:
            had_writer, writer_seen = True, time.monotonic()
        elif time.monotonic() - writer_seen > timeout:
            if not had_writer:
                raise TimeoutError(f"run {run_id!r}: nothing writes {name} (is the run started?)")
            stopping = True
        if stopping:
            break
        yield from batch
    # Leave the run first: the launcher removes its shared memory only once no node is left.
    del subscriber, signals, stop, pubsub, ready, control, node
    yield from batch


def _open(builder: Callable[[], T], run_id: str, name: str, deadline: float) -> T:
    """The service `builder()` opens, retried until `deadline` while the run lacks it."""
    while True:
        try:
            return builder()
        except (iox2.PublishSubscribeOpenError, iox2.EventOpenError) as e:
            reason = str(e)
        if reason == "IncompatibleTypes":
            raise RuntimeError(f"{name}: the run's processes use other message types than this "
                               "lavatube package; install the package from the run's checkout")
        if reason not in _NOT_YET:
            raise RuntimeError(f"{name}: cannot open it ({reason})")
        if time.monotonic() > deadline:
            raise TimeoutError(f"run {run_id!r}: no service {name} (is the run started?)")
        time.sleep(0.05)
