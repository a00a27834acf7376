"""The ``usb_cam`` and ``cv_camera`` driver nodes: a camera, video file or stream on the graph.

Both publish, like their ROS 1 namesakes, on private topics of the node:
``~/image_raw`` (``sensor_msgs/Image``; its ``compressed`` form on
``~/image_raw/compressed`` through image_transport, encoded only while someone
subscribes) and ``~/camera_info`` with the same header (frame, stamp). A frame is
stamped when it is grabbed (the node's clock, before decoding), the camera_info comes
from ``camera_info_url`` (:func:`~visnav.perception.camera_driver.load_camera_info`).
At the end of a video file the node logs it, stops its timer and sets ``finished``.

:class:`UsbCamNode` (``usb_cam``) takes usb_cam's parameters: ``video_device``
(``/dev/video0``; an index, a file or a URL work too), ``image_width`` (640),
``image_height`` (480), ``pixel_format`` (``mjpeg``; :data:`PIXEL_FORMATS`),
``io_method`` (``mmap``, ``read`` or ``userptr``: checked, see
:data:`~visnav.perception.camera_driver.IO_METHODS`), ``framerate`` (30),
``camera_frame_id`` (``head_camera``), ``camera_name`` (``head_camera``),
``camera_info_url`` (``""``) and the device controls ``brightness``, ``contrast``,
``saturation``, ``sharpness``, ``gain``, ``focus`` (-1 leaves the device's value),
``autofocus`` (false), ``autoexposure`` (true), ``exposure`` (100),
``auto_white_balance`` (true), ``white_balance`` (4000). Images are ``rgb8`` (``mono8``
for ``grey``/``mono8``), as usb_cam publishes them.

:class:`CvCameraNode` (``cv_camera``) takes cv_camera's: ``device_id`` (0),
``device_path`` (``""``, wins over ``device_id``), ``file`` (``""``, wins over both),
``rate`` (30.0), ``frame_id`` (``camera``), ``image_width`` / ``image_height`` (0: keep
the source's), ``camera_name`` (``camera``), ``camera_info_url``,
``rescale_camera_info`` (false) and ``capture_delay`` (0.0 s, subtracted from each
stamp). Images are ``bgr8``, as cv_camera publishes them.

A video file plays at the frame rate it was recorded at (``CAP_PROP_FPS``) unless
``framerate`` / ``rate`` is given (then that rate): usb_cam cannot open files and
cv_camera plays them at ``rate`` (30 by default), which turns a 10 fps clip into 30 Hz.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import cv2
import numpy as np

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import CameraInfo, Header
from visnav.perception.camera_driver import (
    IO_METHODS,
    PIXEL_FORMATS,
    CameraDriverError,
    CaptureSource,
    VideoSource,
    frame_to_image,
    load_camera_info,
    parse_source,
    scale_camera_info,
)
from visnav.perception.image_transport import ImageTransportPublisher

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "CameraDriverNode",
    "CvCameraNode",
    "CvCameraParams",
    "DriverSettings",
    "UsbCamNode",
    "UsbCamParams",
]

_QUEUE = 5


@dataclass(frozen=True)
class DriverSettings:
    """What a driver node opens and publishes (built from its ROS parameters).

    Attributes:
        source: the device, file or stream.
        width: requested width (0 keeps the source's).
        height: requested height (0 keeps the source's).
        rate: publish (and, for a device, capture) rate in Hz.
        pixel_format: usb_cam pixel format asked of a device (None keeps its own).
        encoding: encoding of the published images.
        frame_id: header frame_id of image and camera_info.
        camera_name: ``${NAME}`` of the camera_info_url.
        camera_info_url: where the calibration is.
        rescale_camera_info: scale a calibration of another size to the images.
        capture_delay_ns: subtracted from each stamp (known capture latency).
        controls: OpenCV ``CAP_PROP_*`` -> value, set on a device.
        rate_given: ``rate`` was set by the user; False lets a video file play at
            its own frame rate (``rate`` is used when the file reports none).
    """

    source: CaptureSource
    width: int = 0
    height: int = 0
    rate: float = 30.0
    pixel_format: str | None = None
    encoding: str = "rgb8"
    frame_id: str = "camera"
    camera_name: str = "camera"
    camera_info_url: str = ""
    rescale_camera_info: bool = False
    capture_delay_ns: int = 0
    controls: dict[int, float] = field(default_factory=dict)
    rate_given: bool = True


def _overridden(node_kwargs: Mapping[str, object], name: str) -> bool:
    """Whether the node's ``parameter_overrides`` (a mapping or Parameters) set ``name``."""
    overrides = node_kwargs.get("parameter_overrides")
    if isinstance(overrides, Mapping):
        return name in overrides
    if isinstance(overrides, Sequence):
        return any(getattr(p, "name", None) == name for p in overrides)
    return False


def _positive_rate(value: float, name: str, node: str) -> float:
    if not math.isfinite(value) or value <= 0:
        msg = f"node {node}: parameter {name} is {value!r}: expected a frame rate > 0 (Hz)"
        raise CameraDriverError(msg)
    return value


def _size(value: int, name: str, node: str) -> int:
    if value < 0:
        msg = f"node {node}: parameter {name} is {value}: expected pixels >= 0 (0 keeps)"
        raise CameraDriverError(msg)
    return value


class CameraDriverNode(Node):
    """The common driver: open the source, publish image_raw + camera_info at ``rate``.

    Subclasses read their parameters into :class:`DriverSettings` and call
    :meth:`start`.
    """

    finished: bool = False

    def _start_or_destroy(self, settings: Callable[[], DriverSettings]) -> None:
        """Read the settings and start; on a driver error, leave the graph and re-raise."""
        try:
            self.start(settings())
        except CameraDriverError:
            Node.destroy_node(self)
            raise

    def start(self, settings: DriverSettings) -> None:
        """Open the source and start publishing.

        Raises:
            CameraDriverError: the source, format or calibration is unusable.
        """
        self.settings = settings
        self.finished = False
        self.frames = 0
        self.video = VideoSource(
            settings.source,
            width=settings.width,
            height=settings.height,
            fps=settings.rate,
            pixel_format=settings.pixel_format,
        )
        fps = self.video.fps
        if not settings.rate_given and settings.source.kind == "file" and fps > 0:
            settings = replace(settings, rate=fps)  # the file's own frame rate
            self.settings = settings
        try:
            self._setup(settings)
        except CameraDriverError:
            self.video.release()
            del self.video
            raise

    def _setup(self, settings: DriverSettings) -> None:
        log = self.get_logger()
        if settings.source.is_device:
            for prop, value in settings.controls.items():
                if not self.video.set_property(prop, value):
                    log.warning(f"{settings.source.target}: the device refused control {prop}")
        elif settings.controls:
            log.warning(
                f"device controls are ignored: {settings.source.target} is a "
                f"{settings.source.kind}, not a camera device"
            )
        width, height = self.video.size
        info, note = load_camera_info(
            settings.camera_info_url,
            camera_name=settings.camera_name,
            width=width,
            height=height,
        )
        if note:
            log.warning(note)
        elif (int(info.width), int(info.height)) != (width, height):
            if settings.rescale_camera_info:
                log.info(
                    f"camera_info of {info.width}x{info.height} rescaled to the "
                    f"{width}x{height} images"
                )
                info = scale_camera_info(info, width, height)
            else:
                log.warning(
                    f"camera_info_url {settings.camera_info_url!r} is a {info.width}x"
                    f"{info.height} calibration but the images are {width}x{height}: "
                    "calibrate at this size (or set rescale_camera_info for cv_camera)"
                )
        self.camera_info = info
        self.image_transport = ImageTransportPublisher(self, "~/image_raw", _QUEUE)
        self._info_pub = self.create_publisher(CameraInfo, "~/camera_info", _QUEUE)
        self._timer = self.create_timer(1.0 / settings.rate, self._tick)
        log.info(
            f"publishing {self.resolve_topic_name('~/image_raw')} ({width}x{height} "
            f"{settings.encoding}, {settings.rate:g} Hz) from {settings.source.kind} "
            f"{settings.source.target}"
        )

    def _tick(self) -> None:
        if self.finished:
            return
        frame = self.video.read(self.get_clock().now_ns)
        if frame is None:
            self.finished = True
            self.destroy_timer(self._timer)
            what = "end of" if self.settings.source.kind == "file" else "no more frames from"
            self.get_logger().info(
                f"{what} {self.settings.source.target} after {self.frames} frames"
            )
            return
        stamp = ns_to_time(max(0, frame.stamp_ns - self.settings.capture_delay_ns))
        header = Header(stamp=stamp, frame_id=self.settings.frame_id)
        image = frame_to_image(frame.pixels, self.settings.encoding, header)
        self.image_transport.publish(image)
        info = self.camera_info
        self._info_pub.publish(
            CameraInfo(
                header=header,
                height=info.height,
                width=info.width,
                distortion_model=info.distortion_model,
                d=info.d,
                k=info.k,
                r=info.r,
                p=info.p,
                binning_x=info.binning_x,
                binning_y=info.binning_y,
                roi=info.roi,
            )
        )
        self.frames += 1

    def destroy_node(self) -> None:
        """Close the source, then the node."""
        video = getattr(self, "video", None)
        if video is not None:
            video.release()
        super().destroy_node()


_USB_CONTROLS: dict[str, tuple[int, float]] = {
    "brightness": (cv2.CAP_PROP_BRIGHTNESS, -1),
    "contrast": (cv2.CAP_PROP_CONTRAST, -1),
    "saturation": (cv2.CAP_PROP_SATURATION, -1),
    "sharpness": (cv2.CAP_PROP_SHARPNESS, -1),
    "gain": (cv2.CAP_PROP_GAIN, -1),
    "focus": (cv2.CAP_PROP_FOCUS, -1),
}


@dataclass(frozen=True)
class UsbCamParams:
    """usb_cam's parameters (its names and defaults; read once at start).

    The V4L2 controls (``brightness`` ... ``focus``) are -1 for "leave the device's value".
    """

    video_device: str = param("/dev/video0", description="V4L2 device, video file or stream URL")
    pixel_format: str = param("mjpeg", description="the device's pixel format")
    io_method: str = param("mmap", description="V4L2 I/O method: mmap, read or userptr")
    brightness: int = param(-1, description="V4L2 brightness (-1: leave)")
    contrast: int = param(-1, description="V4L2 contrast (-1: leave)")
    saturation: int = param(-1, description="V4L2 saturation (-1: leave)")
    sharpness: int = param(-1, description="V4L2 sharpness (-1: leave)")
    gain: int = param(-1, description="V4L2 gain (-1: leave)")
    focus: int = param(-1, description="V4L2 focus (-1: leave)")
    autofocus: bool = param(False, description="turn autofocus on")
    autoexposure: bool = param(True, description="automatic exposure (false: use exposure)")
    exposure: int = param(100, description="manual exposure when autoexposure is false")
    auto_white_balance: bool = param(True, description="automatic white balance")
    white_balance: int = param(4000, description="white balance (K) when auto is false")
    image_width: int = param(640, description="image width (px)")
    image_height: int = param(480, description="image height (px)")
    framerate: int = param(30, description="frames per second")
    camera_frame_id: str = param("head_camera", description="frame_id of the images")
    camera_name: str = param("head_camera", description="camera name (calibration files)")
    camera_info_url: str = param("", description="calibration file URL ('': none)")


class UsbCamNode(CameraDriverNode):
    """usb_cam: a V4L2 camera (or a file / stream) with usb_cam's parameters.

    Args:
        name: node name (default ``usb_cam``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace, ...).

    Raises:
        CameraDriverError: a parameter out of range, a missing device or a pixel format
            the device does not offer.
    """

    def __init__(self, name: str = "usb_cam", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self._rate_given = _overridden(node_kwargs, "framerate")
        self._start_or_destroy(self._settings)

    def _settings(self) -> DriverSettings:
        fqn = self.get_fully_qualified_name()
        prm = declare_params(self, UsbCamParams)
        device, pixel_format, io_method = prm.video_device, prm.pixel_format, prm.io_method
        if pixel_format not in PIXEL_FORMATS:
            msg = (
                f"node {fqn}: pixel_format {pixel_format!r} is unknown: expected one of "
                f"{', '.join(PIXEL_FORMATS)}"
            )
            raise CameraDriverError(msg)
        if io_method not in IO_METHODS:
            msg = f"node {fqn}: io_method {io_method!r}: expected one of {', '.join(IO_METHODS)}"
            raise CameraDriverError(msg)
        controls: dict[int, float] = {}
        for key, (prop, unset) in _USB_CONTROLS.items():
            value = float(getattr(prm, key))
            if value != unset:
                controls[prop] = value
        if prm.autofocus:
            controls[cv2.CAP_PROP_AUTOFOCUS] = 1.0
        if not prm.autoexposure:  # V4L2: 1 = manual, 3 = aperture priority (auto)
            controls[cv2.CAP_PROP_AUTO_EXPOSURE] = 1.0
            controls[cv2.CAP_PROP_EXPOSURE] = float(prm.exposure)
        if not prm.auto_white_balance:
            controls[cv2.CAP_PROP_AUTO_WB] = 0.0
            controls[cv2.CAP_PROP_WB_TEMPERATURE] = float(prm.white_balance)
        source = parse_source(device)
        return DriverSettings(
            source=source,
            width=_size(prm.image_width, "image_width", fqn),
            height=_size(prm.image_height, "image_height", fqn),
            rate=_positive_rate(float(prm.framerate), "framerate", fqn),
            pixel_format=pixel_format if source.is_device else None,
            encoding="mono8" if PIXEL_FORMATS[pixel_format] == "GREY" else "rgb8",
            frame_id=prm.camera_frame_id,
            camera_name=prm.camera_name,
            camera_info_url=prm.camera_info_url,
            controls=controls,
            rate_given=self._rate_given,
        )


@dataclass(frozen=True)
class CvCameraParams:
    """cv_camera's parameters (its names and defaults; read once at start)."""

    device_id: int = param(0, description="OpenCV camera index (when no path or file)")
    device_path: str = param("", description="device path, preferred to device_id")
    file: str = param("", description="a video file or URL, preferred to the device")
    capture_delay: float = param(0.0, description="s the capture precedes the stamp")
    image_width: int = param(0, description="image width (px; 0: the source's)")
    image_height: int = param(0, description="image height (px; 0: the source's)")
    rate: float = param(30.0, description="frames per second")
    frame_id: str = param("camera", description="frame_id of the images")
    camera_name: str = param("camera", description="camera name (calibration files)")
    camera_info_url: str = param("", description="calibration file URL ('': none)")
    rescale_camera_info: bool = param(False, description="scale the calibration to the size")


class CvCameraNode(CameraDriverNode):
    """cv_camera: OpenCV VideoCapture with cv_camera's parameters.

    Args:
        name: node name (default ``cv_camera``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace, ...).

    Raises:
        CameraDriverError: a parameter out of range or a source that does not open.
    """

    def __init__(self, name: str = "cv_camera", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self._rate_given = _overridden(node_kwargs, "rate")
        self._start_or_destroy(self._settings)

    def _settings(self) -> DriverSettings:
        fqn = self.get_fully_qualified_name()
        prm = declare_params(self, CvCameraParams)
        if prm.file:
            source = parse_source(prm.file if "://" in prm.file else f"file://{prm.file}")
        else:
            source = parse_source(prm.device_path or prm.device_id)
        delay = prm.capture_delay
        if not np.isfinite(delay) or delay < 0:
            msg = f"node {fqn}: capture_delay is {delay!r}: expected seconds >= 0"
            raise CameraDriverError(msg)
        return DriverSettings(
            source=source,
            width=_size(prm.image_width, "image_width", fqn),
            height=_size(prm.image_height, "image_height", fqn),
            rate=_positive_rate(prm.rate, "rate", fqn),
            encoding="bgr8",
            frame_id=prm.frame_id,
            camera_name=prm.camera_name,
            camera_info_url=prm.camera_info_url,
            rescale_camera_info=prm.rescale_camera_info,
            capture_delay_ns=round(delay * 1e9),
            rate_given=self._rate_given,
        )
