"""The viewer in a process of its own (``visnav run --view``): ports, pacing, its life."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.viz.errors import VizError
from visnav.viz.paced_feed import MAX_PAUSE_S, MIN_PAUSE_S, pause_s
from visnav.viz.ports import LOOPBACK, check_ports, free_port
from visnav.viz.view_process import ViewPorts, parse_ready

from .conftest import Rrd, header, tf_msg, tf_stamped


def test_a_shown_message_pauses_for_the_display_period() -> None:
    assert pause_s(0.2, kept=True, since_kept_s=None, rate=None) == pytest.approx(0.2)
    # a run at half real time: 0.4 wall s, as many messages per simulated second
    assert pause_s(0.2, kept=True, since_kept_s=0.2, rate=0.5) == pytest.approx(0.4)
    # a run at 4x real time: still 0.2 wall s, no more than the display rate per wall second
    assert pause_s(0.2, kept=True, since_kept_s=0.2, rate=4.0) == pytest.approx(0.2)
    # early (0.15 s of stamp after the last shown): the rest of the period
    assert pause_s(0.2, kept=False, since_kept_s=0.15, rate=1.0) == pytest.approx(0.05)
    # due but not taken (the viewer's queue is full): a whole period
    assert pause_s(0.2, kept=False, since_kept_s=0.3, rate=1.0) == pytest.approx(0.2)
    assert pause_s(0.0, kept=True, since_kept_s=None, rate=None) == 0.0  # shown in full
    assert pause_s(1.0, kept=True, since_kept_s=1.0, rate=0.01) == MAX_PAUSE_S


@given(
    period=st.one_of(st.floats(-1.0, 5.0), st.just(float("nan"))),
    kept=st.booleans(),
    since=st.one_of(st.none(), st.floats(-10.0, 10.0)),
    rate=st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True)),
)
def test_a_pause_is_bounded(
    period: float, kept: bool, since: float | None, rate: float | None
) -> None:
    wait = pause_s(period, kept=kept, since_kept_s=since, rate=rate)
    assert wait == 0.0 or MIN_PAUSE_S <= wait <= MAX_PAUSE_S


def test_a_taken_port_is_refused_naming_it_and_its_option() -> None:
    with socket.socket() as taken:
        taken.bind((LOOPBACK, 0))
        taken.listen()
        port = taken.getsockname()[1]
        page = rf"web viewer port 127\.0\.0\.1:{port} is in use.*give --port N"
        with pytest.raises(VizError, match=page):
            ViewPorts(port=port, grpc_port=0).check()
        grpc = rf"gRPC port 127\.0\.0\.1:{port} is in use.*give --grpc-port N"
        with pytest.raises(VizError, match=grpc):
            ViewPorts(port=0, grpc_port=port).check()
        node = r"is in use.*set /rviz's parameter port to another"
        with pytest.raises(VizError, match=node):
            check_ports(port, 0, port_option="port", grpc_option="grpc_port", node="/rviz")
    free = free_port()
    with pytest.raises(VizError, match="--port and --grpc-port are both"):
        check_ports(free, free)
    with pytest.raises(VizError, match="--port is 70000: expected a TCP port"):
        check_ports(70000, 0)
    check_ports(0, 0)  # free ones: nothing to check


@given(line=st.binary(max_size=300))
def test_any_start_up_line_is_a_url_or_a_viz_error(line: bytes) -> None:
    try:
        url, grpc = parse_ready(line)
    except VizError:
        return
    assert isinstance(url, str)
    assert grpc is None or isinstance(grpc, str)


@given(
    fields=st.dictionaries(
        st.sampled_from(["url", "grpc_url", "error", "pid"]),
        st.one_of(st.none(), st.integers(), st.text(max_size=20), st.lists(st.integers())),
    )
)
def test_any_start_up_object_is_a_url_or_a_viz_error(fields: dict[str, Any]) -> None:
    line = json.dumps(fields).encode()
    if isinstance(fields.get("error"), str) or not isinstance(fields.get("url"), str):
        with pytest.raises(VizError):
            parse_ready(line)
        return
    assert parse_ready(line)[0] == fields["url"]


def test_the_reason_of_a_child_that_could_not_serve_is_the_error() -> None:
    with pytest.raises(VizError, match=r"port 127\.0\.0\.1:9090 is in use"):
        parse_ready(b'{"error": "the web viewer port 127.0.0.1:9090 is in use"}\n')
    with pytest.raises(VizError, match="did not start"):
        parse_ready(b"")


@given(port=st.one_of(st.integers(-(2**40), 2**40), st.booleans(), st.none(), st.text(max_size=5)))
def test_any_port_value_is_accepted_or_a_viz_error(port: Any) -> None:
    with contextlib.suppress(VizError):
        check_ports(port, 0)


def test_a_log_that_cannot_be_written_is_a_viz_error(tmp_path: Path) -> None:
    from visnav.viz.view_process import ViewProcess

    with pytest.raises(VizError, match=r"viewer process could not start.*missing"):
        ViewProcess(1, tmp_path / "missing" / "viewer.log", ports=ViewPorts(0, 0))


def test_a_viewer_node_on_a_taken_port_names_itself_and_the_parameter() -> None:
    """A launch file's viewer node (``rviz``): the parameter to change, not a CLI flag."""
    pytest.importorskip("rerun")
    from visnav.graph import Context
    from visnav.node_registry import resolve_node_class

    cls = resolve_node_class("viz")
    with socket.socket() as taken, Context(transport="local") as ctx:
        taken.bind((LOOPBACK, 0))
        taken.listen()
        port = taken.getsockname()[1]
        text = rf"127\.0\.0\.1:{port} is in use.*set /rviz's parameter grpc_port to another port"
        with pytest.raises(VizError, match=text):
            cls("rviz", context=ctx, parameter_overrides={"port": 0, "grpc_port": port})


