"""usb_cam / cv_camera on a video file written by OpenCV: images, camera_info, rectification."""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.graph import Context, Node, Parameter
from visnav.msgs import CameraInfo, CompressedImage, Image, image_to_numpy
from visnav.msgs.time import time_to_ns
from visnav.perception import camera_driver
from visnav.perception.camera_driver import (
    CameraDriverError,
    CaptureSource,
    VideoSource,
    device_formats,
    load_camera_info,
    parse_source,
)
from visnav.perception.camera_driver_node import CvCameraNode, UsbCamNode
from visnav.perception.camera_info_yaml import camera_info_from_matrices, write_camera_info_yaml
from visnav.perception.errors import PerceptionError
from visnav.perception.image_transport import decompress
from visnav.perception.nodes import ImageProcNode

W, H, FRAMES = 96, 64, 12
K = [80.0, 0.0, 47.5, 0.0, 80.0, 31.5, 0.0, 0.0, 1.0]
D = [-0.3, 0.1, 0.0, 0.0, 0.0]


def _frame(i: int) -> np.ndarray:
    """Grey grid with a blue (BGR) block that moves one column per frame."""
    img = np.full((H, W, 3), 90, np.uint8)
    img[::8, :] = 200
    img[:, ::8] = 200
    img[20:40, 10 + 4 * i : 26 + 4 * i] = (255, 0, 0)
    return img


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("video") / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 20.0, (W, H))
    assert writer.isOpened()
    for i in range(FRAMES):
        writer.write(_frame(i))
    writer.release()
    return path


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = np.array([*K[:3], 0.0, *K[3:6], 0.0, *K[6:], 0.0])
    info = camera_info_from_matrices((W, H), "plumb_bob", np.array(D), np.array(K), np.eye(3), p)
    return write_camera_info_yaml(tmp_path_factory.mktemp("cal") / "cam.yaml", info)


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def _collect(ctx: Context, ns: str, topics: dict[str, type]) -> dict[str, list[Any]]:
    probe = Node("probe", context=ctx)
    got: dict[str, list[Any]] = {t: [] for t in topics}
    for topic, msg_type in topics.items():
        probe.create_subscription(msg_type, f"{ns}/{topic}", got[topic].append, 50)
    return got


def _run(ctx: Context, node: Any, timeout_s: float = 20.0) -> None:
    assert ctx.spin_until(lambda: node.finished, timeout_s=timeout_s)
    ctx.spin_some()


def test_parse_source() -> None:
    assert parse_source(0) == CaptureSource("device", "/dev/video0")
    assert parse_source("3") == CaptureSource("device", "/dev/video3")
    assert parse_source("/dev/v4l/by-id/usb-cam") == CaptureSource(
        "device", "/dev/v4l/by-id/usb-cam"
    )
    assert parse_source("file:///tmp/a.avi") == CaptureSource("file", "/tmp/a.avi")
    assert parse_source("rtsp://10.0.0.2:8554/cam") == CaptureSource(
        "url", "rtsp://10.0.0.2:8554/cam"
    )
    assert parse_source("clip.mp4").kind == "file"
    with pytest.raises(CameraDriverError, match="negative"):
        parse_source(-1)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.text(max_size=40), st.integers(-(2**40), 2**40)))
def test_parse_source_fuzz(value: str | int) -> None:
    try:
        src = parse_source(value)
    except PerceptionError:
        return
    assert src.kind in ("device", "file", "url")
    assert src.target


def test_missing_device_is_one_line_naming_ls() -> None:
    with pytest.raises(CameraDriverError) as err:
        VideoSource(parse_source("/dev/video97"))
    text = str(err.value)
    assert "/dev/video97 does not exist" in text
    assert "`ls /dev/video*`" in text
    assert "\n" not in text


def test_missing_file_and_undecodable_file(tmp_path: Path) -> None:
    with pytest.raises(CameraDriverError, match=r"video file .*nothing\.avi does not exist"):
        VideoSource(parse_source(str(tmp_path / "nothing.avi")))
    junk = tmp_path / "junk.avi"
    junk.write_bytes(b"not a video" * 10)
    with pytest.raises(CameraDriverError, match="does not open: OpenCV"):
        VideoSource(parse_source(str(junk)))


class _FakeDevice:
    """A capture that opens but keeps YUYV whatever FourCC is asked for."""

    def __init__(self, target: str, api: int) -> None:
        self.props: dict[int, float] = {cv2.CAP_PROP_FOURCC: cv2.VideoWriter.fourcc(*"YUYV")}

    def isOpened(self) -> bool:
        return True

    def set(self, prop: int, value: float) -> bool:
        if prop != cv2.CAP_PROP_FOURCC:
            self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        return self.props.get(prop, 0.0)

    def release(self) -> None:
        pass


