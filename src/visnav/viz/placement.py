"""Placing stamped data in the fixed frame through TF, the way RViz does.

RViz shows every display in one *fixed frame*: a message stamped ``t`` in frame
``F`` is drawn at ``T_fixed_F(t)``, looked up when the message arrives (and kept
there). When the transform is not known yet, RViz's ``tf2_ros::MessageFilter`` holds
the message in a small queue and retries each time TF data arrive; a message that
falls off the queue, or whose stamp is older than the TF data held, is dropped with
a status text ("No transform from [F] to [fixed]").

:class:`FramePlacer` does the same for the viewer, with the callbacks that log the
data as the queued items: :meth:`FramePlacer.place` runs the callback with
``T_fixed_F`` now or later, or drops it and records why.

Differences from RViz (deliberate):

* With no fixed frame given, the fixed frame is the root of the TF tree of the first
  frame placed (RViz starts on ``map`` and complains when it is missing); with no TF
  at all the first data frame is the fixed frame, so a lone cloud still shows.
* A message stamped 0 is placed with the latest transform (as RViz does for markers).
* An empty ``frame_id`` is placed in the fixed frame (RViz refuses it); the drop
  statistics record it so the caller can warn.
"""

from __future__ import annotations

import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.types import TFMessage
from visnav.tf.buffer import Buffer
from visnav.tf.errors import (
    ConnectivityException,
    ExtrapolationException,
    InvalidArgumentException,
    LookupException,
)
from visnav.viz.errors import VizError

__all__ = ["FramePlacer", "PlaceCallback"]

PlaceCallback = Callable[[NDArray[np.float64]], None]
"""Called with ``T_fixed_frame`` (4x4 float64) when the data can be placed."""

_MAX_TREE_DEPTH = 1000


@dataclass
class _Pending:
    frame: str
    stamp_ns: int
    apply: PlaceCallback
    since: float


