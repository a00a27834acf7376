"""The bridge's ROS 1 servers listen only where they are reached (issue 31 item 6).

A second network namespace, joined to this one by a veth pair with addresses of a private
range used only between the two, plays "another machine": by default the bridge's slave
XML-RPC API and TCPROS server are not reachable from it; with ``ROS_IP`` set to the veth
address they are. Skipped (the bound addresses are still checked with ``getsockname``) where
network namespaces cannot be made.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from visnav.bridge.errors import BridgeError
from visnav.bridge.master import Ros1Master
from visnav.bridge.master_api import bind_address, node_addresses
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.runner import open_ros1_node

_NET = 10, 213  # 10.213.N.0/30, used only between this test's namespace pair
_PROBE = """
import socket, sys, xmlrpc.client
socket.setdefaulttimeout(3.0)
host, xport, tport = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
out = []
for port in (xport, tport):
    try:
        socket.create_connection((host, port), timeout=2).close()
        out.append("open")
    except OSError as exc:
        out.append(type(exc).__name__)
try:
    pid = xmlrpc.client.ServerProxy(f"http://{host}:{xport}/").getPid("/probe")[2]
    out.append(str(pid))
except Exception as exc:
    out.append(type(exc).__name__)
print(" ".join(out))
"""


class _NetNs:
    """A network namespace ``peer`` with a veth pair: ``host_ip`` here, ``peer_ip`` there."""

    def __init__(self) -> None:
        n = os.getpid() % 250 + 1
        self.name = f"vnbind{os.getpid()}"
        self.here, self.there = f"vnbh{os.getpid() % 100000}", f"vnbp{os.getpid() % 100000}"
        self.host_ip, self.peer_ip = f"{_NET[0]}.{_NET[1]}.{n}.1", f"{_NET[0]}.{_NET[1]}.{n}.2"
        self.made = False

    def _ip(self, *args: str) -> None:
        subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)

    def create(self) -> None:
        self._ip("netns", "add", self.name)
        self.made = True
        self._ip("link", "add", self.here, "type", "veth", "peer", "name", self.there)
        self._ip("link", "set", self.there, "netns", self.name)
        self._ip("addr", "add", f"{self.host_ip}/30", "dev", self.here)
        self._ip("link", "set", self.here, "up")
        self._ip(
            "netns", "exec", self.name, "ip", "addr", "add", f"{self.peer_ip}/30", "dev", self.there
        )
        self._ip("netns", "exec", self.name, "ip", "link", "set", self.there, "up")
        self._ip("netns", "exec", self.name, "ip", "link", "set", "lo", "up")

    def probe(self, xmlrpc_port: int, tcp_port: int) -> list[str]:
        """From the namespace: connect to both ports at ``host_ip`` and call ``getPid``."""
        ports = (self.host_ip, str(xmlrpc_port), str(tcp_port))
        out = subprocess.run(
            [*("ip", "netns", "exec", self.name, sys.executable, "-c", _PROBE), *ports],
            check=True,
            capture_output=True,
            text=True,
            timeout=30,
        )
        return out.stdout.split()

    def delete(self) -> None:
        if self.made:
            subprocess.run(["ip", "netns", "del", self.name], check=False, capture_output=True)
        subprocess.run(["ip", "link", "del", self.here], check=False, capture_output=True)


@pytest.fixture
def netns() -> Iterator[_NetNs]:
    if shutil.which("ip") is None or os.geteuid() != 0:
        pytest.skip("network namespaces need root and iproute2's `ip`")
    ns = _NetNs()
    try:
        ns.create()
    except (subprocess.CalledProcessError, OSError) as exc:
        ns.delete()
        pytest.skip(f"cannot make a network namespace here: {exc}")
    yield ns
    ns.delete()


@pytest.fixture
def master() -> Iterator[Ros1Master]:
    m = Ros1Master(0)
    m.start()
    yield m
    m.close()


def _ports(node: Ros1Node) -> tuple[int, int]:
    return int(node._xmlrpc.server_address[1]), node.tcp_port


def test_addresses_by_environment() -> None:
    local = "http://localhost:11311/"
    assert node_addresses(local, {}) == ("127.0.0.1", "127.0.0.1")
    assert node_addresses("http://127.0.0.1:5/", {}) == ("127.0.0.1", "127.0.0.1")
    assert node_addresses(local, {"ROS_IP": "10.1.2.3"}) == ("10.1.2.3", "10.1.2.3")
    assert node_addresses(local, {"ROS_HOSTNAME": "localhost", "ROS_IP": "10.1.2.3"}) == (
        "localhost",
        "127.0.0.1",
    )
    # a master elsewhere: this machine's address on the route to it (no traffic: UDP connect)
    host, bind = node_addresses("http://192.0.2.77:11311/", {})
    assert host == bind
    assert not bind.startswith("127.")
    assert bind_address("10.0.0.2") == "10.0.0.2"
    with pytest.raises(BridgeError, match=r"ROS_HOSTNAME='no-such-host\.invalid' does not resolve"):
        node_addresses(local, {"ROS_HOSTNAME": "no-such-host.invalid"})


def test_default_binds_loopback_only(master: Ros1Master) -> None:
    node = open_ros1_node("bind_default", master_uri=master.uri, env={})
    try:
        assert node.uri.startswith("http://127.0.0.1:")
        assert node._xmlrpc.socket.getsockname()[0] == "127.0.0.1"
        assert node._tcp.getsockname()[0] == "127.0.0.1"
    finally:
        node.close()


def test_a_loopback_address_other_than_127_0_0_1_is_reached(master: Ros1Master) -> None:
    """Debian's /etc/hosts gives the host name 127.0.1.1: peers told it must reach it."""
    node = open_ros1_node("bind_lo2", master_uri=master.uri, env={"ROS_IP": "127.0.1.1"})
    try:
        assert node._tcp.getsockname()[0] == "127.0.1.1"
        socket.create_connection(("127.0.1.1", node.tcp_port), timeout=2).close()
    finally:
        node.close()


