"""VISNAV_LISTEN / VISNAV_CONNECT: a locator Zenoh would take silently but never use is refused."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.graph import Context
from visnav.graph.errors import TransportError
from visnav.graph.transport import ENV_CONNECT, ENV_LISTEN, TransportConfig


@pytest.mark.parametrize("var", [ENV_LISTEN, ENV_CONNECT])
@pytest.mark.parametrize(
    ("value", "match"),
    [
        ("tcp/127.0.0.1:notaport", r"port 'notaport' is not a number from [01] to 65535"),
        ("tcp/127.0.0.1:99999", r"port '99999' is not a number"),
        ("tcp/127.0.0.1", "it has no port"),
        ("tcp/127.0.0.1:", "port '' is not a number"),
        ("tcp/:7447", "it has no host"),
        ("tcp/[::1]", "it has no port"),
        ("udp/10.0.0.1:-1", "port '-1'"),
        ("127.0.0.1:7447", "expected a Zenoh locator PROTOCOL/ADDRESS"),
        ("tcp/", "expected a Zenoh locator"),
        ("tcp/1.2.3.4:7447,tcp/x", "'tcp/x': it has no port"),
    ],
)
def test_bad_endpoints_are_refused_naming_variable_value_and_form(
    var: str, value: str, match: str
) -> None:
    with pytest.raises(TransportError, match=match) as info:
        TransportConfig.from_env(5, {var: value})
    text = str(info.value)
    assert text.startswith(f"{var}=")
    assert f"for example {var}=tcp/" in text
    assert "\n" not in text


def test_connect_refuses_port_zero_listen_takes_it() -> None:
    assert TransportConfig.from_env(5, {ENV_LISTEN: "tcp/0.0.0.0:0"}).listen == ("tcp/0.0.0.0:0",)
    with pytest.raises(TransportError, match="port '0' is not a number from 1 to 65535"):
        TransportConfig.from_env(5, {ENV_CONNECT: "tcp/10.0.0.2:0"})


@pytest.mark.parametrize(
    "value",
    [
        "tcp/0.0.0.0:7447",
        "tcp/[::1]:7447",
        "udp/192.168.1.5:7447",
        "tcp/robot.local:7447#iface=eth0",
        "unixsock-stream//tmp/visnav.sock",
        " tcp/10.0.0.1:1 , tcp/10.0.0.2:65535 ",
    ],
)
def test_good_endpoints_are_kept(value: str) -> None:
    config = TransportConfig.from_env(5, {ENV_LISTEN: value, ENV_CONNECT: value})
    assert config.listen == config.connect == tuple(v.strip() for v in value.split(","))


@settings(max_examples=300, deadline=None)
@given(value=st.text(max_size=40), var=st.sampled_from([ENV_LISTEN, ENV_CONNECT]))
def test_fuzzed_endpoints_raise_only_transport_errors(value: str, var: str) -> None:
    error = None
    try:
        TransportConfig.from_env(5, {var: value})
    except TransportError as exc:
        error = str(exc)
    assert error is None or error.startswith(f"{var}=")


def test_a_context_refuses_a_bad_listen_variable() -> None:
    with pytest.raises(TransportError, match=r"VISNAV_LISTEN='tcp/127\.0\.0\.1:notaport'"):
        Context(5, env={ENV_LISTEN: "tcp/127.0.0.1:notaport"})


def test_the_cli_prints_one_line(domain: int) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain), ENV_LISTEN: "tcp/127.0.0.1:99999"}
    result = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "topic", "list"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: VISNAV_LISTEN='tcp/127.0.0.1:99999': port '99999'")
