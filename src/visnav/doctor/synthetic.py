"""A synthetic, fault-free car-like stream: to try doctor, inject faults, and benchmark it.

:func:`car_stream` yields the messages a camera car publishes, in receive order, with
sim-time stamps and ``/clock``: RGB camera and camera_info, depth image, depth
camera_info and point cloud (optical frames), odometry and ``odom -> base_footprint``
on ``/tf``, the mounts on ``/tf_static``. The frames and topics are those of the
built-in car (``visnav sim --robot car``). Tests copy the events and alter them to
inject one fault at a time (copy a message before changing it: messages of one kind
share their pixel and point buffers); :func:`events_to_observation` and
:func:`write_bag` turn them into an observation or a bag.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from visnav.bag.qos import latched_qos
from visnav.bag.writer import BagWriter
from visnav.doctor.builder import ObservationBuilder, SamplingPolicy
from visnav.doctor.observation import GraphSnapshot, Observation
from visnav.msgs.construct import make
from visnav.msgs.image import numpy_to_image
from visnav.msgs.pointcloud import xyz_to_cloud
from visnav.msgs.serde import get_message_class, msg_type_name, serialize
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    CameraInfo,
    Clock,
    Header,
    Odometry,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Vector3,
)

__all__ = ["CarStreamConfig", "StreamEvent", "car_stream", "events_to_observation", "write_bag"]

_OPTICAL = (-0.5, 0.5, -0.5, 0.5)  # rpy (-pi/2, 0, -pi/2): body -> optical, x y z w
_MOUNTS = (
    ("base_footprint", "base_link", (0.0, 0.0, 0.08), (0.0, 0.0, 0.0, 1.0)),
    ("base_link", "camera_link", (0.16, 0.0, 0.25), (0.0, 0.0, 0.0, 1.0)),
    ("camera_link", "camera_optical_frame", (0.0, 0.0, 0.0), _OPTICAL),
    ("base_link", "depth_camera_link", (0.16, 0.0, 0.20), (0.0, 0.0, 0.0, 1.0)),
    ("depth_camera_link", "depth_camera_optical_frame", (0.0, 0.0, 0.0), _OPTICAL),
)


_VARIANTS = 8  # distinct RGB frames, cycled (keeps long streams cheap to generate)


class StreamEvent(NamedTuple):
    """One message as received: topic, type, receive time, message, publisher identity."""

    topic: str
    type_name: str
    receive_ns: int
    msg: Any
    publisher: str = ""


@dataclass(frozen=True)
class CarStreamConfig:
    """The synthetic car.

    Attributes:
        duration_s: sim seconds to generate.
        width: image width (pixels).
        height: image height (pixels).
        camera_hz: RGB camera rate.
        depth_hz: depth image and cloud rate.
        odom_hz: odometry and odom TF rate.
        clock_hz: /clock rate.
        hfov: horizontal field of view of both cameras (radians).
        speed: forward speed, m/s.
        wall_start_ns: receive time of sim time 0 (the observer's wall clock).
        real_time_factor: sim seconds per wall second.
        latency_ns: publish -> receive delay.
        cloud_stride: keep every n-th pixel (in both directions) in the cloud.
        sky: paint a blue sky in the top of the RGB image (else a grey wall).
        seed: texture noise seed.
    """

    duration_s: float = 3.0
    width: int = 64
    height: int = 48
    camera_hz: float = 30.0
    depth_hz: float = 20.0
    odom_hz: float = 50.0
    clock_hz: float = 100.0
    hfov: float = 1.3962634
    speed: float = 0.5
    wall_start_ns: int = 1_700_000_000_000_000_000
    real_time_factor: float = 1.0
    latency_ns: int = 1_000_000
    cloud_stride: int = 2
    sky: bool = True
    seed: int = 0

    @property
    def fx(self) -> float:
        """Focal length in pixels matching ``hfov``."""
        return self.width / (2.0 * math.tan(self.hfov / 2.0))


def _ticks(rate_hz: float, duration_s: float) -> Iterator[int]:
    n = math.floor(duration_s * rate_hz + 1e-9)
    for k in range(n + 1):
        yield round(k * 1e9 / rate_hz)


def _header(t_ns: int, frame: str) -> Header:
    return Header(stamp=ns_to_time(t_ns), frame_id=frame)


def _transform(parent: str, child: str, t_ns: int, xyz: Any, q: Any) -> TransformStamped:
    return TransformStamped(
        _header(t_ns, parent),
        child,
        Transform(Vector3(*map(float, xyz)), Quaternion(*map(float, q))),
    )


def camera_info(cfg: CarStreamConfig, t_ns: int, frame: str) -> CameraInfo:
    """The camera_info of the synthetic cameras."""
    fx, cx, cy = cfg.fx, cfg.width / 2.0, cfg.height / 2.0
    msg = make(
        CameraInfo,
        header=_header(t_ns, frame),
        width=cfg.width,
        height=cfg.height,
        distortion_model="plumb_bob",
    )
    msg.d = np.zeros(5)
    msg.k[:] = [fx, 0.0, cx, 0.0, fx, cy, 0.0, 0.0, 1.0]
    msg.r[:] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p[:] = [fx, 0.0, cx, 0.0, 0.0, fx, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg


class _Scene:
    """Pixels and depth of the synthetic scene (precomputed, shifted per frame)."""

    def __init__(self, cfg: CarStreamConfig) -> None:
        rng = np.random.default_rng(cfg.seed)
        h, w = cfg.height, cfg.width
        rows = np.arange(h)[:, None] / max(h - 1, 1)
        rgb = np.empty((h, w, 3), dtype=np.float64)
        top = np.array([110.0, 160.0, 225.0]) if cfg.sky else np.array([120.0, 120.0, 125.0])
        wall = np.array([150.0, 140.0, 125.0])
        ground = np.array([140.0, 105.0, 70.0])
        band = rows[..., None]
        rgb[:] = np.where(band < 0.3, top, np.where(band < 0.55, wall, ground))
        noise = rng.normal(0.0, 6.0, size=(h, 2 * w, 3))
        self.noise = noise
        self.rgb = rgb
        depth = np.broadcast_to(3.0 + 1.5 * (1.0 - rows), (h, w))
        self.depth = np.ascontiguousarray(depth, dtype=np.float32)
        u, v = np.meshgrid(np.arange(w), np.arange(h))
        s = max(1, cfg.cloud_stride)
        us, vs, zs = u[::s, ::s], v[::s, ::s], self.depth[::s, ::s]
        fx, cx, cy = cfg.fx, w / 2.0, h / 2.0
        points = np.stack([(us - cx) / fx * zs, (vs - cy) / fx * zs, zs], axis=-1)
        self.points = points.reshape(-1, 3).astype(np.float32)

    def image(self, k: int) -> NDArray[np.uint8]:
        """Frame ``k``: the scene with shifted noise (8 variants, cycled)."""
        w = self.rgb.shape[1]
        shift = (k % _VARIANTS) * max(1, w // _VARIANTS)
        out = self.rgb + self.noise[:, shift : shift + w]
        return np.clip(out, 0, 255).astype(np.uint8)


def car_stream(cfg: CarStreamConfig | None = None) -> Iterator[StreamEvent]:
    """Yield the car's messages in receive order (see the module docs)."""
    cfg = cfg or CarStreamConfig()
    scene = _Scene(cfg)
    events: list[tuple[int, int, StreamEvent]] = []
    seq = 0

    def emit(t_ns: int, topic: str, msg: Any, publisher: str) -> None:
        nonlocal seq
        rx = cfg.wall_start_ns + round(t_ns / cfg.real_time_factor) + cfg.latency_ns
        events.append((rx, seq, StreamEvent(topic, msg_type_name(msg), rx, msg, publisher)))
        seq += 1

    static = [_transform(p, c, 0, xyz, q) for p, c, xyz, q in _MOUNTS]
    emit(0, "/tf_static", TFMessage(transforms=static), "sim:rsp")
    for t in _ticks(cfg.clock_hz, cfg.duration_s):
        emit(t, "/clock", Clock(clock=ns_to_time(t)), "sim:clock")
    for t in _ticks(cfg.odom_hz, cfg.duration_s):
        x = cfg.speed * t / 1e9
        tf = _transform("odom", "base_footprint", t, (x, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        emit(t, "/tf", TFMessage(transforms=[tf]), "sim:diff_drive")
        odom = make(Odometry, header=_header(t, "odom"), child_frame_id="base_footprint")
        odom.pose.pose.position.x = x
        odom.pose.pose.orientation.w = 1.0
        odom.twist.twist.linear.x = cfg.speed
        emit(t, "/odom", odom, "sim:diff_drive")
    frame = "camera_optical_frame"
    images = [numpy_to_image(scene.image(k), "rgb8") for k in range(_VARIANTS)]
    for k, t in enumerate(_ticks(cfg.camera_hz, cfg.duration_s)):
        image = replace(images[k % _VARIANTS], header=_header(t, frame))
        emit(t, "/camera/image_raw", image, "sim:camera")
        emit(t, "/camera/camera_info", camera_info(cfg, t, frame), "sim:camera")
    frame = "depth_camera_optical_frame"
    depth_image = numpy_to_image(scene.depth, "32FC1")
    cloud = xyz_to_cloud(scene.points)
    for t in _ticks(cfg.depth_hz, cfg.duration_s):
        emit(
            t,
            "/depth_camera/depth/image_raw",
            replace(depth_image, header=_header(t, frame)),
            "sim:depth",
        )
        emit(t, "/depth_camera/depth/camera_info", camera_info(cfg, t, frame), "sim:depth")
        emit(t, "/depth_camera/points", replace(cloud, header=_header(t, frame)), "sim:depth")
    events.sort(key=lambda e: (e[0], e[1]))
    for _, _, ev in events:
        yield ev


def events_to_observation(
    events: Iterable[StreamEvent],
    *,
    source: str = "bag",
    graph: GraphSnapshot | None = None,
    policy: SamplingPolicy | None = None,
    label: str = "synthetic car stream",
) -> Observation:
    """Feed events to an :class:`ObservationBuilder` (as a bag or live observer would)."""
    builder = ObservationBuilder(source=source, label=label, policy=policy)
    if graph is not None:
        for e in graph.endpoints:
            if e.kind == "publisher":
                builder.declare_topic(e.topic, e.type_name)
    for ev in events:
        builder.add(ev.topic, ev.type_name, ev.receive_ns, ev.msg, publisher=ev.publisher)
    if graph is not None:
        builder.set_graph(graph)
    return builder.build()


def write_bag(events: Iterable[StreamEvent], path: str | Path, *, fmt: str = "mcap") -> Path:
    """Write events into a bag (record time = receive time); return its path."""
    with BagWriter(path, fmt=fmt) as bag:
        handles: dict[str, int] = {}
        for ev in events:
            h = handles.get(ev.topic)
            if h is None:
                get_message_class(ev.type_name)
                qos = [latched_qos()] if ev.topic == "/tf_static" else []
                h = bag.add_topic(ev.topic, ev.type_name, qos=qos)
                handles[ev.topic] = h
            bag.write(h, ev.receive_ns, serialize(ev.msg))
        return bag.path
