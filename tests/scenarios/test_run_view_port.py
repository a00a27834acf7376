"""``visnav run --view --port/--grpc-port``: a taken port refused up front, the viewer's process."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from visnav.viz.errors import VizError
from visnav.viz.ports import LOOPBACK, check_ports


def _visnav(
    *args: str, cwd: Path, domain: int, timeout: float = 600
) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


@pytest.mark.parametrize("option", ["--port", "--grpc-port"])
def test_a_taken_port_refuses_the_run_before_it_starts(
    option: str, tmp_path: Path, domain: int
) -> None:
    pytest.importorskip("rerun")
    out = tmp_path / "run"
    with socket.socket() as taken:
        taken.bind((LOOPBACK, 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = _visnav(
            "run",
            "car",
            "--view",
            option,
            str(port),
            "--out",
            str(out),
            cwd=tmp_path,
            domain=domain,
        )
    assert done.returncode == 1, done.stderr
    assert f"127.0.0.1:{port} is in use" in done.stderr
    assert f"give {option} N" in done.stderr
    assert "Traceback" not in done.stderr
    assert not out.exists()  # refused before anything: no run folder left behind
    assert "summary" not in done.stdout


def test_a_port_without_view_is_refused(tmp_path: Path, domain: int) -> None:
    done = _visnav(
        "run", "car", "--port", "9100", "--out", str(tmp_path / "r"), cwd=tmp_path, domain=domain
    )
    assert done.returncode == 1
    assert "--port sets the viewer's port: add --view" in done.stderr
    assert not (tmp_path / "r").exists()


@pytest.mark.slow
def test_run_view_serves_from_its_own_process_and_frees_its_ports(
    tmp_path: Path, domain: int
) -> None:
    """A short car run with ``--view`` on free ports: the page's address on stderr, the
    viewer's log in the run folder (nothing of Rerun's on the terminal), no .rrd, and
    both ports free again once the run has ended."""
    pytest.importorskip("rerun")
    out = tmp_path / "run"
    done = _visnav(
        "run", "car", "--view", "--port", "0", "--grpc-port", "0", "--no-slam", "--duration", "2",
        "--out", str(out), "--quiet", cwd=tmp_path, domain=domain,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    found = re.search(
        r"viewer: http://127\.0\.0\.1:(\d+)/\?url=rerun%2Bhttp%3A%2F%2F127\.0\.0\.1%3A(\d+)",
        done.stderr,
    )
    assert found, done.stderr
    page, grpc = int(found.group(1)), int(found.group(2))
    log = (out / "viewer.log").read_text()
    assert "peak RSS of the viewer process" in log
    assert "viewer: subscribed to /scan" in log  # the run's topics, over Zenoh
    assert not list(out.glob("*.rrd"))
    assert "rerun" not in done.stderr.lower().replace("rerun%2bhttp", "")
    try:
        check_ports(page, grpc)
    except VizError as exc:  # pragma: no cover - the failure's message
        pytest.fail(f"a port is still bound after the run: {exc}")


def _viewer_processes(domain: int) -> list[int]:
    """Viewer processes of ``domain`` still alive (not zombies), from /proc."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().split(b"\0")
            state = (entry / "stat").read_text().split(")")[1].split()[0]
        except OSError:
            continue
        if b"visnav.viz.view_process" in cmd and str(domain).encode() in cmd and state != "Z":
            found.append(int(entry.name))
    return found


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_stopped_run_stops_its_viewer(signum: int, tmp_path: Path, domain: int) -> None:
    """Ctrl-C (SIGINT to the terminal's process group) or SIGTERM during a ``--view`` run:
    the run ends interrupted, its viewer process with it, and no port stays bound."""
    pytest.importorskip("rerun")
    out = tmp_path / "run"
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    cmd = [sys.executable, "-m", "visnav.cli.main", "run", "car", "--view", "--port", "0"]
    cmd += ["--grpc-port", "0", "--no-slam", "--duration", "60", "--out", str(out), "--quiet"]
    proc = subprocess.Popen(
        cmd, cwd=tmp_path, env=env, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
        start_new_session=True,  # its own group, as a terminal's foreground job
    )  # fmt: skip
    try:
        assert proc.stderr is not None
        url = ""
        for line in proc.stderr:
            if line.startswith("viewer: http"):
                url = line
                break
        assert url, "no viewer address"
        assert _viewer_processes(domain)
        time.sleep(3.0)  # the simulation runs
        if signum == signal.SIGINT:
            os.killpg(proc.pid, signum)  # what a terminal's Ctrl-C does
        else:
            proc.send_signal(signum)
        rest = proc.communicate(timeout=300)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 128 + signum, rest[-2000:]
    assert not _viewer_processes(domain)
    found = re.search(r"127\.0\.0\.1:(\d+)/\?url=rerun%2Bhttp%3A%2F%2F127\.0\.0\.1%3A(\d+)", url)
    assert found
    check_ports(int(found.group(1)), int(found.group(2)))  # raises if still bound
    assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
