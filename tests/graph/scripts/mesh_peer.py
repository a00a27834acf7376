"""One of N processes started at the same moment: each must discover all the others.

Usage: mesh_peer.py INDEX COUNT TIMEOUT_S. Creates node ``peer<INDEX>`` with a publisher
``/mesh/p<INDEX>`` and a Trigger service ``/mesh/s<INDEX>``, waits until it sees every
peer's publisher and service, calls each peer's service once, then waits for the
others to finish their calls. Prints ``ok`` or ``missing: ...`` and exits.
"""

from __future__ import annotations

import sys
import threading
import time

from visnav.graph import Context, Node
from visnav.msgs import String
from visnav.msgs.srv import get_service_type

index, count, timeout_s = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
Trigger = get_service_type("std_srvs/srv/Trigger")
served = [0]


def answer(_req: object, resp: object) -> object:
    served[0] += 1
    resp.success = True  # type: ignore[attr-defined]
    resp.message = f"peer{index}"  # type: ignore[attr-defined]
    return resp


with Context() as ctx:
    node = Node(f"peer{index}", context=ctx)
    node.create_publisher(String, f"/mesh/p{index}", 10)
    node.create_service(Trigger, f"/mesh/s{index}", answer)
    stop = threading.Event()
    spinner = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, timeout_s + 5))
    spinner.start()
    deadline = time.monotonic() + timeout_s
    want_topics = {f"/mesh/p{i}" for i in range(count)}
    clients = [node.create_client(Trigger, f"/mesh/s{i}") for i in range(count) if i != index]
    missing: list[str] = []
    while time.monotonic() < deadline:
        topics = {t for t, _ in node.get_topic_names_and_types()}
        missing = sorted(want_topics - topics) + [
            c.srv_name for c in clients if not c.service_is_ready()
        ]
        if not missing:
            break
        time.sleep(0.02)
    if not missing:
        for c in clients:
            try:
                reply = c.call(Trigger.Request(), timeout_sec=max(1.0, deadline - time.monotonic()))
                if not reply.success:
                    missing.append(f"{c.srv_name} (bad reply)")
            except Exception as exc:  # noqa: BLE001 - reported to the test
                missing.append(f"{c.srv_name} ({exc})")
    # stay until every other peer called us (or the deadline), so that none misses us
    while served[0] < count - 1 and time.monotonic() < deadline:
        time.sleep(0.02)
    stop.set()
    spinner.join()
    print("ok" if not missing else f"missing: {missing}", flush=True)
