"""Fuzz the stack's services on the wire: the simulator's ``/gazebo/*``, map_server's, amcl's
and the SLAM node's. A raw Zenoh session sends random and mutated request payloads to each
service's key; every query gets exactly one reply (a response that reads as the service's
response type, or an error naming the service), and every server answers a proper call after.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from hypothesis import given
from hypothesis import strategies as st

from visnav.graph import Context, Node
from visnav.graph.node import _service_key
from visnav.mapping.amcl_node import AmclNode
from visnav.mapping.map_io import MapMetadata, OccupancyMap, save_map
from visnav.mapping.map_server_node import MapServerNode
from visnav.msgs.construct import message_from_dict
from visnav.msgs.serde import deserialize, serialize
from visnav.msgs.srv import get_service_type
from visnav.sim.simulator import RobotSpawn, Simulator
from visnav.slam.node import SlamNode

from .conftest import FUZZ, mutated

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"

# name -> (type, a valid request as a dict)
SERVICES: dict[str, tuple[str, dict[str, Any]]] = {
    "/gazebo/reset_world": ("std_srvs/srv/Empty", {}),
    "/gazebo/reset_simulation": ("std_srvs/srv/Empty", {}),
    "/gazebo/pause_physics": ("std_srvs/srv/Empty", {}),
    "/gazebo/unpause_physics": ("std_srvs/srv/Empty", {}),
    "/gazebo/get_model_state": (
        "gazebo_msgs/srv/GetModelState",
        {"model_name": "tb3", "relative_entity_name": "tb3::wheel_left_link"},
    ),
    "/gazebo/set_model_state": (
        "gazebo_msgs/srv/SetModelState",
        {
            "model_state": {
                "model_name": "tb3",
                "pose": {"position": {"x": 0.5}, "orientation": {"w": 1.0}},
                "twist": {"linear": {"x": 0.1}},
                "reference_frame": "world",
            }
        },
    ),
    "/gazebo/spawn_urdf_model": (
        "gazebo_msgs/srv/SpawnModel",
        {"model_name": "box", "model_xml": "<robot name='box'/>", "reference_frame": "world"},
    ),
    "/gazebo/spawn_sdf_model": ("gazebo_msgs/srv/SpawnModel", {"model_name": "tb3"}),
    "/gazebo/delete_model": ("gazebo_msgs/srv/DeleteModel", {"model_name": "tb3"}),
    "/static_map": ("nav_msgs/srv/GetMap", {}),
    "/map_server/map": ("nav_msgs/srv/GetMap", {}),
    "/global_localization": ("std_srvs/srv/Empty", {}),
    "/request_nomotion_update": ("std_srvs/srv/Empty", {}),
    "/slam/reset": ("std_srvs/srv/Empty", {}),
    "/slam/pause": ("std_srvs/srv/Empty", {}),
    "/slam/resume": ("std_srvs/srv/Empty", {}),
    "/slam/save_map": ("std_srvs/srv/Trigger", {}),
}


def _request_bytes(name: str) -> bytes:
    type_name, values = SERVICES[name]
    return serialize(message_from_dict(f"{type_name}_Request", values))


def _raw_get(session: zenoh.Session, key: str, payload: bytes) -> list[Any]:
    replies: list[Any] = []
    done = threading.Event()
    session.get(
        key, zenoh.handlers.Callback(replies.append, done.set), payload=payload, timeout=10.0
    )
    assert done.wait(20.0), f"the server of {key} never finished the query"
    return replies


@pytest.mark.slow
def test_malformed_requests_to_the_stack_services_never_kill_them(
    domain: int, tmp_path: Path
) -> None:
    grid = np.zeros((20, 30), dtype=np.int8)
    grid[0, :] = 100
    meta = MapMetadata(image=Path("x"), resolution=0.1, origin=(-1.0, -1.0, 0.0))
    yaml_path, _ = save_map(OccupancyMap(grid, meta).to_msg(), tmp_path / "map")
    robot = RobotSpawn(
        source=TB3 / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3},
        spawn=(0.5, 0.0, 0.0, 0.0),
        name="tb3",
    )
    with Context(domain) as ctx, Context(domain) as raw_ctx:
        sim = Simulator("empty", [robot], context=ctx, realtime=True)
        MapServerNode(context=ctx, parameter_overrides={"yaml_filename": str(yaml_path)})
        AmclNode(context=ctx)
        SlamNode(context=ctx, parameter_overrides={"database_path": str(tmp_path / "s.npz")})
        stop = threading.Event()
        # the simulation steps and spins the context (services, and the map reaching amcl)
        runner = threading.Thread(target=lambda: sim.run(None, until=stop.is_set))
        runner.start()
        raw = raw_ctx.zenoh
        assert raw is not None
        probe = Node("probe", context=raw_ctx, start_parameter_services=False)
        try:
            for name, (type_name, _) in SERVICES.items():
                client = probe.create_client(get_service_type(type_name), name)
                assert client.wait_for_service(10.0), name

            @FUZZ
            @given(data=st.data(), name=st.sampled_from(sorted(SERVICES)))
            def check(data: st.DataObject, name: str) -> None:
                type_name, _ = SERVICES[name]
                payload = data.draw(
                    st.one_of(st.binary(max_size=64), mutated(_request_bytes(name))),
                    label="payload",
                )
                replies = _raw_get(raw.session, _service_key(domain, name, type_name), payload)
                assert len(replies) == 1
                reply = replies[0]
                if reply.ok is not None:  # it read as a request: a well-formed response
                    deserialize(reply.ok.payload.to_bytes(), f"{type_name}_Response")
                else:
                    assert f"'{name}'" in reply.err.payload.to_bytes().decode()

            check()
            for name, (type_name, values) in SERVICES.items():  # every server still answers
                stype = get_service_type(type_name)
                request = message_from_dict(stype.request_type_name, values)
                reply = probe.create_client(stype, name).call(request, timeout_sec=10.0)
                assert isinstance(reply, stype.Response), name
            assert sim.now_ns > 0
            assert runner.is_alive()
        finally:
            stop.set()
            runner.join(10.0)
            sim.close()