def _scan(t_ns: int) -> Any:
    from visnav.msgs import LaserScan

    ranges = np.full(36, 2.0, np.float32)
    return LaserScan(
        header=header("laser", t_ns), angle_min=-3.14, angle_max=3.14, angle_increment=0.1745,
        time_increment=0.0, scan_time=0.1, range_min=0.1, range_max=10.0, ranges=ranges,
        intensities=np.zeros(0, np.float32),
    )  # fmt: skip


@pytest.mark.slow  # the Rerun SDK's import and a recording: seconds on a loaded machine
def test_a_paced_feed_pauses_a_display_rated_topic_until_its_next_message_is_due(
    tmp_path: Path,
) -> None:
    pytest.importorskip("rerun")
    from visnav.graph import Context, Node, QoSProfile
    from visnav.graph.qos import DurabilityPolicy
    from visnav.msgs import LaserScan, String, TFMessage
    from visnav.viz import RerunSink, open_viewer
    from visnav.viz.display_sink import DisplaySink
    from visnav.viz.paced_feed import PacedFeed

    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    with Context(transport="local") as ctx, open_viewer(save=tmp_path / "v.rrd") as viewer:
        node = Node("robot", context=ctx)
        scans = node.create_publisher(LaserScan, "/scan", 10)
        node.create_publisher(String, "/robot_description", latched)
        node.create_publisher(TFMessage, "/tf", 100)
        sink = DisplaySink(RerunSink(viewer.recording))
        feed = PacedFeed(sink, ctx)
        feed.sink = sink
        try:
            feed.scan()
            assert feed.paced_topics == ["/scan"]  # TF, latched strings: every message
            assert {"/tf", "/tf_static", "/robot_description"} <= set(feed.topics)
            scans.publish(_scan(1_000_000_000))
            feed.spin_once(0.2)
            sub = feed._paced["/scan"]
            assert sub.paused  # 10 Hz display rate: paused ~0.1 s
            assert feed.pauses == 1
            assert 0.0 < feed.resume_due() <= 0.1 + 1e-6
            time.sleep(0.12)
            feed.resume_due()
            assert not sub.paused
        finally:
            feed.close()
            sink.close()


