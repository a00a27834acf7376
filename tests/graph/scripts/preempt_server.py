"""An action server process whose newer goal preempts the running one (as move_base does).

Node ``/pre/server`` serves ``/nav`` (example_interfaces/action/Fibonacci): each goal
publishes feedback every 20 ms until it is cancelled or preempted; a new goal ends the
running one CANCELED with result ``[-1]`` (preempted) before it starts; a client's cancel
ends it with ``[42]``. Serves until killed or argv[1] seconds.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

import numpy as np

from visnav.graph import Context, Node
from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import CancelResponse
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import make

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
Fibonacci = get_action_type("example_interfaces/action/Fibonacci")
running: list[ServerGoalHandle] = []
lock = threading.Lock()


def execute(handle: ServerGoalHandle) -> Any:
    n = 0
    while not handle.is_cancel_requested:
        if not handle.is_active:  # preempted by a newer goal
            return make(Fibonacci.Result, sequence=np.array([-1], dtype=np.int32))
        n += 1
        handle.publish_feedback(make(Fibonacci.Feedback, sequence=np.array([n], dtype=np.int32)))
        time.sleep(0.02)
    handle.canceled()
    return make(Fibonacci.Result, sequence=np.array([42], dtype=np.int32))


def accepted(handle: ServerGoalHandle) -> None:
    with lock:
        for old in running:
            if old.is_active:
                old.canceled()
        running.append(handle)
    handle.execute()


with Context() as ctx:
    node = Node("server", namespace="/pre", context=ctx)
    ActionServer(
        node,
        Fibonacci,
        "/nav",
        execute,
        handle_accepted_callback=accepted,
        cancel_callback=lambda _h: CancelResponse.ACCEPT,
    )
    ctx.flush_tokens()
    print("ready", flush=True)
    ctx.spin(duration)
