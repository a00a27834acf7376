"""A service server process for cross-process tests; serves until killed or argv[1] seconds.

Node ``/srv/server`` (parameters ``gain`` 1.0 in [0, 10], ``mode`` read-only) serves:
``/srv/trigger`` (Trigger, counts calls), ``/srv/set_bool`` (SetBool, echoes),
``/srv/get_map`` (GetMap: a 1000x1000 map, 1 MB), ``/srv/set_map`` (SetMap: answers
success when the map's data sum is width * height), ``/srv/boom`` (Trigger, raises),
``/srv/slow`` (Trigger, sleeps argv[2] seconds, default 30: to be killed mid-call).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from visnav.graph import Context, Node, ParamBinding, param
from visnav.graph.qos import QoSProfile
from visnav.msgs.srv import get_service_type

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
slow_s = float(sys.argv[2]) if len(sys.argv) > 2 else 30.0


@dataclass(frozen=True)
class ServerParams:
    gain: float = param(1.0, description="a gain", range=(0.0, 10.0))
    mode: str = param("fast", description="fixed at start", read_only=True)


Trigger = get_service_type("std_srvs/srv/Trigger")
SetBool = get_service_type("std_srvs/srv/SetBool")
GetMap = get_service_type("nav_msgs/srv/GetMap")
SetMap = get_service_type("nav_msgs/srv/SetMap")
calls = [0]


def trigger(_req: Any, resp: Any) -> Any:
    calls[0] += 1
    resp.success = True
    resp.message = f"call {calls[0]}"
    return resp


def set_bool(req: Any, resp: Any) -> Any:
    resp.success = bool(req.data)
    resp.message = "on" if req.data else "off"
    return resp


def get_map(_req: Any, resp: Any) -> Any:
    resp.map.header.frame_id = "map"
    resp.map.info.width = resp.map.info.height = 1000
    resp.map.data = (np.arange(1_000_000) % 100).astype(np.int8)
    return resp


def set_map(req: Any, resp: Any) -> Any:
    info = req.map.info
    resp.success = int(np.asarray(req.map.data, dtype=np.int64).sum()) == info.width * info.height
    return resp


def boom(_req: Any, _resp: Any) -> Any:
    raise ValueError("the arm is not homed")


def slow(_req: Any, resp: Any) -> Any:
    time.sleep(slow_s)
    return resp


with Context() as ctx:
    node = Node("server", namespace="/srv", context=ctx)
    ParamBinding(node, ServerParams)
    deep = QoSProfile(depth=200)
    node.create_service(Trigger, "trigger", trigger, qos_profile=deep)
    node.create_service(SetBool, "set_bool", set_bool)
    node.create_service(GetMap, "get_map", get_map)
    node.create_service(SetMap, "set_map", set_map)
    node.create_service(Trigger, "boom", boom)
    node.create_service(Trigger, "slow", slow)
    ctx.flush_tokens()
    print("ready", flush=True)
    ctx.spin(duration_s=duration)