def test_refused_pixel_format_names_the_offered_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    dev = tmp_path / "video0"
    dev.touch()
    monkeypatch.setattr(camera_driver, "device_formats", lambda path: ["YUYV", "GREY"])
    with pytest.raises(CameraDriverError) as err:
        VideoSource(CaptureSource("device", str(dev)), pixel_format="mjpeg", capture=_FakeDevice)
    assert "does not offer pixel_format 'mjpeg' (MJPG): it offers yuyv, mono8" in str(err.value)
    # the format it has is accepted
    VideoSource(CaptureSource("device", str(dev)), pixel_format="yuyv", capture=_FakeDevice)


def test_device_formats_of_a_non_device_is_empty(tmp_path: Path) -> None:
    f = tmp_path / "plain"
    f.write_bytes(b"x")
    assert device_formats(str(f)) == []
    assert device_formats("/dev/video97") == []


def test_unknown_pixel_format_and_io_method(ctx: Context, video: Path) -> None:
    with pytest.raises(
        CameraDriverError, match="pixel_format 'yuv420' is unknown: expected one of"
    ):
        UsbCamNode(
            context=ctx, parameter_overrides={"video_device": str(video), "pixel_format": "yuv420"}
        )
    with pytest.raises(CameraDriverError, match="io_method 'dma'"):
        UsbCamNode(
            context=ctx, parameter_overrides={"video_device": str(video), "io_method": "dma"}
        )
    assert ctx.graph.nodes() == [] or all(n.name != "usb_cam" for n in ctx.graph.nodes())


def test_usb_cam_video_file_with_calibration_and_rectification(
    ctx: Context, video: Path, calibration: Path
) -> None:
    got = _collect(
        ctx,
        "/usb_cam",
        {
            "image_raw": Image,
            "camera_info": CameraInfo,
            "image_rect": Image,
            "image_raw/compressed": CompressedImage,
        },
    )
    ImageProcNode(context=ctx, namespace="/usb_cam")  # image_proc on the driver's topics
    start_ns = time.time_ns()
    cam = UsbCamNode(
        context=ctx,
        parameter_overrides={
            "video_device": str(video),
            "framerate": 200,
            "camera_frame_id": "front_optical",
            "camera_info_url": f"file://{calibration}",
            "io_method": "read",
        },
    )
    _run(ctx, cam)
    images, infos, rects = got["image_raw"], got["camera_info"], got["image_rect"]
    assert cam.frames == FRAMES
    assert len(images) == len(infos) == len(rects) == FRAMES
    first = image_to_numpy(images[0])
    assert images[0].encoding == "rgb8"
    assert first.shape == (H, W, 3)
    # the block is blue: BGR (255, 0, 0) in the file is RGB (0, 0, 255) on the topic
    assert first[30, 18, 2] > 200
    assert first[30, 18, 0] < 60

    # frames in order: the block moves 4 px per frame
    def block_start(m: Image) -> int:
        row = image_to_numpy(m)[30].astype(int)
        return int(np.argmax((row[:, 2] > 200) & (row[:, 0] < 100)))

    cols = [block_start(m) for m in images]
    assert cols == [10 + 4 * i for i in range(FRAMES)]
    # camera_info from the calibration YAML, with the image's header
    assert list(infos[0].k) == K
    assert list(infos[0].d) == D
    assert infos[0].distortion_model == "plumb_bob"
    for img, info in zip(images, infos, strict=True):
        assert img.header == info.header
        assert img.header.frame_id == "front_optical"
    stamps = [time_to_ns(m.header.stamp) for m in images]
    assert stamps == sorted(set(stamps))
    assert start_ns <= stamps[0]
    assert stamps[-1] <= time.time_ns()
    # image_proc rectified with D: equals OpenCV's undistortion of the mono image
    mono = cv2.cvtColor(image_to_numpy(images[3]), cv2.COLOR_RGB2GRAY)
    expected = cv2.undistort(mono, np.reshape(K, (3, 3)), np.array(D))
    rect = image_to_numpy(rects[3])
    assert np.mean(np.abs(rect.astype(float) - expected)) < 1.5
    assert np.mean(np.abs(rect.astype(float) - mono)) > 5  # rectification changed it
    # compressed through image_transport (someone subscribed)
    assert len(got["image_raw/compressed"]) == FRAMES
    jpeg = image_to_numpy(decompress(got["image_raw/compressed"][0]))
    assert np.mean(np.abs(jpeg.astype(float) - first)) < 6


