"""Services through the ROS 1 bridge, in process: visnav's master, ROS 1 nodes and graph.

Real ``rosservice`` / ``rospy`` against the bridge: tests/bridge/test_ros1_services_real.py.
"""

from __future__ import annotations

import shutil
import socket
import struct
import subprocess
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.bridge.bridge import BridgeOptions, Ros1Bridge
from visnav.bridge.errors import Ros1ServiceError, TcprosError, UnconvertibleTypeError
from visnav.bridge.master import Ros1Master
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.srvmap import decode_part, encode_part, ros1_service_type
from visnav.bridge.tcpros import encode_header, read_header
from visnav.bridge.tcpros_service import call_service, parse_rosrpc_uri, probe_service
from visnav.bridge.typemap import ros1_type
from visnav.graph import Context, Node
from visnav.graph.errors import ServiceError
from visnav.msgs.construct import default_message
from visnav.msgs.srv import get_service_type

SetBool = get_service_type("std_srvs/srv/SetBool")
Trigger = get_service_type("std_srvs/srv/Trigger")
Empty = get_service_type("std_srvs/srv/Empty")

# ROS 1's MD5 sums (Debian's python3-std-srvs / python3-nav-msgs: SetBool._md5sum, ...)
ROS1_MD5 = {
    "std_srvs/srv/SetBool": "09fb03525b03e7ea1fd3992bafd87e16",
    "std_srvs/srv/Trigger": "937c9679a518e3a18d831e57125ea522",
    "std_srvs/srv/Empty": "d41d8cd98f00b204e9800998ecf8427e",
    "nav_msgs/srv/GetPlan": "421c8ea4d21c6c9db7054b4bbdf1e024",
    "nav_msgs/srv/GetMap": "6cdd0a18e0aff5b0a3ca2326a89b54ff",
    "nav_msgs/srv/SetMap": "c36922319011e63ed7784112ad4fdd32",
    "nav_msgs/srv/LoadMap": "22e647fdfbe3b23c8c9f419908afaebd",
    # gazebo_msgs (no Debian package: the values of gazebo_msgs' generated code)
    "gazebo_msgs/srv/GetModelState": "4c515e936d3319c9610c559c60bfc3d4",
    "gazebo_msgs/srv/SetModelState": "5b3ab0281d4f5445def017e3a2e4a07b",
    "gazebo_msgs/srv/SpawnModel": "9ed9c82c96abe1a00c3e8cdaeee24413",
    "gazebo_msgs/srv/DeleteModel": "9ce56b4e9e54616de25d796dc972a262",
}
SYSTEM_PYTHON = "/usr/bin/python3"


class _Graphs:
    def __init__(self) -> None:
        self.master = Ros1Master(0)
        self.master.start()
        self.ctx = Context(transport="local")
        self.ros1 = Ros1Node("visnav_bridge", master_uri=self.master.uri, host="127.0.0.1")
        self.ros1.start()
        self.peer = Ros1Node("peer", master_uri=self.master.uri, host="127.0.0.1")
        self.peer.start()
        self.bridge = Ros1Bridge(
            Node("ros1_bridge", context=self.ctx),
            self.ros1,
            BridgeOptions(scan_period_s=0.05, service_timeout_s=3.0),
        )

    def spin_until(self, pred: Callable[[], bool], timeout_s: float = 5.0) -> bool:
        return self.ctx.spin_until(pred, timeout_s)

    def call(self, name: str, srv: str, request: Any, **kw: Any) -> Any:
        """Call ``name`` as a ROS 1 client would, while the visnav executor spins."""
        stype = ros1_service_type(srv)
        uri = self.peer.master.lookup_service(name)
        out: dict[str, Any] = {}

        def run() -> None:
            try:
                data = encode_part(request, stype.request)
                out["ok"] = decode_part(
                    call_service(uri, name, stype, data, caller_id="/peer", **kw), stype.response
                )
            except Exception as exc:  # noqa: BLE001 - handed to the test
                out["error"] = exc

        thread = threading.Thread(target=run)
        thread.start()
        self.spin_until(lambda: not thread.is_alive(), 10.0)
        thread.join(1.0)
        if "error" in out:
            raise out["error"]
        return out["ok"]

    def close(self) -> None:
        self.bridge.close()
        self.peer.close()
        self.ros1.close()
        self.ctx.shutdown()
        self.master.close()


