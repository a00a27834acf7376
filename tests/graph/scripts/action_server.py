"""An action server process for cross-process tests; serves until killed or argv[1] seconds.

Node ``/act/server`` serves ``/fibonacci`` (example_interfaces/action/Fibonacci):
goals of order > 40 are rejected; feedback after every number (10 ms apart); a
cancel request is accepted and ends the goal CANCELED; order 0 raises in the execute
callback (the goal aborts); order 1 is answered at once (for latency).
"""

from __future__ import annotations

import sys
import time
from typing import Any

import numpy as np

from visnav.graph import Context, Node
from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import CancelResponse, GoalResponse
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import make

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
Fibonacci = get_action_type("example_interfaces/action/Fibonacci")


def execute(handle: ServerGoalHandle) -> Any:
    order = handle.request.order
    if order == 0:
        raise RuntimeError("order 0 is not a sequence")
    seq = [0, 1]
    for i in range(1, order):
        if handle.is_cancel_requested:
            handle.canceled()
            return make(Fibonacci.Result, sequence=np.array(seq, dtype=np.int32))
        seq.append(seq[i] + seq[i - 1])
        handle.publish_feedback(make(Fibonacci.Feedback, sequence=np.array(seq, dtype=np.int32)))
        time.sleep(0.1)  # order 40 runs 4 s: time for a Ctrl-C test to cancel it
    handle.succeed()
    return make(Fibonacci.Result, sequence=np.array(seq, dtype=np.int32))


with Context() as ctx:
    node = Node("server", namespace="/act", context=ctx)
    ActionServer(
        node,
        Fibonacci,
        "/fibonacci",
        execute,
        goal_callback=lambda g: GoalResponse.REJECT if g.order > 40 else GoalResponse.ACCEPT,
        cancel_callback=lambda _h: CancelResponse.ACCEPT,
    )
    ctx.flush_tokens()
    print("ready", flush=True)
    ctx.spin(duration)
