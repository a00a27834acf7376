"""open_viewer: .rrd files, the web viewer bound to 127.0.0.1 only, and a missing Rerun SDK."""

from __future__ import annotations

import importlib
import sys
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from visnav.cli.main import main
from visnav.viz.errors import RERUN_MISSING_TEXT, RerunMissingError, VizError


def _listening(pid: int) -> set[tuple[str, int]]:
    import psutil

    return {
        (c.laddr.ip, c.laddr.port)
        for c in psutil.Process(pid).net_connections(kind="inet")
        if c.status == psutil.CONN_LISTEN
    }


def test_web_viewer_and_grpc_server_listen_on_loopback_only(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    pytest.importorskip("psutil")
    import os

    from visnav.viz import open_viewer

    with open_viewer(web=True, port=0, grpc_port=0, save=tmp_path / "x.rrd") as viewer:
        assert viewer.url is not None
        assert viewer.url.startswith("http://127.0.0.1:")
        assert viewer.grpc_url is not None
        assert viewer.web_process is not None
        web_port = int(viewer.url.split(":")[2].split("/")[0])
        grpc_port = int(viewer.grpc_url.split(":")[2].split("/")[0])
        web = _listening(viewer.web_process.pid)
        ours = _listening(os.getpid())
        assert ("127.0.0.1", web_port) in web
        assert ("127.0.0.1", grpc_port) in web  # the rerun process serves both
        assert not ours  # this process listens on nothing
        for ip, _ in web:
            assert ip == "127.0.0.1", f"bound to {ip}"
        with urllib.request.urlopen(viewer.url, timeout=10) as resp:
            page = resp.read().decode(errors="replace")
        assert "<html" in page.lower()
        assert "wasm" in page.lower() or "rerun" in page.lower()
    assert viewer.web_process.poll() is not None  # stopped on close
    assert (tmp_path / "x.rrd").stat().st_size > 0


def test_save_path_is_checked(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from visnav.viz import open_viewer

    with pytest.raises(VizError, match=r"must end in \.rrd"):
        open_viewer(save=tmp_path / "x.mcap")
    with pytest.raises(VizError, match="does not exist"):
        open_viewer(save=tmp_path / "nope" / "x.rrd")


def test_native_viewer_without_display_says_what_to_do(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("rerun")
    from visnav.viz import open_viewer

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if not sys.platform.startswith("linux"):
        pytest.skip("display detection is Linux-only")
    with pytest.raises(VizError, match="use --web"):
        open_viewer()


@pytest.fixture
def no_rerun(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make ``import rerun`` fail, and forget the viewer modules that imported it."""
    monkeypatch.setitem(sys.modules, "rerun", None)
    for name in [
        m for m in sys.modules if m.startswith("visnav.viz.") and m != "visnav.viz.errors"
    ]:
        monkeypatch.delitem(sys.modules, name)


def test_missing_rerun_gives_one_clear_error(no_rerun: None) -> None:
    viz = importlib.import_module("visnav.viz")
    with pytest.raises(RerunMissingError, match=r"pip install 'visnav\[viz\]'"):
        viz.RerunSink  # noqa: B018
    # The parts that need no Rerun still work.
    from visnav.viz.display import image_to_display

    assert image_to_display(__import__("numpy").zeros((2, 2), "uint8"), "mono8").shape == (2, 2, 3)


def test_missing_rerun_cli_message(no_rerun: None, tmp_path: Path, capsys: Any) -> None:
    code = main(["view", "--save", str(tmp_path / "x.rrd"), "--duration", "0"])
    assert code == 1
    err = capsys.readouterr().err
    assert err.startswith("error: " + RERUN_MISSING_TEXT)
    assert err.count("\n") == 1  # one line, no traceback


def test_fixed_ports_a_busy_port_is_named_and_rerun_logs_go_to_a_file(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    import socket

    from visnav.viz import VizError, open_viewer
    from visnav.viz.viewer import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT

    assert (DEFAULT_WEB_PORT, DEFAULT_GRPC_PORT) == (9090, 9876)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(VizError, match=f"127.0.0.1:{port} is in use.*--port N"):
            open_viewer(web=True, port=port, grpc_port=0)
        with pytest.raises(VizError, match="--grpc-port N"):
            open_viewer(web=True, port=0, grpc_port=port)
    log = tmp_path / "viewer.log"
    with open_viewer(web=True, port=0, grpc_port=0, log_path=log) as viewer:
        assert viewer.log_path == log
        assert viewer.save is None
    assert "Listening for gRPC connections" in log.read_text(errors="replace")
    assert list(tmp_path.iterdir()) == [log]  # nothing else written