@pytest.fixture
def graphs() -> Iterator[_Graphs]:
    g = _Graphs()
    yield g
    g.close()


def test_md5_sums_are_ros1s() -> None:
    for name, md5 in ROS1_MD5.items():
        assert ros1_service_type(name).md5sum == md5, name
    st_ = ros1_service_type("std_srvs/SetBool")
    assert (st_.ros1_name, st_.request.ros1_name, st_.response.ros1_name) == (
        "std_srvs/SetBool",
        "std_srvs/SetBoolRequest",
        "std_srvs/SetBoolResponse",
    )
    assert st_.request.md5sum == "8b94c1b53db61fb6aed406028ad6332a"  # SetBoolRequest
    # the gazebo_msgs messages cross as topics too (the same .msg in ROS 1 and ROS 2)
    assert ros1_type("gazebo_msgs/msg/ModelStates").md5sum == "48c080191eb15c41858319b4d8a609c2"
    assert ros1_type("gazebo_msgs/msg/ModelState").md5sum == "9330fd35f2fcd82d457e54bd54e10593"


def test_ros2_only_types_do_not_cross() -> None:
    with pytest.raises(UnconvertibleTypeError, match="only in ROS 2"):
        ros1_service_type("rcl_interfaces/srv/GetParameters")
    with pytest.raises(UnconvertibleTypeError, match="actionlib topics"):
        ros1_service_type("move_base_msgs/action/MoveBase_SendGoal")


@pytest.mark.skipif(
    subprocess.run(
        [SYSTEM_PYTHON, "-c", "import nav_msgs.srv, std_srvs.srv"],
        capture_output=True,
        check=False,
    ).returncode
    != 0
    if shutil.which(SYSTEM_PYTHON)
    else True,
    reason="Debian's python3-nav-msgs / python3-std-srvs missing",
)
def test_bytes_and_md5_equal_genpys() -> None:
    request = default_message("nav_msgs/srv/GetPlan_Request")
    request.goal.header.frame_id = "map"
    request.goal.pose.position.x = 1.5
    request.start.header.stamp.sec = 7
    request.tolerance = 0.5
    ours = encode_part(request, ros1_service_type("nav_msgs/srv/GetPlan").request)
    script = (
        "import io, sys, nav_msgs.srv as n, std_srvs.srv as s\n"
        "r = n.GetPlanRequest(); r.goal.header.frame_id = 'map'; r.goal.pose.position.x = 1.5\n"
        "r.start.header.stamp.secs = 7; r.tolerance = 0.5\n"
        # ROS 2's Quaternion defaults to w = 1 (visnav's default message), genpy's to 0
        "r.goal.pose.orientation.w = 1.0; r.start.pose.orientation.w = 1.0\n"
        "b = io.BytesIO(); r.serialize(b); print(b.getvalue().hex())\n"
        "for c in (s.SetBool, s.Trigger, s.Empty, n.GetPlan, n.GetMap, n.SetMap, n.LoadMap):\n"
        "    print(c._type, c._md5sum)\n"
    )
    out = subprocess.run(
        [SYSTEM_PYTHON, "-c", script], capture_output=True, text=True, check=True
    ).stdout.split("\n")
    assert bytes.fromhex(out[0]) == ours
    theirs = dict(line.split() for line in out[1:] if line)
    for name, md5 in theirs.items():
        assert ros1_service_type(name).md5sum == md5, name
    back = decode_part(ours, ros1_service_type("nav_msgs/srv/GetPlan").request)
    assert back.goal.pose.position.x == 1.5
    assert back.start.header.stamp.sec == 7