def test_address_not_of_this_machine_is_one_clear_error(master: Ros1Master) -> None:
    with pytest.raises(BridgeError, match=r"cannot listen on 192\.0\.2\.250 .*ROS_IP"):
        open_ros1_node("bind_bad", master_uri=master.uri, env={"ROS_IP": "192.0.2.250"})


def test_reachable_from_another_namespace_only_when_asked(
    master: Ros1Master, netns: _NetNs
) -> None:
    default = open_ros1_node("bind_default", master_uri=master.uri, env={})
    try:
        probe = netns.probe(*_ports(default))
        assert probe[0] == "ConnectionRefusedError", probe  # the slave API
        assert probe[1] == "ConnectionRefusedError", probe  # TCPROS
        assert not probe[2].isdigit(), probe  # getPid (and so shutdown) unreachable
    finally:
        default.close()
    asked = open_ros1_node("bind_asked", master_uri=master.uri, env={"ROS_IP": netns.host_ip})
    try:
        assert asked.uri == f"http://{netns.host_ip}:{_ports(asked)[0]}/"
        assert asked._tcp.getsockname()[0] == netns.host_ip
        probe = netns.probe(*_ports(asked))
        assert probe == ["open", "open", str(os.getpid())], probe
        # and only there: not on loopback
        with pytest.raises(ConnectionRefusedError):
            socket.create_connection(("127.0.0.1", asked.tcp_port), timeout=2).close()
    finally:
        asked.close()


def test_probe_script_is_python(tmp_path: Path) -> None:
    """The probe runs as written (so a failure above is the network's, not the script's)."""
    with socket.create_server(("127.0.0.1", 0)) as srv:
        port = srv.getsockname()[1]
        out = subprocess.run(
            [sys.executable, "-c", _PROBE, "127.0.0.1", str(port), str(port)],
            capture_output=True,
            text=True,
            timeout=30,
            check=True,
            cwd=tmp_path,
        )
    assert out.stdout.split()[:2] == ["open", "open"]
