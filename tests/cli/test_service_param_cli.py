"""``visnav service`` and ``visnav param`` against a live server process (ros2's output shapes)."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from visnav.cli.param import ParamFileError, flatten_parameter_file
from visnav.cli.service import ros_repr
from visnav.msgs.srv import get_service_type

SCRIPTS = Path(__file__).parents[1] / "graph" / "scripts"


def _cli(domain: int, *args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


@pytest.fixture
def server(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "service_server.py", "120")


def test_ros_repr_is_rclpy_shaped() -> None:
    set_bool = get_service_type("std_srvs/srv/SetBool")
    assert ros_repr(set_bool.Request(data=True)) == "std_srvs.srv.SetBool_Request(data=True)"
    assert ros_repr(get_service_type("std_srvs/srv/Empty").Request()) == (
        "std_srvs.srv.Empty_Request()"
    )


def test_service_list_type_find_call(server: subprocess.Popen[str], domain: int) -> None:
    listed = _cli(domain, "service", "list", "-t")
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    assert "/srv/set_bool [std_srvs/srv/SetBool]" in lines
    assert "/srv/server/get_parameters [rcl_interfaces/srv/GetParameters]" in lines
    assert _cli(domain, "service", "type", "/srv/get_map").stdout == "nav_msgs/srv/GetMap\n"
    found = _cli(domain, "service", "find", "std_srvs/srv/Trigger").stdout.split()
    assert found == ["/srv/boom", "/srv/slow", "/srv/trigger"]
    call = _cli(domain, "service", "call", "/srv/set_bool", "std_srvs/srv/SetBool", "{data: true}")
    assert call.returncode == 0, call.stderr
    assert "requester: making request: std_srvs.srv.SetBool_Request(data=True)\n" in call.stdout
    assert call.stdout.endswith(
        "response:\nstd_srvs.srv.SetBool_Response(success=True, message='on')\n\n"
    )
    info = _cli(domain, "node", "info", "/srv/server")
    assert "  Service Servers:\n" in info.stdout
    assert "    /srv/set_bool: std_srvs/srv/SetBool\n" in info.stdout


def test_service_bad_input_is_one_error_line(server: subprocess.Popen[str], domain: int) -> None:
    cases = [
        (("/srv/set_bool", "std_srvs/srv/SetBool", "{dat: true}"), "has no field 'dat'"),
        (("/srv/set_bool", "std_srvs/srv/SetBol", "{}"), "did you mean std_srvs/srv/SetBool"),
        (("/srv/set_bool", "std_srvs/srv/SetBool", "[1, 2]"), "expected a YAML mapping"),
        (("/srv/set_bool", "std_srvs/srv/SetBool", "{data: [}"), "request '{data: [}'"),
        (("/srv/boom", "std_srvs/srv/Trigger"), "ValueError: the arm is not homed"),
    ]
    for args, expected in cases:
        out = _cli(domain, "service", "call", *args)
        assert out.returncode == 1, (args, out.stdout)
        errors = [line for line in out.stderr.splitlines() if line.startswith("error: ")]
        assert len(errors) == 1, (args, out.stderr)
        assert expected in errors[0], (args, out.stderr)
    missing = _cli(domain, "service", "type", "/srv/set_boo")
    assert missing.returncode == 1
    assert "did you mean /srv/set_bool" in missing.stderr
    gone = _cli(domain, "service", "call", "/nope", "std_srvs/srv/Trigger", "--timeout", "1")
    assert gone.returncode == 1
    assert "did not appear within 1 s" in gone.stderr


def test_param_verbs(server: subprocess.Popen[str], domain: int, tmp_path: Path) -> None:
    listed = _cli(domain, "param", "list")
    assert listed.returncode == 0, listed.stderr
    assert "/srv/server:\n  gain\n  mode\n  use_sim_time\n" in listed.stdout
    assert _cli(domain, "param", "get", "/srv/server", "gain").stdout == "Double value is: 1.0\n"
    ok = _cli(domain, "param", "set", "/srv/server", "gain", "2")
    assert (ok.returncode, ok.stdout) == (0, "Set parameter successful\n")
    assert _cli(domain, "param", "get", "/srv/server", "gain").stdout == "Double value is: 2.0\n"
    refused = _cli(domain, "param", "set", "/srv/server", "gain", "50")
    assert refused.returncode == 1
    assert refused.stdout.startswith("Set parameter failed: parameter 'gain' is 50")
    described = _cli(domain, "param", "describe", "/srv/server", "gain", "mode").stdout
    assert "Parameter name: gain\n  Type: double\n  Description: a gain\n" in described
    assert "    Min value: 0.0\n    Max value: 10.0\n" in described
    assert "Parameter name: mode\n" in described
    assert "    Read only: true\n" in described
    dumped = _cli(domain, "param", "dump", "/srv/server").stdout
    assert dumped.startswith("/srv/server:\n  ros__parameters:\n")
    assert "    gain: 2.0\n" in dumped
    path = tmp_path / "params.yaml"
    path.write_text(
        "/**:\n  ros__parameters:\n    gain: 3.5\n"
        "/srv/server:\n  ros__parameters:\n    mode: slow\n"
    )
    loaded = _cli(domain, "param", "load", "/srv/server", str(path))
    assert "Set parameter gain successful\n" in loaded.stdout
    assert "Set parameter mode failed: parameter 'mode' is read-only\n" in loaded.stdout
    assert loaded.returncode == 1
    assert _cli(domain, "param", "get", "/srv/server", "gain").stdout == "Double value is: 3.5\n"
    bad_node = _cli(domain, "param", "get", "/srv/servr", "gain")
    assert bad_node.returncode == 1
    assert "did you mean /srv/server" in bad_node.stderr


def test_parameter_file_layout_errors() -> None:
    assert flatten_parameter_file(
        {"/**": {"ros__parameters": {"a": {"b": 1}}}, "n": {"ros__parameters": {"c": 2}}},
        "/n",
        source="f.yaml",
    ) == {"a.b": 1, "c": 2}
    with pytest.raises(ParamFileError, match="no section for node '/x'"):
        flatten_parameter_file({"/y": {"ros__parameters": {}}}, "x", source="f.yaml")
    with pytest.raises(ParamFileError, match="has no 'ros__parameters'"):
        flatten_parameter_file({"/x": {"a": 1}}, "x", source="f.yaml")