def test_a_video_file_plays_at_its_own_frame_rate(ctx: Context, video: Path) -> None:
    # The clip was written at 20 fps: played at 20 Hz, not at framerate's default 30.
    got = _collect(ctx, "/usb_cam", {"image_raw": Image})
    cam = UsbCamNode(context=ctx, parameter_overrides={"video_device": str(video)})
    assert cam.settings.rate == pytest.approx(20.0)
    _run(ctx, cam)
    stamps = [time_to_ns(m.header.stamp) for m in got["image_raw"]]
    assert len(stamps) == FRAMES
    period_s = (stamps[-1] - stamps[0]) / (len(stamps) - 1) / 1e9
    assert period_s == pytest.approx(0.05, rel=0.2)
    cam.destroy_node()
    # A rate that is given still wins (usb_cam framerate, cv_camera rate), in either form
    # of parameter_overrides; without one cv_camera plays the file at its rate too.
    given = UsbCamNode(
        "given", context=ctx, parameter_overrides={"video_device": str(video), "framerate": 30}
    )
    assert given.settings.rate == 30.0
    plain = CvCameraNode(context=ctx, parameter_overrides=[Parameter("file", str(video))])
    assert plain.settings.rate == pytest.approx(20.0)
    fixed = CvCameraNode(
        "fixed",
        context=ctx,
        parameter_overrides=[Parameter("file", str(video)), Parameter("rate", 30.0)],
    )
    assert fixed.settings.rate == 30.0
    for node in (given, plain, fixed):
        node.destroy_node()


def test_cv_camera_file_bgr_and_rescaled_calibration(
    ctx: Context, video: Path, tmp_path: Path
) -> None:
    big = camera_info_from_matrices(
        (2 * W, 2 * H),
        "plumb_bob",
        np.array(D),
        np.array([160.0, 0, 95.0, 0, 160.0, 63.0, 0, 0, 1]),
        np.eye(3),
        np.array([160.0, 0, 95.0, 0, 0, 160.0, 63.0, 0, 0, 0, 1, 0]),
    )
    yaml_path = write_camera_info_yaml(tmp_path / "big.yaml", big)
    got = _collect(ctx, "/cv_camera", {"image_raw": Image, "camera_info": CameraInfo})
    cam = CvCameraNode(
        context=ctx,
        parameter_overrides={
            "file": str(video),
            "rate": 200.0,
            "camera_info_url": str(yaml_path),
            "rescale_camera_info": True,
            "capture_delay": 0.25,
        },
    )
    _run(ctx, cam)
    assert len(got["image_raw"]) == FRAMES
    img = got["image_raw"][0]
    assert img.encoding == "bgr8"
    assert img.header.frame_id == "camera"
    assert image_to_numpy(img)[30, 18, 0] > 200  # blue stays in channel 0
    info = got["camera_info"][0]
    assert (info.width, info.height) == (W, H)
    assert np.allclose(info.k, [80.0, 0, 47.5, 0, 80.0, 31.5, 0, 0, 1])
    # capture_delay moves the stamp back by 0.25 s
    assert time_to_ns(img.header.stamp) < time.time_ns() - 200_000_000


def test_uncalibrated_and_missing_calibration(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    info, note = load_camera_info("", camera_name="front", width=W, height=H)
    assert (info.width, info.height) == (W, H)
    assert not np.any(info.k)
    assert "uncalibrated" in note
    assert str(tmp_path / "camera_info" / "front.yaml") in note
    with pytest.raises(CameraDriverError, match="visnav calibrate"):
        load_camera_info(f"file://{tmp_path}/none.yaml", camera_name="x", width=W, height=H)
    bad = tmp_path / "bad.yaml"
    bad.write_text("image_width: [1\n")
    with pytest.raises(CameraDriverError, match="camera_info_url"):
        load_camera_info(str(bad), camera_name="x", width=W, height=H)


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=60))
def test_camera_info_url_fuzz(url: str) -> None:
    with contextlib.suppress(PerceptionError):
        load_camera_info(url, camera_name="cam", width=4, height=3)


