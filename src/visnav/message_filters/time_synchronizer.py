"""``TimeSynchronizer`` (exact stamps) and ROS 1 Python's ``ApproximateTimeSynchronizer``.

Both follow the ``message_filters`` Python module of ROS 1 Noetic (also what
ROS 2's Python ``message_filters`` does): per input a dict ``stamp -> message``
of at most ``queue_size`` entries (the oldest stamp is evicted first).

``TimeSynchronizer`` emits, after each message, every stamp present in all
inputs, oldest first. ``ApproximateTimeSynchronizer`` looks, after each message,
for one set that contains the new message and one queued message per other
input, all within ``slop`` of the new one and spanning strictly less than
``slop``; it tries the other inputs' stamps nearest to the new one first and
emits the first set found (see :mod:`visnav.message_filters` for how this
differs from :class:`~visnav.message_filters.ApproximateTime`).

Time jumps. rospy's ``ApproximateTimeSynchronizer`` reads ROS time on every
message and, when it went backwards ("Detected jump back in time. Clearing
buffer."), empties every queue, the message just added included; old sets can
then not pair with the replayed ones (``bag play --loop``, a simulator reset).
visnav's does the same with ``clock`` (by default the input Subscribers' node
clock, which follows ``/clock`` under ``use_sim_time``). visnav's
``TimeSynchronizer`` applies the rule too (rospy's only with ``reset=True`` under
sim time, per queue) but keeps the message that revealed the jump.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Sequence
from functools import reduce
from typing import Any

from visnav.message_filters._common import (
    BackJumpDetector,
    FilterLike,
    LoggerLike,
    check_queue_size,
    default_logger,
    input_names,
    message_stamp_ns,
    resolve_clock,
    rospy_duration_ns,
)
from visnav.message_filters.errors import MessageFilterError
from visnav.message_filters.simple_filter import SimpleFilter

__all__ = ["ApproximateTimeSynchronizer", "TimeSynchronizer"]


class TimeSynchronizer(SimpleFilter):
    """Emits one message per input when all inputs have a message with the same stamp.

    The callback signature is ``cb(msg_0, ..., msg_n-1, *extra_args)``, one message
    per input in the order of ``fs``.

    Args:
        fs: the input filters (``Subscriber``, ``Cache``, any ``SimpleFilter``).
        queue_size: how many distinct stamps to keep per input while waiting for
            the other inputs (the oldest stamp is dropped first).
        clock: int nanoseconds ROS time; when it goes backwards every queue is
            emptied (see the module docs). Default: the clock of the inputs' node
            (a :class:`~visnav.message_filters.Subscriber`'s), else wall-clock time.
        logger: where warnings go (default the ``visnav.message_filters`` logger).

    Messages without ``header.stamp`` are dropped with a warning. A stamp older
    than the previous one on the same input is logged (once per input) and kept,
    as ROS does: exact matching does not depend on arrival order.

    Raises:
        MessageFilterError: no inputs, or ``queue_size`` not an int >= 1.
    """

    def __init__(
        self,
        fs: Sequence[FilterLike],
        queue_size: int,
        *,
        clock: Callable[[], int] | None = None,
        logger: LoggerLike | None = None,
    ) -> None:
        super().__init__()
        fs = list(fs)
        self.queue_size = check_queue_size(queue_size)
        self._clock = resolve_clock(clock, fs)
        self._jump = BackJumpDetector(self._clock)
        self._logger: LoggerLike = logger if logger is not None else default_logger()
        self._lock = threading.Lock()
        self.queues: list[dict[int, Any]] = []
        self._names: list[str] = []
        self._last: list[int | None] = []
        self._warned_order: list[bool] = []
        self.input_connections: list[int] = []
        self.connect_input(fs)

    def connect_input(self, fs: Sequence[FilterLike]) -> None:
        """Take input from the filters ``fs`` (one queue per filter, in order).

        Raises:
            MessageFilterError: ``fs`` is empty.
        """
        fs = list(fs)
        if not fs:
            text = "fs is empty: a synchronizer needs at least one input filter"
            raise MessageFilterError(text)
        self.queues = [{} for _ in fs]
        self._names = input_names(fs)
        self._last = [None] * len(fs)
        self._warned_order = [False] * len(fs)
        self.input_connections = [f.register_callback(self._on_input, i) for i, f in enumerate(fs)]

    def add(self, index: int, msg: Any) -> None:
        """Feed ``msg`` as input number ``index`` (what the input filters call).

        Raises:
            MessageFilterError: ``index`` is not an input number.
        """
        if isinstance(index, bool) or not isinstance(index, int):
            index = -1
        if not 0 <= index < len(self.queues):
            text = f"index is {index!r}: expected an input number in [0, {len(self.queues)})"
            raise MessageFilterError(text)
        self._on_input(msg, index)

    def _stamp(self, msg: Any, index: int) -> int | None:
        stamp = message_stamp_ns(msg)
        if stamp is None:
            self._logger.warning(
                f"{type(self).__name__}: {self._names[index]} received a "
                f"{type(msg).__name__} without header.stamp; dropped (message filters need "
                "stamped messages)"
            )
        return stamp

    def _note_order(self, index: int, stamp: int) -> None:
        """Warn (once per input) when a stamp goes backwards; the message is still used."""
        last = self._last[index]
        if last is not None and stamp < last and not self._warned_order[index]:
            self._warned_order[index] = True
            self._logger.warning(
                f"{type(self).__name__}: {self._names[index]} stamp went backwards "
                f"({last} ns -> {stamp} ns); the message is kept, as in ROS (logged once "
                "per input)"
            )
        if last is None or stamp > last:
            self._last[index] = stamp

    def _clear_on_jump(self) -> bool:
        """Empty every queue if ROS time went backwards since the last message."""
        back = self._jump.jumped_back()
        if not back:
            return False
        self._logger.info(
            f"{type(self).__name__}: Detected jump back in time of {back / 1e9:.3f} s. "
            "Clearing buffer."
        )
        for q in self.queues:
            q.clear()
        self._last = [None] * len(self.queues)
        return True

    def _on_input(self, msg: Any, index: int) -> None:
        stamp = self._stamp(msg, index)
        if stamp is None:
            return
        out: list[tuple[Any, ...]] = []
        with self._lock:
            self._clear_on_jump()
            self._note_order(index, stamp)
            queues = self.queues
            my_queue = queues[index]
            my_queue[stamp] = msg
            while len(my_queue) > self.queue_size:
                del my_queue[min(my_queue)]
            common: set[int] = reduce(set.intersection, [set(q) for q in queues])
            for t in sorted(common):
                out.append(tuple(q[t] for q in queues))
                for q in queues:
                    del q[t]
        for msgs in out:
            self.signal_message(*msgs)


class ApproximateTimeSynchronizer(TimeSynchronizer):
    """ROS 1 Python's approximate synchronizer: sets spanning less than ``slop`` seconds.

    Emits exactly the tuples ``message_filters.ApproximateTimeSynchronizer`` of
    ROS 1 Noetic emits for the same inputs in the same arrival order. On each new
    message (stamp ``t``) it considers, for every other input, the queued stamps
    ``s`` with ``|s - t| <= slop`` sorted by ``|s - t|`` (ties in queue order); if an
    input has none, nothing happens. It walks the combinations in
    ``itertools.product`` order and emits the first whose span (max - min, the new
    stamp included) is strictly less than ``slop``, removing its messages from the
    queues. At most one set is emitted per message.

    Args:
        fs: the input filters.
        queue_size: how many distinct stamps to keep per input (oldest dropped first).
        slop: the largest allowed span in seconds, converted to nanoseconds the
            way ``rospy.Duration.from_sec`` does (truncating).
        allow_headerless: stamp messages without ``header.stamp`` with ``clock()``
            on arrival instead of dropping them (arrival delays make this fragile).
        clock: int nanoseconds ROS time (rospy's ``Time.now()``): stamps headerless
            messages, and when it goes backwards every queue is emptied, the new
            message included, as rospy does. Default: the clock of the inputs' node
            (a :class:`~visnav.message_filters.Subscriber`'s), else wall-clock time.
        logger: where warnings go (default the ``visnav.message_filters`` logger).

    Raises:
        MessageFilterError: no inputs, ``queue_size`` not an int >= 1 or ``slop``
            negative or not finite.
    """

    def __init__(
        self,
        fs: Sequence[FilterLike],
        queue_size: int,
        slop: float,
        allow_headerless: bool = False,
        *,
        clock: Callable[[], int] | None = None,
        logger: LoggerLike | None = None,
    ) -> None:
        self.slop = rospy_duration_ns(slop, "slop")
        self.allow_headerless = allow_headerless
        super().__init__(fs, queue_size, clock=clock, logger=logger)

    def _stamp(self, msg: Any, index: int) -> int | None:
        stamp = message_stamp_ns(msg)
        if stamp is not None:
            return stamp
        if self.allow_headerless:
            return int(self._clock())
        self._logger.warning(
            f"ApproximateTimeSynchronizer: {self._names[index]} received a "
            f"{type(msg).__name__} without header.stamp; dropped. Pass allow_headerless=True "
            "to stamp headerless messages with the current time"
        )
        return None

    def _on_input(self, msg: Any, index: int) -> None:
        stamp = self._stamp(msg, index)
        if stamp is None:
            return
        found: tuple[Any, ...] | None = None
        with self._lock:
            if self._clear_on_jump():
                return  # rospy adds the message, then clears every queue: it is lost too
            self._note_order(index, stamp)
            found = self._match(index, stamp, msg)
        if found is not None:
            self.signal_message(*found)

    def _match(self, index: int, stamp: int, msg: Any) -> tuple[Any, ...] | None:
        slop = self.slop
        queues = self.queues
        my_queue = queues[index]
        my_queue[stamp] = msg
        while len(my_queue) > self.queue_size:
            del my_queue[min(my_queue)]
        choices: list[list[int]] = []
        for j, queue in enumerate(queues):
            if j == index:
                continue
            near = [(s, abs(s - stamp)) for s in queue if abs(s - stamp) <= slop]
            if not near:
                return None
            near.sort(key=lambda item: item[1])
            choices.append([s for s, _ in near])
        for combo in itertools.product(*choices):
            stamps = list(combo)
            stamps.insert(index, stamp)
            if max(stamps) - min(stamps) < slop and all(
                t in q for q, t in zip(queues, stamps, strict=True)
            ):
                msgs = tuple(q[t] for q, t in zip(queues, stamps, strict=True))
                for q, t in zip(queues, stamps, strict=True):
                    del q[t]
                return msgs
        return None
