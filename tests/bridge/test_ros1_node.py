"""visnav's ROS 1 node and master against each other (real sockets, one process)."""

from __future__ import annotations

import logging
import socket
import threading
import time
import xmlrpc.client
from collections.abc import Callable, Iterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.bridge.errors import BridgeError, MasterError, MasterUnreachableError
from visnav.bridge.master import Ros1Master, resolve_param_key
from visnav.bridge.master_api import MasterClient, advertised_host, bind_address
from visnav.bridge.ros1_node import Ros1Node, ThreadingXmlRpcServer
from visnav.bridge.runner import open_ros1_node
from visnav.bridge.tcpros import encode_header, frame, read_header
from visnav.bridge.typemap import Ros1Type, ros1_type

STRING = ros1_type("std_msgs/msg/String")


def _string(text: str) -> bytes:
    data = text.encode()
    return len(data).to_bytes(4, "little") + data


def _wait(pred: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return pred()


@pytest.fixture
def master() -> Iterator[Ros1Master]:
    m = Ros1Master(0)
    m.start()
    yield m
    m.close()


@pytest.fixture
def make_node(master: Ros1Master) -> Iterator[Callable[..., Ros1Node]]:
    nodes: list[Ros1Node] = []

    def make(name: str, **kw: object) -> Ros1Node:
        node = Ros1Node(name, master_uri=master.uri, host="127.0.0.1", **kw)  # type: ignore[arg-type]
        node.start()
        nodes.append(node)
        return node

    yield make
    for n in nodes:
        n.close()


def test_publish_subscribe_both_orders(make_node: Callable[..., Ros1Node]) -> None:
    talker, early, late = make_node("talker"), make_node("early"), make_node("late")
    got_early: list[bytes] = []
    got_late: list[bytes] = []
    early.subscribe("/chatter", STRING, got_early.append)  # before the publisher: publisherUpdate
    talker.advertise("/chatter", STRING)
    late.subscribe("/chatter", STRING, got_late.append)  # after: registerSubscriber's answer
    assert _wait(lambda: talker.subscriber_count("/chatter") == 2)
    for i in range(5):
        talker.publish("/chatter", _string(f"hi {i}"))
    assert _wait(lambda: len(got_early) == 5 and len(got_late) == 5)
    assert got_late[-1] == _string("hi 4")


def test_latched_topic_reaches_late_subscriber(make_node: Callable[..., Ros1Node]) -> None:
    talker, late = make_node("talker"), make_node("late")
    talker.advertise("/tf_static", STRING, latch=True)
    talker.publish("/tf_static", _string("old"))
    talker.publish("/tf_static", _string("static"))
    got: list[bytes] = []
    late.subscribe("/tf_static", STRING, got.append)
    assert _wait(lambda: got == [_string("static")])


def test_md5_mismatch_refused_and_node_keeps_running(
    make_node: Callable[..., Ros1Node], caplog: pytest.LogCaptureFixture
) -> None:
    talker, listener = make_node("talker"), make_node("listener")
    talker.advertise("/chatter", STRING)
    talker.advertise("/other", STRING)
    wrong = Ros1Type(STRING.ros2_name, STRING.ros1_name, "0" * 32, STRING.definition)
    got: list[bytes] = []
    with caplog.at_level(logging.WARNING, logger="visnav.bridge"):
        listener.subscribe("/chatter", wrong, got.append)
        assert _wait(lambda: "0" * 32 in caplog.text and STRING.md5sum in caplog.text)
    assert talker.subscriber_count("/chatter") == 0
    ok: list[bytes] = []
    listener.subscribe("/other", STRING, ok.append)
    assert _wait(lambda: talker.subscriber_count("/other") == 1)
    talker.publish("/other", _string("still here"))
    assert _wait(lambda: ok == [_string("still here")])


class _FakePublisher:
    """A ROS 1 'publisher' that misbehaves after requestTopic, on a real socket."""

    def __init__(self, send: Callable[[socket.socket], None]) -> None:
        self.tcp = socket.create_server(("127.0.0.1", 0))
        self.xmlrpc = ThreadingXmlRpcServer(("127.0.0.1", 0))
        port = self.tcp.getsockname()[1]
        self.xmlrpc.register_function(
            lambda *_: [1, "ready", ["TCPROS", "127.0.0.1", port]], "requestTopic"
        )
        self.uri = f"http://127.0.0.1:{self.xmlrpc.server_address[1]}/"
        self._send = send
        threading.Thread(target=self.xmlrpc.serve_forever, daemon=True).start()
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        conn, _ = self.tcp.accept()
        read_header(conn)
        self._send(conn)
        conn.close()

    def close(self) -> None:
        self.xmlrpc.shutdown()
        self.xmlrpc.server_close()
        self.tcp.close()


def _header_without_md5(conn: socket.socket) -> None:
    conn.sendall(encode_header({"callerid": "/bad", "type": "std_msgs/String"}))


def _closes_mid_message(conn: socket.socket) -> None:
    conn.sendall(
        encode_header({"callerid": "/bad", "type": "std_msgs/String", "md5sum": STRING.md5sum})
    )
    conn.sendall(frame(b"x" * 100) + b"x" * 30)


@pytest.mark.parametrize(
    ("behaviour", "words"),
    [
        (_header_without_md5, "sent a header without md5sum"),
        (_closes_mid_message, "closed the connection after 30 of 100 bytes"),
    ],
)
def test_broken_publisher_costs_only_its_connection(
    master: Ros1Master,
    make_node: Callable[..., Ros1Node],
    caplog: pytest.LogCaptureFixture,
    behaviour: Callable[[socket.socket], None],
    words: str,
) -> None:
    fake = _FakePublisher(behaviour)
    good, listener = make_node("good"), make_node("listener")
    MasterClient(master.uri, "/bad").register_publisher("/chatter", "std_msgs/String", fake.uri)
    good.advertise("/chatter", STRING)
    got: list[bytes] = []
    with caplog.at_level(logging.WARNING, logger="visnav.bridge"):
        listener.subscribe("/chatter", STRING, got.append)
        assert _wait(lambda: words in caplog.text)
    assert _wait(lambda: good.subscriber_count("/chatter") == 1)
    good.publish("/chatter", _string("fine"))
    assert _wait(lambda: got == [_string("fine")])
    fake.close()


def test_slave_api_answers_rosnode_calls(make_node: Callable[..., Ros1Node]) -> None:
    stopped: list[str] = []
    talker = make_node("talker", on_shutdown=stopped.append)
    listener = make_node("listener")
    talker.advertise("/chatter", STRING)
    listener.subscribe("/chatter", STRING, lambda _b: None)
    assert _wait(lambda: talker.subscriber_count("/chatter") == 1)
    api = xmlrpc.client.ServerProxy(talker.uri)
    code, _, pid = api.getPid("/t")
    assert code == 1
    assert isinstance(pid, int)
    assert api.getPublications("/t")[2] == [
        ["/rosout", "rosgraph_msgs/Log"],
        ["/chatter", "std_msgs/String"],
    ]
    info = api.getBusInfo("/t")[2]
    assert [(i[1], i[2], i[4]) for i in info] == [("/listener", "o", "/chatter")]
    in_info = xmlrpc.client.ServerProxy(listener.uri).getBusInfo("/t")[2]
    assert [(i[1], i[2], i[4]) for i in in_info] == [("/talker", "i", "/chatter")]
    assert api.getMasterUri("/t")[2] == talker.master.uri
    assert api.requestTopic("/t", "/nope", [["TCPROS"]])[0] == -1
    assert api.requestTopic("/t", "/chatter", [["UDPROS"]])[0] == 0
    assert api.shutdown("/rosnode", "user request")[0] == 1
    assert _wait(lambda: stopped == ["/rosnode: user request"])


def test_master_state_and_params(master: Ros1Master, make_node: Callable[..., Ros1Node]) -> None:
    talker = make_node("talker")
    talker.advertise("/chatter", STRING)
    client = MasterClient(master.uri, "/tool")
    pubs, subs, _ = client.system_state()
    assert pubs == [["/chatter", ["/talker"]], ["/rosout", ["/talker"]]]
    assert subs == []
    assert client.topic_types() == {"/chatter": "std_msgs/String", "/rosout": "rosgraph_msgs/Log"}
    assert client.call("lookupNode", "/talker") == talker.uri
    client.set_param("/robot/arm/length", 1.5)
    client.set_param("/use_sim_time", True)
    assert client.get_param("/robot") == {"arm": {"length": 1.5}}
    assert MasterClient(master.uri, "/robot/node").get_param("arm/length") == 1.5
    assert client.call("hasParam", "/robot/arm") is True
    with pytest.raises(MasterError, match="cannot find"):
        client.call("searchParam", "arm")  # /tool's namespace is /: no /arm
    assert MasterClient(master.uri, "/robot/node").call("searchParam", "arm") == "/robot/arm"
    assert client.call("getParamNames") == ["/robot/arm/length", "/use_sim_time"]
    client.call("deleteParam", "/robot/arm")
    assert client.call("hasParam", "/robot/arm") is False
    talker.unadvertise("/chatter")
    assert client.system_state()[0] == [["/rosout", ["/talker"]]]


def test_resolve_param_key() -> None:
    assert resolve_param_key("/ns/node", "a/b") == "/ns/a/b"
    assert resolve_param_key("/ns/node", "~p") == "/ns/node/p"
    assert resolve_param_key("/node", "/abs//x/") == "/abs/x"


def test_no_master_is_one_clear_line() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    uri = f"http://127.0.0.1:{port}/"
    env = {"ROS_MASTER_URI": uri, "ROS_IP": "127.0.0.1"}
    with pytest.raises(MasterUnreachableError) as info:
        open_ros1_node("visnav_bridge", env=env)
    text = str(info.value)
    assert uri in text
    assert "roscore" in text
    assert "--serve-master" in text
    assert "\n" not in text


def test_host_resolution_follows_rospy() -> None:
    assert advertised_host({"ROS_HOSTNAME": "robot.local", "ROS_IP": "10.0.0.2"}) == "robot.local"
    assert advertised_host({"ROS_IP": "10.0.0.2"}) == "10.0.0.2"
    assert advertised_host({}) != ""
    assert bind_address("localhost") == "127.0.0.1"
    assert bind_address("127.0.1.1") == "127.0.1.1"  # Debian's /etc/hosts address of the host name
    assert bind_address("10.0.0.2") == "10.0.0.2"  # never all interfaces: tests/bridge/test_bind.py


def test_served_master_port_taken_is_named(master: Ros1Master) -> None:
    with pytest.raises(BridgeError, match=rf"127.0.0.1:{master.port}: .*--serve-master PORT"):
        Ros1Master(master.port)


@given(st.text(max_size=30), st.text(max_size=30))
def test_fuzz_param_keys_resolve_to_absolute(caller: str, key: str) -> None:
    out = resolve_param_key("/" + caller.strip("/"), key)
    assert out.startswith("/")
    assert "//" not in out


def test_subscriber_connections_keep_a_small_send_buffer(
    make_node: Callable[..., Ros1Node],
) -> None:
    """At most about one image waits in the kernel for a subscriber (SEND_BUFFER_BYTES)."""
    from pathlib import Path

    from visnav.bridge.ros1_node import SEND_BUFFER_BYTES

    talker, listener = make_node("talker"), make_node("listener")
    talker.advertise("/chatter", STRING)
    listener.subscribe("/chatter", STRING, lambda _raw: None)
    assert _wait(lambda: talker.subscriber_count("/chatter") == 1)
    conn = talker._pubs["/chatter"].conns[0]
    size = conn.sock.getsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF)
    # Linux caps the request at net.core.wmem_max (212992 on many kernels, 4 MiB on the
    # development machine) and doubles it (bookkeeping); the autotuned default starts at
    # 16 KiB
    try:
        asked = min(SEND_BUFFER_BYTES, int(Path("/proc/sys/net/core/wmem_max").read_text()))
    except OSError:
        asked = SEND_BUFFER_BYTES
    assert asked <= size <= 2 * asked