def _image(t_ns: int) -> Any:
    from visnav.msgs.image import numpy_to_image

    pixels = np.full((48, 64, 3), (t_ns // 10_000_000) % 255, np.uint8)
    return numpy_to_image(pixels, "rgb8", header=header("camera", t_ns))


@pytest.mark.slow
def test_the_viewer_process_shows_a_remote_graph_and_paces_it(tmp_path: Path, domain: int) -> None:
    """A 30 Hz camera and 50 Hz TF for 4 s: the child shows ~5 images a second, and the
    publisher skips serializing most of the rest (the paced subscription is paused)."""
    pytest.importorskip("rerun")
    from visnav.graph import Context, Node
    from visnav.msgs import Image, TFMessage
    from visnav.viz.view_process import ViewProcess

    rrd, log = tmp_path / "view.rrd", tmp_path / "viewer.log"
    with Context(domain) as ctx:
        node = Node("camera", context=ctx)
        pub = node.create_publisher(Image, "/camera/image_raw", 5)
        tf = node.create_publisher(TFMessage, "/tf", 100)
        node.create_subscription(Image, "/camera/image_raw", lambda m: None, 5)  # in use
        view = ViewProcess(domain, log, ports=ViewPorts(0, 0), save=rrd)
        try:
            assert view.url is not None
            assert view.url.startswith("http://127.0.0.1:")
            published = 0
            t0 = time.monotonic()
            t_ns = 1_000_000_000
            while time.monotonic() - t0 < 4.0 or published < 90:
                tf.publish(tf_msg(tf_stamped("map", "camera", t_ns, (t_ns / 1e10, 0.0, 0.0))))
                if published * 33_333_333 <= t_ns - 1_000_000_000:
                    pub.publish(_image(t_ns))
                    published += 1
                ctx.spin_once(0.0)
                time.sleep(0.02)
                t_ns += 20_000_000
            skipped = pub._zpub.skipped
        finally:
            code = view.close()
    assert code == 0, log.read_text()[-3000:]
    assert not view.alive()
    shown = len(Rrd(rrd).rows("world/cameras/camera/image_raw", "EncodedImage:blob"))
    print(f"published {published}, shown {shown}, skipped by the publisher {skipped}")
    assert 3 <= shown <= published // 2, (shown, published)
    assert skipped > published // 3, (skipped, published)
    assert "peak RSS of the viewer process" in log.read_text()
    port = int(view.url.split(":")[2].split("/")[0])
    check_ports(port, 0)  # free again


_PARENT = textwrap.dedent(
    """
    import sys, time
    from visnav.viz.view_process import ViewPorts, ViewProcess
    view = ViewProcess(int(sys.argv[1]), sys.argv[2], ports=ViewPorts(0, 0))
    print(view.pid, view.url.split(":")[2].split("/")[0], flush=True)
    time.sleep(600)
    """
)


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    status = Path(f"/proc/{pid}/stat")
    return status.exists() and status.read_text().split(")")[1].split()[0] == "Z"


@pytest.mark.slow
def test_a_killed_run_leaves_no_viewer_and_no_port(tmp_path: Path, domain: int) -> None:
    pytest.importorskip("rerun")
    parent = subprocess.Popen(
        [sys.executable, "-c", _PARENT, str(domain), str(tmp_path / "viewer.log")],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert parent.stdout is not None
        line = parent.stdout.readline().split()
        assert len(line) == 2, (tmp_path / "viewer.log").read_text()[-2000:]
        child, port = int(line[0]), int(line[1])
        assert not _gone(child)
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 30
        while not _gone(child) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert _gone(child)
        deadline = time.monotonic() + 15
        while True:  # the web viewer's server went with it
            try:
                check_ports(port, 0)
                break
            except VizError:
                assert time.monotonic() < deadline, f"port {port} still bound"
                time.sleep(0.2)
    finally:
        parent.kill()
        parent.wait()