class FramePlacer:
    """Looks up ``T_fixed_frame`` at message stamps, queueing data until TF can answer.

    Args:
        fixed_frame: the frame everything is shown in; None picks the root of the TF
            tree of the first frame placed (see the module notes).
        buffer: the TF buffer to use (default: a new one holding ``cache_time_s``).
        queue_size: messages held per key (topic) while waiting for TF (RViz: 10).
        max_wait_s: wall-clock seconds a message may wait (see :meth:`expire`).
        cache_time_s: history of the buffer created when ``buffer`` is None.
        clock: monotonic clock in seconds (injectable for tests).
    """

    def __init__(
        self,
        fixed_frame: str | None = None,
        *,
        buffer: Buffer | None = None,
        queue_size: int = 10,
        max_wait_s: float = 1.0,
        cache_time_s: float = 30.0,
        clock: Callable[[], float] = time.monotonic,
        auto_root: bool = True,
    ) -> None:
        self._auto_root = auto_root
        if fixed_frame is not None and (not fixed_frame or fixed_frame.startswith("/")):
            text = (
                f"fixed frame {fixed_frame!r} is not a TF frame id: give a name without a "
                "leading '/', e.g. 'map' or 'odom'"
            )
            raise VizError(text)
        if queue_size < 1:
            text = f"queue_size is {queue_size}: expected at least 1"
            raise VizError(text)
        self.buffer = buffer if buffer is not None else Buffer(cache_time=cache_time_s)
        self._fixed = fixed_frame
        self._queue_size = queue_size
        self._max_wait_s = max_wait_s
        self._clock = clock
        self._pending: OrderedDict[str, deque[_Pending]] = OrderedDict()
        self.placed = 0
        """Items placed so far."""
        self.dropped: dict[str, int] = {}
        """Items dropped, per key."""
        self.drop_reasons: dict[str, str] = {}
        """The latest reason an item of each key was dropped."""

    # ------------------------------------------------------------------ state

    @property
    def fixed_frame(self) -> str | None:
        """The fixed frame (None until it is chosen automatically)."""
        return self._fixed

    @property
    def pending(self) -> int:
        """Items waiting for TF."""
        return sum(len(q) for q in self._pending.values())

    # ------------------------------------------------------------------ TF input

    def add_transforms(self, msg: TFMessage, *, static: bool, authority: str = "viewer") -> int:
        """Insert a ``/tf`` (or, with ``static``, ``/tf_static``) message; retry queued data.

        Returns:
            The number of transforms the buffer accepted.
        """
        insert = self.buffer.set_transform_static if static else self.buffer.set_transform
        accepted = sum(1 for t in msg.transforms if insert(t, authority))
        if accepted and self._pending:
            self._retry()
        return accepted

    # ------------------------------------------------------------------ lookups

    def root_of(self, frame: str) -> str:
        """The root of ``frame``'s tree by the newest parents (``frame`` if unknown)."""
        seen = {frame}
        for _ in range(_MAX_TREE_DEPTH):
            parent = self.buffer.get_parent(frame)
            if parent is None or parent in seen:
                break
            seen.add(parent)
            frame = parent
        return frame

    def lookup(self, frame: str, stamp_ns: int) -> NDArray[np.float64] | None:
        """``T_fixed_frame`` at ``stamp_ns`` (0: latest), or None if TF cannot tell now."""
        matrix, _, _ = self._attempt(frame, stamp_ns)
        return matrix

    def choose_fixed(self, frame: str) -> str:
        """Make the root of ``frame``'s tree the fixed frame if none is chosen; return it."""
        if self._fixed is None:
            self._fixed = self.root_of(frame.lstrip("/"))
        return self._fixed

    def _resolve_fixed(self, frame: str) -> str | None:
        if self._fixed is None and self._auto_root and self.buffer.has_frame(frame):
            self._fixed = self.root_of(frame)
        return self._fixed

    def _attempt(self, frame: str, stamp_ns: int) -> tuple[NDArray[np.float64] | None, bool, str]:
        """Return (matrix, keep_waiting, reason)."""
        fixed = self._resolve_fixed(frame) if frame else self._fixed
        if not frame:
            return np.eye(4), False, "empty frame_id: placed in the fixed frame"
        if fixed is None:
            return None, True, f"no TF data for frame [{frame}] yet (fixed frame not chosen)"
        if frame == fixed:
            return np.eye(4), False, ""
        try:
            matrix = self.buffer.lookup_transform_matrix(fixed, frame, stamp_ns)
        except ExtrapolationException as exc:
            waiting = exc.direction == "future" or (
                exc.direction == "single" and stamp_ns > exc.latest_ns
            )
            return None, waiting, f"no transform from [{frame}] to [{fixed}]: {exc}"
        except (LookupException, ConnectivityException) as exc:
            return None, True, f"no transform from [{frame}] to [{fixed}]: {exc}"
        except InvalidArgumentException as exc:
            return None, False, f"frame [{frame}] cannot be looked up: {exc}"
        return matrix, False, ""

    # ------------------------------------------------------------------ placement

    def place(self, key: str, frame: str, stamp_ns: int, apply: PlaceCallback) -> bool:
        """Run ``apply(T_fixed_frame)`` now if TF can tell, else queue it under ``key``.

        Args:
            key: the queue (one per topic, as one MessageFilter per display).
            frame: the data's ``header.frame_id``.
            stamp_ns: the data's stamp (0: use the latest transform).
            apply: the callback that logs the data.

        Returns:
            True if placed now; False if queued or dropped (see :attr:`dropped`).
        """
        frame = frame.lstrip("/")
        matrix, waiting, reason = self._attempt(frame, stamp_ns)
        if matrix is not None:
            if reason:
                self._note(key, reason, count=False)
            self.placed += 1
            apply(matrix)
            return True
        if not waiting:
            self._drop(key, reason)
            return False
        queue = self._pending.setdefault(key, deque())
        queue.append(_Pending(frame, stamp_ns, apply, self._clock()))
        if len(queue) > self._queue_size:
            old = queue.popleft()
            if self._fixed is None:
                # No TF for this data at all: its own frame becomes the fixed frame.
                self._fixed = self.root_of(old.frame)
                queue.appendleft(old)
                self._retry()
            else:
                self._drop(key, f"queue full while waiting for TF: {reason}")
        return False

    def expire(self, *, force: bool = False) -> None:
        """Give up on items that waited longer than ``max_wait_s`` (all with ``force``).

        An item that gives up while no fixed frame is chosen makes its own frame's
        root the fixed frame and is placed; otherwise it is dropped with the reason.
        """
        now = self._clock()
        self._retry()
        for key, queue in list(self._pending.items()):
            while queue and (force or now - queue[0].since >= self._max_wait_s):
                item = queue.popleft()
                if self._fixed is None:
                    self._fixed = self.root_of(item.frame)
                matrix, _, reason = self._attempt(item.frame, item.stamp_ns)
                if matrix is None:
                    self._drop(key, reason)
                else:
                    self.placed += 1
                    item.apply(matrix)
            if not queue:
                del self._pending[key]

    def _retry(self) -> None:
        for key, queue in list(self._pending.items()):
            kept: deque[_Pending] = deque()
            while queue:
                item = queue.popleft()
                matrix, waiting, reason = self._attempt(item.frame, item.stamp_ns)
                if matrix is not None:
                    self.placed += 1
                    item.apply(matrix)
                elif waiting:
                    kept.append(item)
                else:
                    self._drop(key, reason)
            if kept:
                self._pending[key] = kept
            else:
                del self._pending[key]

    def _drop(self, key: str, reason: str) -> None:
        self._note(key, reason, count=True)

    def _note(self, key: str, reason: str, *, count: bool) -> None:
        if count:
            self.dropped[key] = self.dropped.get(key, 0) + 1
        self.drop_reasons[key] = reason