def test_ros1_client_calls_visnav_service(graphs: _Graphs) -> None:
    server = Node("motor", context=graphs.ctx)
    calls: list[bool] = []

    def on_set(request: Any, response: Any) -> Any:
        calls.append(request.data)
        response.success = request.data
        response.message = "motor on" if request.data else "motor off"
        return response

    def on_trigger(request: Any, response: Any) -> Any:
        raise ValueError("the motor is stuck")

    server.create_service(SetBool, "/enable", on_set)
    server.create_service(Trigger, "/stuck", on_trigger)
    server.create_service(Empty, "/gazebo/reset_world", lambda req, resp: resp)
    assert graphs.spin_until(
        lambda: (
            graphs.bridge.services.out_services() == ["/enable", "/gazebo/reset_world", "/stuck"]
        )
    )
    # the parameter services (rcl_interfaces) stay in visnav
    _, _, srvs = graphs.peer.master.system_state()
    assert sorted(n for n, _ in srvs) == ["/enable", "/gazebo/reset_world", "/stuck"]

    reply = graphs.call("/enable", "std_srvs/srv/SetBool", SetBool.Request(data=True))
    assert (reply.success, reply.message) == (True, "motor on")
    assert calls == [True]
    graphs.call("/gazebo/reset_world", "std_srvs/srv/Empty", Empty.Request())
    with pytest.raises(Ros1ServiceError, match=r"/stuck failed: .*ValueError: the motor is stuck"):
        graphs.call("/stuck", "std_srvs/srv/Trigger", Trigger.Request())

    # rosservice's probe learns the type; a wrong md5sum is refused with rospy's text
    uri = graphs.peer.master.lookup_service("/enable")
    assert parse_rosrpc_uri(uri)[0] == "127.0.0.1"
    header = probe_service(uri, "/enable", caller_id="/rosservice")
    assert header["type"] == "std_srvs/SetBool"
    assert header["md5sum"] == ROS1_MD5["std_srvs/srv/SetBool"]
    with pytest.raises(Ros1ServiceError, match="md5sums do not match"):
        graphs.call("/enable", "std_srvs/srv/Trigger", Trigger.Request())

    # the server goes: the service leaves the ROS 1 master
    server.destroy_node()
    assert graphs.spin_until(lambda: graphs.bridge.services.out_services() == [])
    assert graphs.peer.master.system_state()[2] == []


def test_persistent_connection_carries_many_calls(graphs: _Graphs) -> None:
    server = Node("motor", context=graphs.ctx)
    server.create_service(SetBool, "/enable", lambda req, resp: _set(resp, req.data))
    assert graphs.spin_until(lambda: graphs.bridge.services.out_services() == ["/enable"])
    stype = ros1_service_type("std_srvs/srv/SetBool")
    host, port = parse_rosrpc_uri(graphs.peer.master.lookup_service("/enable"))
    got: list[bool] = []

    def run() -> None:
        with socket.create_connection((host, port), timeout=5) as sock:
            sock.sendall(
                encode_header(
                    {
                        "callerid": "/p",
                        "service": "/enable",
                        "md5sum": stype.md5sum,
                        "persistent": "1",
                    }
                )
            )
            assert read_header(sock)["type"] == "std_srvs/SetBool"
            for i in range(5):
                body = encode_part(SetBool.Request(data=bool(i % 2)), stype.request)
                sock.sendall(struct.pack("<I", len(body)) + body)
                ok = sock.recv(1)
                size = struct.unpack("<I", _exact(sock, 4))[0]
                response = decode_part(_exact(sock, size), stype.response)
                got.append(ok == b"\x01" and response.success)

    thread = threading.Thread(target=run)
    thread.start()
    assert graphs.spin_until(lambda: not thread.is_alive(), 10.0)
    assert got == [False, True, False, True, False]


def _set(resp: Any, value: bool) -> Any:
    resp.success = value
    return resp


def _exact(sock: socket.socket, n: int) -> bytes:
    buf = b""
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError("closed")
        buf += chunk
    return buf


def test_visnav_client_calls_ros1_service(graphs: _Graphs) -> None:
    stype = ros1_service_type("std_srvs/srv/SetBool")

    def handler(data: bytes) -> bytes:
        request = decode_part(data, stype.request)
        if not request.data:
            raise RuntimeError("refusing to switch off")
        return encode_part(SetBool.Response(success=True, message="on in ROS 1"), stype.response)

    graphs.peer.advertise_service("/ros1_enable", stype, handler)
    caller = Node("panel", context=graphs.ctx)
    client = caller.create_client(SetBool, "/ros1_enable")
    assert graphs.spin_until(lambda: graphs.bridge.services.in_services() == ["/ros1_enable"])
    assert graphs.spin_until(client.service_is_ready)
    future = client.call_async(SetBool.Request(data=True))
    assert graphs.spin_until(future.done)
    reply = future.result()
    assert reply is not None
    assert reply.message == "on in ROS 1"
    future = client.call_async(SetBool.Request(data=False))
    assert graphs.spin_until(future.done)
    with pytest.raises(ServiceError, match="refusing to switch off"):
        future.result()
    # not re-exported to ROS 1 (no loop): the master still has the peer as the provider
    _, _, srvs = graphs.peer.master.system_state()
    assert srvs == [["/ros1_enable", ["/peer"]]]
    # the ROS 1 provider goes: the proxy goes too
    graphs.peer.unadvertise_service("/ros1_enable")
    assert graphs.spin_until(lambda: graphs.bridge.services.in_services() == [])