def test_cli_missing_device_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from visnav.cli.main import main

    assert main(["camera", "/dev/video97"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: camera device /dev/video97 does not exist")
    assert "`ls /dev/video*`" in err
    assert "\n" not in err
    assert main(["camera", "--driver", "cv_camera", "--pixel-format", "yuyv", "x.avi"]) == 1
    assert "--pixel-format is a usb_cam parameter" in capsys.readouterr().err


def test_cli_fps_is_whole_for_usb_cam(
    video: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`visnav camera FILE --fps 5` (default driver usb_cam: integer framerate) runs."""
    from visnav.cli.main import main

    monkeypatch.setenv("VISNAV_TRANSPORT", "local")
    assert main(["camera", str(video), "--fps", "200"]) == 0
    assert f"usb_cam: published {FRAMES} frames" in capsys.readouterr().out
    assert main(["camera", str(video), "--fps", "2.5"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --fps 2.5: usb_cam's framerate is whole frames per second")
    assert "--driver cv_camera" in err
    assert "\n" not in err


def test_roslaunch_usb_cam_node_maps_to_the_driver(tmp_path: Path, video: Path) -> None:
    from visnav.launch import load_launch

    f = tmp_path / "cam.launch"
    f.write_text(
        f"""<launch>
  <node name="usb_cam" pkg="usb_cam" type="usb_cam_node" output="screen">
    <param name="video_device" value="{video}"/>
    <param name="image_width" value="{W}"/>
    <param name="pixel_format" value="yuyv"/>
    <param name="io_method" value="mmap"/>
    <param name="camera_frame_id" value="usb_cam"/>
  </node>
</launch>"""
    )
    (spec,) = load_launch(f).nodes
    assert spec.executable == "usb_cam"
    assert spec.params["pixel_format"] == "yuyv"
    assert spec.params["video_device"] == str(video)


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(120)
def test_cli_publishes_a_video_file_to_another_process(domain: int, video: Path) -> None:
    import subprocess
    import sys

    got: list[Image] = []
    with Context(domain) as c:
        probe = Node("probe", context=c)
        probe.create_subscription(Image, "/front/cv_camera/image_raw", got.append, 50)
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "visnav.cli.main",
                "--domain",
                str(domain),
                "camera",
                str(video),
                "--driver",
                "cv_camera",
                "--namespace",
                "/front",
                "--fps",
                "5",
                "--frame-id",
                "front_optical",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            c.spin_until(lambda: len(got) >= 5, timeout_s=60)
            out, err = proc.communicate(timeout=60)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    assert f"cv_camera: published {FRAMES} frames" in out
    assert len(got) >= 5
    assert got[0].header.frame_id == "front_optical"
    assert got[0].encoding == "bgr8"


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.text(max_size=20), max_size=4),
    st.sampled_from(["usb_cam", "cv_camera"]),
    st.one_of(st.none(), st.text(max_size=12)),
    st.one_of(st.none(), st.floats()),
)
def test_cli_parameters_fuzz(
    items: list[str], driver: str, source: str | None, fps: float | None
) -> None:
    from visnav.cli.camera import add_arguments, driver_parameters

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--driver", driver])
    args.param = items
    args.source = source
    args.fps = fps
    with contextlib.suppress(PerceptionError):
        params = driver_parameters(args)
        assert all(isinstance(k, str) for k in params)
        if fps is not None and driver == "usb_cam":
            assert type(params["framerate"]) is int


def _launch_text(form: str, video: Path, calibration: Path) -> str:
    if form == "yaml":
        return f"""launch:
  - node:
      exec: usb_cam
      name: usb_cam
      params:
        video_device: {video}
        framerate: 200
        io_method: read
        camera_frame_id: front_optical
        camera_info_url: file://{calibration}
  - node: {{exec: image_proc, name: rectify, namespace: /usb_cam}}
"""
    return f"""<launch>
  <node name="usb_cam" pkg="usb_cam" type="usb_cam_node">
    <param name="video_device" value="{video}"/>
    <param name="framerate" value="200"/>
    <param name="io_method" value="mmap"/>
    <param name="camera_frame_id" value="front_optical"/>
    <param name="camera_info_url" value="file://{calibration}"/>
  </node>
  <node name="rectify" pkg="image_proc" type="image_proc" ns="usb_cam"/>
</launch>"""


@pytest.mark.parametrize("form", ["yaml", "xml"])
@pytest.mark.timeout(60)
def test_launch_file_starts_the_driver_and_a_rectifier_by_name(
    form: str, tmp_path: Path, video: Path, calibration: Path
) -> None:
    """`exec: usb_cam` (YAML) and `pkg="usb_cam" type="usb_cam_node"` (roslaunch) both run."""
    import threading

    from visnav.launch import Launcher, load_launch

    path = tmp_path / ("cam.launch.yaml" if form == "yaml" else "cam.launch")
    path.write_text(_launch_text(form, video, calibration))
    with Context(transport="local") as ctx:
        got = _collect(ctx, "/usb_cam", {"image_rect": Image, "camera_info": CameraInfo})
        launcher = Launcher(load_launch(path), context=ctx)
        stop = threading.Event()
        thread = threading.Thread(target=launcher.run, args=(stop,), daemon=True)
        thread.start()
        try:
            deadline = time.monotonic() + 30
            while len(got["image_rect"]) < FRAMES and time.monotonic() < deadline:
                time.sleep(0.05)
        finally:
            stop.set()
            thread.join(timeout=20)
    (cam,) = [n for n in launcher.shared_nodes if isinstance(n, UsbCamNode)]
    assert cam.frames == FRAMES
    assert len(got["image_rect"]) == FRAMES
    assert got["image_rect"][0].header.frame_id == "front_optical"
    assert list(got["camera_info"][0].d) == D
