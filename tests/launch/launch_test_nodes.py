"""Tiny nodes for the launch tests (imported as ``launch_test_nodes:Class``).

The tests put this directory on ``sys.path`` and ``PYTHONPATH`` so that shared
nodes (this process) and ``own`` nodes (child processes) import it alike.
"""

from __future__ import annotations

import os
from typing import Any

from visnav.graph import Node
from visnav.msgs import String


class Talker(Node):
    """Publishes ``"<text> <pid>"`` on the relative topic ``chatter`` and ``~/status``."""

    def __init__(self, name: str = "talker", **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        text = str(self.declare_parameter("text", "hello").value)
        rate = float(self.declare_parameter("rate", 20.0).value)
        self.chatter = self.create_publisher(String, "chatter", 10)
        self.status = self.create_publisher(String, "~/status", 10)

        def tick() -> None:
            self.chatter.publish(String(data=f"{text} {os.getpid()}"))
            self.status.publish(String(data=self.get_fully_qualified_name()))

        self.create_timer(1.0 / rate, tick)


class Crasher(Node):
    """Exits the process with the ``code`` parameter as soon as it is built."""

    def __init__(self, name: str = "crasher", **kwargs: Any) -> None:
        code = int(dict(kwargs.get("parameter_overrides") or {}).get("code", 3))
        raise SystemExit(code)


class Listener(Node):
    """Subscribes ``chatter`` and keeps what it received (for in-process checks)."""

    def __init__(self, name: str = "listener", **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.received: list[str] = []
        self.create_subscription(String, "chatter", lambda m: self.received.append(m.data), 10)


class Bomb(Node):
    """Raises from a timer callback after ``delay`` seconds (a crashing shared node)."""

    def __init__(self, name: str = "bomb", **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        delay = float(self.declare_parameter("delay", 0.3).value)

        def explode() -> None:
            msg = "boom"
            raise RuntimeError(msg)

        self.create_timer(delay, explode)