def test_service_patterns(graphs: _Graphs) -> None:
    graphs.bridge.close()
    graphs.bridge = Ros1Bridge(
        Node("ros1_bridge2", context=graphs.ctx),
        graphs.ros1,
        BridgeOptions(scan_period_s=0.05, services=("/gazebo/*",), exclude=("*/delete_*",)),
    )
    server = Node("sim", context=graphs.ctx)
    for name in ("/gazebo/reset_world", "/gazebo/delete_model", "/other"):
        server.create_service(Empty, name, lambda req, resp: resp)
    assert graphs.spin_until(
        lambda: graphs.bridge.services.out_services() == ["/gazebo/reset_world"]
    )
    graphs.ctx.spin(duration_s=0.2)
    assert graphs.bridge.services.out_services() == ["/gazebo/reset_world"]


# ---------------------------------------------------------------------------- fuzz
_SERVED: dict[str, Any] = {}


def _fuzz_node() -> tuple[Ros1Node, str]:
    if "node" not in _SERVED:
        master = Ros1Master(0)
        master.start()
        node = Ros1Node("fuzzed", master_uri=master.uri, host="127.0.0.1")
        node.start()
        stype = ros1_service_type("std_srvs/srv/SetBool")

        def handler(data: bytes) -> bytes:
            request = decode_part(data, stype.request)
            return encode_part(SetBool.Response(success=request.data, message=""), stype.response)

        node.advertise_service("/fuzz", stype, handler)
        _SERVED.update(master=master, node=node, stype=stype)
    return _SERVED["node"], f"127.0.0.1:{_SERVED['node'].tcp_port}"


@pytest.fixture(scope="module", autouse=True)
def _close_fuzz_node() -> Iterator[None]:
    yield
    if "node" in _SERVED:
        _SERVED["node"].close()
        _SERVED["master"].close()
        _SERVED.clear()


def _send_raw(port: int, data: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        try:
            sock.sendall(data)
            sock.shutdown(socket.SHUT_WR)
        except OSError:
            return b""
        out = b""
        while True:
            try:
                chunk = sock.recv(65536)
            except OSError:
                return out
            if not chunk:
                return out
            out += chunk


def _good_call(node: Ros1Node) -> bool:
    stype = _SERVED["stype"]
    reply = call_service(
        f"rosrpc://127.0.0.1:{node.tcp_port}",
        "/fuzz",
        stype,
        encode_part(SetBool.Request(data=True), stype.request),
        caller_id="/check",
    )
    return bool(decode_part(reply, stype.response).success)


_fields = st.dictionaries(
    st.sampled_from(["service", "md5sum", "callerid", "persistent", "probe", "x"]),
    st.one_of(
        st.sampled_from(["/fuzz", "*", "09fb03525b03e7ea1fd3992bafd87e16", "1", "/nope"]),
        st.text(max_size=20),
    ),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    header=st.one_of(
        _fields.map(lambda f: encode_header({"service": "/fuzz", **f})),
        st.binary(max_size=64),
        st.binary(max_size=32).map(lambda b: struct.pack("<I", len(b) + 10) + b),
    ),
    body=st.one_of(
        st.binary(max_size=32),
        st.binary(max_size=8).map(lambda b: struct.pack("<I", len(b)) + b),
        st.just(struct.pack("<I", 1 << 31)),
        st.just(struct.pack("<I", 5) + b"\x01"),
    ),
)
def test_fuzz_malformed_service_connections_keep_the_node_serving(
    header: bytes, body: bytes
) -> None:
    node, _ = _fuzz_node()
    reply = _send_raw(node.tcp_port, header + body)
    if reply[:4] and len(reply) >= 4:
        size = struct.unpack_from("<I", reply)[0]
        fields = reply[4 : 4 + size]
        assert b"=" in fields or not fields  # a header (maybe an error one), never garbage
    assert _good_call(node)


def test_decode_of_broken_bytes_names_the_type() -> None:
    part = ros1_service_type("std_srvs/srv/Trigger").response
    with pytest.raises(TcprosError, match="std_srvs/TriggerResponse"):
        decode_part(b"\x01\xff\xff\xff\x7f", part)
