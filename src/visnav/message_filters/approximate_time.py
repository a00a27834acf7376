"""``ApproximateTime``: roscpp's ApproximateTime synchronization policy.

The policy (``message_filters/sync_policies/approximate_time.h``, described on
the ROS wiki page "message_filters/ApproximateTime") finds, without a tolerance
parameter, the best match among the queued messages:

* each message is used at most once; some are dropped;
* sets do not cross: for two output sets S before T, ``S_i <= T_i`` on every input;
* sets are contiguous: between two consecutive sets at least one input has no
  dropped message;
* each set has the smallest span (latest minus earliest stamp) among the sets
  contiguous to the previous one, later sets being penalised by a factor
  ``1 + age_penalty`` so that a set can be output before all candidates are seen;
* the output depends only on the stamps, not on the arrival interleaving across
  inputs (messages should arrive in stamp order on each input; one that does not
  is kept with a warning, as roscpp does).

How it works: once every input has a message, the latest of the queue heads is
the *pivot*; the heads form the first *candidate*. The earliest head is then
repeatedly moved out of the way and the new heads compared with the candidate
(the better one is kept). When the pivot itself is the earliest head, no later
set can contain it, and the candidate is published. It is published earlier
when no future set can beat it: any future candidate spans at least
``[pivot time, latest head]``. With ``inter_message_lower_bounds`` the policy
also reasons about messages not yet received (an input with period >= b cannot
produce its next message before ``last + b``), which proves optimality sooner
and lowers latency without changing the output.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Sequence
from typing import Any

from visnav.message_filters._common import (
    FilterLike,
    LoggerLike,
    check_queue_size,
    default_logger,
    input_names,
    message_stamp_ns,
    seconds_to_ns,
)
from visnav.message_filters.errors import MessageFilterError
from visnav.message_filters.simple_filter import SimpleFilter

__all__ = ["ApproximateTime"]

_NO_PIVOT = -1
_FOREVER = 2**63  # "no max_interval_duration": larger than any stamp difference
_Entry = tuple[int, Any]  # (stamp in ns, message)


class ApproximateTime(SimpleFilter):
    """roscpp's ApproximateTime policy: optimal, non-crossing sets without a slop.

    The callback signature is ``cb(msg_0, ..., msg_n-1, *extra_args)``.

    Args:
        fs: the input filters (at least two), or None to feed messages with
            :meth:`add` (then give ``num_inputs``).
        queue_size: per input, how many messages may wait (queued plus those
            set aside while searching); beyond it the oldest is dropped. At
            least 2 is recommended; roscpp's examples use 10.
        age_penalty: later candidates are compared after multiplying their
            extra span by ``1 + age_penalty`` (>= 0; roscpp's default 0.1). 0
            gives the strictly smallest sets at the cost of latency.
        max_interval_duration: seconds; a candidate spanning more is never
            formed (its earliest message is dropped instead). None: unbounded.
        inter_message_lower_bounds: seconds, one per input or one for all: the
            smallest gap between two consecutive messages of that input. Only
            lowers latency; a wrong (too large) bound can change the output.
        num_inputs: number of inputs when ``fs`` is None.
        reset: when a stamp goes backwards on an input (a bag looping, the
            simulator restarting), clear that input's queue and accept the
            message instead of dropping it (roscpp's ``setReset`` does this on
            a jump back of the receive clock under simulated time).
        logger: where warnings go (default the ``visnav.message_filters`` logger).

    Messages without ``header.stamp`` are dropped with a warning. A message whose
    stamp is older than the previous one on the same input is kept and queued
    in arrival order with a warning, as roscpp (Noetic) does (the policy assumes
    per-input stamp order, so such sets may cross); with ``reset`` the input's
    queue is cleared instead. Messages arriving closer than their input's lower
    bound are kept with a warning, as in roscpp. Warnings are logged once per
    input; later occurrences go to debug.

    Raises:
        MessageFilterError: fewer than two inputs, or a parameter out of range.
    """

    def __init__(
        self,
        fs: Sequence[FilterLike] | None,
        queue_size: int,
        age_penalty: float = 0.1,
        max_interval_duration: float | None = None,
        inter_message_lower_bounds: Sequence[float] | float | None = None,
        *,
        num_inputs: int | None = None,
        reset: bool = False,
        logger: LoggerLike | None = None,
    ) -> None:
        super().__init__()
        inputs = list(fs) if fs is not None else None
        n = len(inputs) if inputs is not None else num_inputs
        if inputs is not None and num_inputs is not None and num_inputs != n:
            text = f"num_inputs is {num_inputs!r} but fs has {n} filters: give one or the other"
            raise MessageFilterError(text)
        if isinstance(n, bool) or not isinstance(n, int) or n < 2:
            text = (
                f"ApproximateTime got {n!r} inputs: expected at least 2 (pass fs, a list of "
                "filters, or num_inputs when feeding messages with add())"
            )
            raise MessageFilterError(text)
        self._n = n
        self.queue_size = check_queue_size(queue_size)
        self.age_penalty = self._check_age_penalty(age_penalty)
        self._factor = 1.0 + self.age_penalty
        self.max_interval_duration = max_interval_duration
        self._max_interval = (
            _FOREVER
            if max_interval_duration is None
            else seconds_to_ns(max_interval_duration, "max_interval_duration")
        )
        self._bounds = self._lower_bounds_ns(inter_message_lower_bounds, n)
        self.reset = reset
        self._logger: LoggerLike = logger if logger is not None else default_logger()
        self._names = (
            input_names(inputs) if inputs is not None else [f"input {i}" for i in range(n)]
        )
        self._lock = threading.Lock()

        self._deques: list[deque[_Entry]] = [deque() for _ in range(n)]
        self._past: list[list[_Entry]] = [[] for _ in range(n)]
        self._num_non_empty = 0
        self._candidate: tuple[_Entry, ...] | None = None
        self._candidate_start = 0
        self._candidate_end = 0
        self._pivot = _NO_PIVOT
        self._pivot_time = 0
        self._has_dropped = [False] * n
        self._last: list[int | None] = [None] * n
        self._warned_order = [False] * n
        self._warned_bound = [False] * n
        self._out: list[tuple[Any, ...]] = []

        self.input_connections: list[int] = []
        if inputs is not None:
            self.input_connections = [
                f.register_callback(self._on_input, i) for i, f in enumerate(inputs)
            ]

    # ------------------------------------------------------------------ setup

    @staticmethod
    def _check_age_penalty(age_penalty: float) -> float:
        ok = isinstance(age_penalty, (int, float)) and not isinstance(age_penalty, bool)
        if ok and 0.0 <= age_penalty < float("inf"):
            return float(age_penalty)
        text = f"age_penalty is {age_penalty!r}: expected a finite number >= 0 (roscpp: 0.1)"
        raise MessageFilterError(text)

    @staticmethod
    def _lower_bounds_ns(bounds: Sequence[float] | float | None, n: int) -> list[int]:
        if bounds is None:
            return [0] * n
        if isinstance(bounds, (int, float)):
            return [seconds_to_ns(bounds, "inter_message_lower_bounds")] * n
        values = list(bounds)
        if len(values) != n:
            text = (
                f"inter_message_lower_bounds has {len(values)} values: expected one per "
                f"input ({n}) or a single number for all"
            )
            raise MessageFilterError(text)
        return [seconds_to_ns(v, f"inter_message_lower_bounds[{i}]") for i, v in enumerate(values)]

    # ------------------------------------------------------------------ input

    def add(self, index: int, msg: Any, *, stamp: int | None = None) -> None:
        """Feed ``msg`` as input number ``index``; callbacks run for every set completed.

        Args:
            index: the input number, 0 <= index < number of inputs.
            msg: the message.
            stamp: its time in nanoseconds; default ``msg.header.stamp``.

        Raises:
            MessageFilterError: ``index`` out of range or ``stamp`` not an int.
        """
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < self._n:
            text = f"index is {index!r}: expected an input number in [0, {self._n})"
            raise MessageFilterError(text)
        if stamp is not None and (isinstance(stamp, bool) or not isinstance(stamp, int)):
            text = f"stamp is {stamp!r}: expected integer nanoseconds"
            raise MessageFilterError(text)
        self._on_input(msg, index, stamp)

    def _on_input(self, msg: Any, index: int, stamp: int | None = None) -> None:
        if stamp is None:
            stamp = message_stamp_ns(msg)
            if stamp is None:
                self._logger.warning(
                    f"ApproximateTime: {self._names[index]} received a {type(msg).__name__} "
                    "without header.stamp; dropped (the policy needs stamped messages)"
                )
                return
        with self._lock:
            self._add(index, stamp, msg)
            out = self._out
            if not out:
                return
            self._out = []
        for msgs in out:
            self.signal_message(*msgs)

    def _warn(self, flags: list[bool], index: int, text: str) -> None:
        if flags[index]:
            self._logger.debug(text)
        else:
            flags[index] = True
            self._logger.warning(text + " (warned once per input; later ones at debug level)")

    def _add(self, i: int, stamp: int, msg: Any) -> None:
        last = self._last[i]
        if last is not None:
            if stamp < last:
                if self.reset:
                    self._logger.warning(
                        f"ApproximateTime: {self._names[i]} jumped back in time ({last} ns -> "
                        f"{stamp} ns); clearing its queue"
                    )
                    self._clear_input(i)
                else:
                    # roscpp (Noetic) warns once and keeps the message in the queue.
                    self._warn(
                        self._warned_order,
                        i,
                        f"ApproximateTime: {self._names[i]} stamp went backwards ({last} ns -> "
                        f"{stamp} ns); message kept, as roscpp does, but sets may cross. "
                        "Pass reset=True to restart the input's queue on a jump back instead",
                    )
            elif stamp - last < self._bounds[i]:
                self._warn(
                    self._warned_bound,
                    i,
                    f"ApproximateTime: {self._names[i]} messages arrived {stamp - last} ns apart, "
                    f"closer than its inter_message_lower_bound of {self._bounds[i]} ns",
                )
        self._last[i] = stamp
        dq = self._deques[i]
        dq.append((stamp, msg))
        if len(dq) == 1:
            self._num_non_empty += 1
            if self._num_non_empty == self._n:
                self._process()
        if len(dq) + len(self._past[i]) > self.queue_size:
            # Too many messages on this input: cancel the search, drop its oldest.
            self._recover_all()
            dq.popleft()
            self._has_dropped[i] = True
            if self._pivot != _NO_PIVOT:
                self._candidate = None
                self._pivot = _NO_PIVOT
                self._process()

    def _clear_input(self, i: int) -> None:
        self._recover_all()
        dq = self._deques[i]
        if dq:
            self._num_non_empty -= 1
        dq.clear()
        self._warned_order[i] = False
        self._warned_bound[i] = False
        self._candidate = None
        self._pivot = _NO_PIVOT

    # ------------------------------------------------------------- internals

    def _recover_all(self) -> None:
        """Put every set-aside message back at the head of its queue."""
        count = 0
        for dq, past in zip(self._deques, self._past, strict=True):
            if past:
                dq.extendleft(reversed(past))
                past.clear()
            if dq:
                count += 1
        self._num_non_empty = count

    def _delete_front(self, i: int) -> None:
        dq = self._deques[i]
        dq.popleft()
        if not dq:
            self._num_non_empty -= 1

    def _move_front_to_past(self, i: int) -> None:
        dq = self._deques[i]
        self._past[i].append(dq.popleft())
        if not dq:
            self._num_non_empty -= 1

    def _make_candidate(self) -> None:
        self._candidate = tuple(dq[0] for dq in self._deques)
        for past in self._past:
            past.clear()

    def _publish_candidate(self) -> None:
        candidate = self._candidate
        assert candidate is not None  # internal invariant
        self._out.append(tuple(entry[1] for entry in candidate))
        self._candidate = None
        self._pivot = _NO_PIVOT
        count = 0
        for dq, past in zip(self._deques, self._past, strict=True):
            if past:
                dq.extendleft(reversed(past))
                past.clear()
            dq.popleft()  # the candidate's message: the oldest left on this input
            if dq:
                count += 1
        self._num_non_empty = count

    def _scaled(self, duration: int) -> int:
        """Return ``duration * (1 + age_penalty)`` rounded to ns (roscpp's Duration * double)."""
        if self._factor == 1.0:
            return duration
        return int(duration * self._factor + 0.5)

    def _virtual_times(self) -> list[int]:
        """Queue heads, or for empty queues the earliest time the next message can have."""
        pivot_time = self._pivot_time
        times = []
        for dq, past, bound in zip(self._deques, self._past, self._bounds, strict=True):
            if dq:
                times.append(dq[0][0])
            else:
                lower = past[-1][0] + bound
                times.append(lower if lower > pivot_time else pivot_time)
        return times

    def _process(self) -> None:
        n = self._n
        deques = self._deques
        has_dropped = self._has_dropped
        while self._num_non_empty == n:
            # Start (earliest head; first on ties) and end (latest head; last on ties).
            start_time = end_time = deques[0][0][0]
            start_index = end_index = 0
            for k in range(1, n):
                t = deques[k][0][0]
                if t < start_time:
                    start_time, start_index = t, k
                if t >= end_time:
                    end_time, end_index = t, k
            for k in range(n):
                if k != end_index:
                    # No dropped message of input k could beat what we have: k may be pivot.
                    has_dropped[k] = False
            if self._pivot == _NO_PIVOT:
                if end_time - start_time > self._max_interval or has_dropped[end_index]:
                    # Too wide to be a candidate, or the would-be pivot lost messages.
                    self._delete_front(start_index)
                    continue
                self._make_candidate()
                self._candidate_start = start_time
                self._candidate_end = end_time
                self._pivot = end_index
                self._pivot_time = end_time
                self._move_front_to_past(start_index)
            else:
                grown = self._scaled(end_time - self._candidate_end)
                if grown < start_time - self._candidate_start:
                    self._make_candidate()  # better than the current candidate
                    self._candidate_start = start_time
                    self._candidate_end = end_time
                self._move_front_to_past(start_index)
            if start_index == self._pivot:
                # Every candidate containing the pivot has been seen.
                self._publish_candidate()
            elif (
                self._scaled(end_time - self._candidate_end)
                >= self._pivot_time - self._candidate_start
            ):
                # Any later candidate spans at least [pivot_time, end_time]: ours is optimal.
                self._publish_candidate()
            elif self._num_non_empty < n:
                self._virtual_search()

    def _virtual_search(self) -> None:
        """Use the inter-message lower bounds to try to prove the candidate optimal now."""
        n = self._n
        moves = [0] * n
        while True:
            times = self._virtual_times()
            start_time = end_time = times[0]
            start_index = 0
            for k in range(1, n):
                t = times[k]
                if t < start_time:
                    start_time, start_index = t, k
                end_time = max(t, end_time)
            grown = self._scaled(end_time - self._candidate_end)
            if grown >= self._pivot_time - self._candidate_start:
                self._publish_candidate()  # proved optimal; also undoes the virtual moves
                return
            if grown < start_time - self._candidate_start:
                # An optimistic future candidate could be better: undo and wait for data.
                count = 0
                for k in range(n):
                    dq, past = self._deques[k], self._past[k]
                    for _ in range(moves[k]):
                        dq.appendleft(past.pop())
                    if dq:
                        count += 1
                self._num_non_empty = count
                return
            # start_index cannot be the pivot here (then the two tests above would be
            # complementary), so its queue is non-empty and holds a real message.
            self._move_front_to_past(start_index)
            moves[start_index] += 1
