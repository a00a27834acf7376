"""The executor's fault boundary: a callback that raises is logged and its node keeps running.

rospy's behaviour: an exception in a subscription or timer callback is logged and
the node goes on with its next message. visnav does the same, with two additions:

* The log is rate limited per callback: the first error of a callback is logged at
  once (with its traceback unless it is a visnav error, whose message says it
  all); further errors of the same callback within ``interval_s`` (5 s) are
  counted and the count is reported with the next logged one.
* A node may ask for its errors to be raised instead (``policy="raise"``): the
  error is logged as above, then :class:`CallbackError` leaves
  :meth:`~visnav.graph.Context.spin_once`. ``visnav launch`` uses this for
  ``on_error: restart`` and ``on_error: shutdown``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from visnav.errors import VisnavError
from visnav.graph.errors import GraphError

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = ["ERROR_POLICIES", "CallbackError", "FaultBoundary", "FaultRecord"]

ERROR_POLICIES = ("log", "raise")
"""What the executor does after logging a callback's exception."""


class CallbackError(GraphError):
    """A callback raised and its node's error policy is ``"raise"``.

    Attributes:
        node_name: the fully qualified name of the node whose callback raised.
        what: the callback, e.g. ``subscription on '/a' (std_msgs/msg/String)``.
    """

    def __init__(self, message: str, *, node_name: str, what: str) -> None:
        super().__init__(message)
        self.node_name = node_name
        self.what = what


@dataclass
class FaultRecord:
    """The errors of one callback.

    Attributes:
        node_name: the node's fully qualified name.
        what: the callback.
        count: errors so far.
        suppressed: errors not logged since the last logged one.
        last_logged: the monotonic time of the last logged one.
        last_error: the last error's ``Type: message``.
    """

    node_name: str
    what: str
    count: int = 0
    suppressed: int = 0
    last_logged: float = float("-inf")
    last_error: str = ""


class FaultBoundary:
    """Logs (rate limited) and counts exceptions of callbacks; one per :class:`Context`.

    Args:
        interval_s: at most one log line per callback per this many seconds.
        clock: monotonic time source in seconds (for tests).
    """

    def __init__(
        self, *, interval_s: float = 5.0, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.interval_s = interval_s
        self._clock = clock
        self._records: dict[int, FaultRecord] = {}
        self._policies: dict[str, str] = {}

    def set_policy(self, node_name: str, policy: str) -> None:
        """Set what happens after a callback of ``node_name`` (fully qualified) raised.

        Raises:
            GraphError: ``policy`` is not ``"log"`` or ``"raise"``.
        """
        if policy not in ERROR_POLICIES:
            msg = f"error policy of {node_name} is {policy!r}: expected 'log' or 'raise'"
            raise GraphError(msg)
        self._policies[node_name] = policy

    def policy(self, node_name: str) -> str:
        """The error policy of a node (``"log"`` unless set)."""
        return self._policies.get(node_name, "log")

    @property
    def records(self) -> list[FaultRecord]:
        """Every callback that raised so far."""
        return list(self._records.values())

    def count(self, node_name: str | None = None) -> int:
        """Errors so far, of one node (fully qualified name) or of all."""
        return sum(r.count for r in self._records.values() if node_name in (None, r.node_name))

    def report(self, node: Node, entity_id: int, what: str, exc: Exception) -> None:
        """Log ``exc`` raised by a callback (rate limited); raise if the node's policy says so.

        Raises:
            CallbackError: the node's policy is ``"raise"`` (chained to ``exc``).
        """
        name = node.get_fully_qualified_name()
        record = self._records.get(entity_id)
        if record is None:
            record = self._records[entity_id] = FaultRecord(name, what)
        record.count += 1
        record.last_error = f"{type(exc).__name__}: {exc}"
        fatal = self.policy(name) == "raise"
        now = self._clock()
        if fatal or now - record.last_logged >= self.interval_s:
            more = ""
            if record.suppressed:
                more = (
                    f" ({record.suppressed} more error(s) of this callback in the last "
                    f"{now - record.last_logged:.0f} s were not logged)"
                )
            outcome = "the node keeps running"
            if fatal:
                outcome = "stopping the node (its on_error policy)"
            text = f"{what} raised {record.last_error}; {outcome}{more}"
            trace = None if isinstance(exc, VisnavError) else exc
            node.get_logger().error(text, exc_info=trace)
            record.last_logged = now
            record.suppressed = 0
        else:
            record.suppressed += 1
        if fatal:
            msg = f"node {name}: {what} raised {record.last_error}"
            raise CallbackError(msg, node_name=name, what=what) from exc
