"""Frame capture for the camera drivers: OpenCV ``VideoCapture`` on a device, file or stream.

The graph nodes (:mod:`visnav.perception.camera_driver_node`: ``usb_cam`` and
``cv_camera``) wrap the plain objects here:

* :func:`parse_source`: what to open. An integer or ``"2"`` is a device index
  (``/dev/video2``), ``/dev/...`` a device path, a ``scheme://`` address a stream
  (``rtsp://``, ``http://``, ...; ``file://`` is a file), anything else a video file.
* :class:`VideoSource`: opens the source, asks a device for the size, frame rate and
  pixel format (usb_cam's ``pixel_format`` names, :data:`PIXEL_FORMATS`), grabs frames
  and records the capture time of each (the caller's clock, read as soon as ``grab``
  returns, before the frame is decoded).
* :func:`device_formats`: the pixel formats a V4L2 device offers (``VIDIOC_ENUM_FMT``),
  named in the error when a requested format is refused.
* :func:`frame_to_image`: an OpenCV BGR (or grey) frame as a ``sensor_msgs/Image``.
* :func:`load_camera_info`: camera_info_manager's rules for ``camera_info_url``:
  a ``file://`` YAML (as ``visnav calibrate`` writes it), the default
  ``${ROS_HOME}/camera_info/${NAME}.yaml``, or an uncalibrated camera_info (size only).

Every failure a user can cause (no such device, a file that does not decode, a format
the device does not offer) raises :class:`CameraDriverError` with one line that names
the source and the fix (``ls /dev/video*``, the formats offered).
"""

from __future__ import annotations

import fcntl
import os
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import numpy_to_image
from visnav.msgs.types import CameraInfo, Header, Image, RegionOfInterest, Time
from visnav.perception._calibration_common import CalibrationError
from visnav.perception.camera_info_yaml import read_camera_info_yaml, resolve_camera_info_url
from visnav.perception.errors import PerceptionError

__all__ = [
    "IO_METHODS",
    "PIXEL_FORMATS",
    "CameraDriverError",
    "CaptureSource",
    "Frame",
    "VideoSource",
    "device_formats",
    "frame_to_image",
    "load_camera_info",
    "parse_source",
    "scale_camera_info",
    "uncalibrated_camera_info",
]

PIXEL_FORMATS: dict[str, str] = {
    "yuyv": "YUYV",
    "uyvy": "UYVY",
    "mjpeg": "MJPG",
    "rgb24": "RGB3",
    "bgr24": "BGR3",
    "grey": "GREY",
    "mono8": "GREY",
    "mono16": "Y16 ",
    "yuvmono10": "Y10 ",
    "h264": "H264",
}
"""usb_cam's ``pixel_format`` names -> the V4L2 FourCC asked of the device."""

IO_METHODS = ("mmap", "read", "userptr")
"""usb_cam's ``io_method`` values. Accepted and checked; OpenCV's V4L2 backend always
streams through mmap buffers, so the value does not change how frames are read."""

SourceKind = Literal["device", "file", "url"]

_VIDIOC_ENUM_FMT = 0xC0405602  # _IOWR('V', 2, struct v4l2_fmtdesc), 64-byte struct
_V4L2_BUF_TYPE_VIDEO_CAPTURE = 1
_FMTDESC = struct.Struct("<III32sII12x")
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


class CameraDriverError(PerceptionError, ValueError):
    """A camera source cannot be opened or read, or a driver parameter is invalid."""


@dataclass(frozen=True)
class CaptureSource:
    """What a driver captures from.

    Attributes:
        kind: ``device`` (V4L2 path), ``file`` (a video file) or ``url`` (a stream).
        target: the device path, file path or URL.
    """

    kind: SourceKind
    target: str

    @property
    def is_device(self) -> bool:
        """True for a camera device."""
        return self.kind == "device"


def parse_source(value: str | int) -> CaptureSource:
    """Classify a ``video_device`` / ``device_id`` / ``file`` value.

    Raises:
        CameraDriverError: an empty value or a negative device index.
    """
    text = str(value).strip()
    if not text:
        msg = "camera source is empty: give a device (/dev/video0 or 0), a video file or a URL"
        raise CameraDriverError(msg)
    if re.fullmatch(r"-?\d+", text):
        index = int(text)
        if index < 0:
            msg = f"camera device index {index} is negative: expected 0 for /dev/video0, 1, ..."
            raise CameraDriverError(msg)
        return CaptureSource("device", f"/dev/video{index}")
    if text.startswith("file://"):
        return CaptureSource("file", text[len("file://") :])
    if _URL.match(text):
        return CaptureSource("url", text)
    if text.startswith("/dev/"):
        return CaptureSource("device", text)
    return CaptureSource("file", os.path.expanduser(text))  # noqa: PTH111 (never raises)


def device_formats(path: str) -> list[str]:
    """The FourCC codes a V4L2 capture device offers (empty when it cannot be asked)."""
    out: list[str] = []
    try:
        fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)
    except OSError:
        return out
    try:
        for index in range(64):
            buf = bytearray(_FMTDESC.pack(index, _V4L2_BUF_TYPE_VIDEO_CAPTURE, 0, b"", 0, 0))
            try:
                fcntl.ioctl(fd, _VIDIOC_ENUM_FMT, buf)
            except OSError:
                break
            fourcc = _FMTDESC.unpack(bytes(buf))[4]
            out.append(struct.pack("<I", fourcc).decode("ascii", "replace"))
    finally:
        os.close(fd)
    return out


def _fourcc_name(code: float) -> str:
    value = int(code) & 0xFFFFFFFF
    return struct.pack("<I", value).decode("ascii", "replace") if value else ""


def _offered_names(offered: list[str]) -> str:
    names = [n for n, f in PIXEL_FORMATS.items() if f in offered and n not in ("grey",)]
    extra = [f.strip() for f in offered if f not in PIXEL_FORMATS.values()]
    return ", ".join(names + extra) or "none reported"


@dataclass(frozen=True)
class Frame:
    """One captured frame: pixels (OpenCV order: BGR or grey) and the capture time."""

    pixels: NDArray[np.uint8]
    stamp_ns: int
    index: int


class VideoSource:
    """An opened camera, video file or stream.

    Args:
        source: what to open (:func:`parse_source`).
        width: requested width (devices; 0 keeps the device's). Files keep their size.
        height: requested height.
        fps: requested frame rate (devices).
        pixel_format: usb_cam ``pixel_format`` name (devices; None keeps the device's).
        capture: a factory ``(target, api) -> cv2.VideoCapture`` (tests inject one).

    Raises:
        CameraDriverError: the source does not exist or does not open, or the device
            refuses the pixel format.
    """

    def __init__(
        self,
        source: CaptureSource,
        *,
        width: int = 0,
        height: int = 0,
        fps: float = 0.0,
        pixel_format: str | None = None,
        capture: Callable[[str, int], Any] | None = None,
    ) -> None:
        self.source = source
        if pixel_format is not None and pixel_format not in PIXEL_FORMATS:
            msg = (
                f"pixel_format {pixel_format!r} is not one usb_cam knows: expected one of "
                f"{', '.join(PIXEL_FORMATS)}"
            )
            raise CameraDriverError(msg)
        self._check_exists()
        factory = capture if capture is not None else cv2.VideoCapture
        api = cv2.CAP_V4L2 if source.is_device else cv2.CAP_ANY
        self._cap = factory(source.target, api)
        if not self._cap.isOpened():
            self._cap.release()
            raise CameraDriverError(self._open_failure())
        self._count = 0
        if source.is_device:
            self._configure(width, height, fps, pixel_format)

    def _check_exists(self) -> None:
        src = self.source
        if src.kind == "device" and not Path(src.target).exists():
            msg = (
                f"camera device {src.target} does not exist: list the cameras with "
                "`ls /dev/video*` (or `v4l2-ctl --list-devices`) and set video_device / "
                "device_id to one of them"
            )
            raise CameraDriverError(msg)
        if src.kind == "file" and not Path(src.target).is_file():
            msg = f"video file {src.target} does not exist: check the path (file parameter)"
            raise CameraDriverError(msg)

    def _open_failure(self) -> str:
        src = self.source
        if src.kind == "device":
            return (
                f"camera device {src.target} exists but does not open as a V4L2 capture "
                "device (in use by another program, or no permission: add yourself to the "
                "'video' group); list the cameras with `ls /dev/video*`"
            )
        if src.kind == "file":
            return (
                f"video file {src.target} does not open: OpenCV (FFmpeg) cannot decode it; "
                "convert it, e.g. `ffmpeg -i IN -c:v mjpeg OUT.avi`"
            )
        return f"stream {src.target} does not open: check the URL and that the server is up"

    def _configure(self, width: int, height: int, fps: float, pixel_format: str | None) -> None:
        cap = self._cap
        if pixel_format is not None:
            want = PIXEL_FORMATS[pixel_format]
            cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*want))
            got = _fourcc_name(cap.get(cv2.CAP_PROP_FOURCC))
            if got and got != want:
                offered = device_formats(self.source.target)
                cap.release()
                msg = (
                    f"camera {self.source.target} does not offer pixel_format {pixel_format!r} "
                    f"({want.strip()}): it offers {_offered_names(offered)}; set pixel_format "
                    "to one of them"
                )
                raise CameraDriverError(msg)
        if width > 0:
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, float(width))
        if height > 0:
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, float(height))
        if fps > 0:
            cap.set(cv2.CAP_PROP_FPS, float(fps))

    def set_property(self, prop: int, value: float) -> bool:
        """Set an OpenCV ``CAP_PROP_*`` on the capture; True when the backend took it."""
        return bool(self._cap.set(prop, float(value)))

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) the source delivers."""
        w = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        h = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        return w, h

    @property
    def fps(self) -> float:
        """The frame rate the source reports (0 when unknown)."""
        value = float(self._cap.get(cv2.CAP_PROP_FPS))
        return value if np.isfinite(value) and value > 0 else 0.0

    def read(self, now_ns: Callable[[], int]) -> Frame | None:
        """Grab and decode the next frame; None at the end of a file or stream.

        Args:
            now_ns: the clock stamping the frame, read as soon as the frame is grabbed.
        """
        if not self._cap.grab():
            return None
        stamp = now_ns()
        ok, pixels = self._cap.retrieve()
        if not ok or pixels is None:
            return None
        self._count += 1
        return Frame(np.ascontiguousarray(pixels, dtype=np.uint8), stamp, self._count - 1)

    def release(self) -> None:
        """Close the device, file or stream."""
        self._cap.release()


def frame_to_image(frame: NDArray[np.uint8], encoding: str, header: Header) -> Image:
    """A captured OpenCV frame as an Image in ``encoding`` (``rgb8``, ``bgr8`` or ``mono8``).

    Raises:
        CameraDriverError: an encoding other than those three.
    """
    grey = frame.ndim == 2 or (frame.ndim == 3 and frame.shape[2] == 1)
    if encoding == "mono8":
        pixels = frame if grey else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    elif encoding in ("rgb8", "bgr8"):
        bgr = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if grey else frame
        pixels = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) if encoding == "rgb8" else bgr
    else:
        msg = f"camera encoding {encoding!r}: expected rgb8, bgr8 or mono8"
        raise CameraDriverError(msg)
    return numpy_to_image(np.ascontiguousarray(pixels), encoding, header=header)


def uncalibrated_camera_info(width: int, height: int, frame_id: str = "") -> CameraInfo:
    """camera_info_manager's uncalibrated camera_info: the size, every matrix zero."""
    return CameraInfo(
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id=frame_id),
        height=int(height),
        width=int(width),
        distortion_model="",
        d=np.zeros(0, dtype=np.float64),
        k=np.zeros(9, dtype=np.float64),
        r=np.zeros(9, dtype=np.float64),
        p=np.zeros(12, dtype=np.float64),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def scale_camera_info(info: CameraInfo, width: int, height: int) -> CameraInfo:
    """``info`` rescaled to ``width`` x ``height`` (cv_camera's ``rescale_camera_info``)."""
    sx, sy = width / max(int(info.width), 1), height / max(int(info.height), 1)
    k = np.asarray(info.k, dtype=np.float64).copy()
    p = np.asarray(info.p, dtype=np.float64).copy()
    k[[0, 2]] *= sx
    k[[4, 5]] *= sy
    p[[0, 2, 3]] *= sx
    p[[5, 6, 7]] *= sy
    return CameraInfo(
        header=info.header,
        height=int(height),
        width=int(width),
        distortion_model=info.distortion_model,
        d=np.asarray(info.d, dtype=np.float64).copy(),
        k=k,
        r=np.asarray(info.r, dtype=np.float64).copy(),
        p=p,
        binning_x=info.binning_x,
        binning_y=info.binning_y,
        roi=info.roi,
    )


def load_camera_info(
    url: str, *, camera_name: str, width: int, height: int
) -> tuple[CameraInfo, str]:
    """camera_info_manager's lookup: the calibration for ``url``, or an uncalibrated one.

    Args:
        url: ``camera_info_url`` (``file://...``, a path, or empty for
            ``${ROS_HOME}/camera_info/${NAME}.yaml``).
        camera_name: replaces ``${NAME}``.
        width: image width (of the uncalibrated camera_info).
        height: image height.

    Returns:
        The camera_info and a note for the log (``""`` when a calibration was loaded).

    Raises:
        CameraDriverError: a URL that was given names no file, or the file is not a
            calibration (the YAML reader's message is kept).
    """
    try:
        path = resolve_camera_info_url(url, camera_name=camera_name or None)
    except CalibrationError as exc:
        raise CameraDriverError(f"camera_info_url: {exc}") from exc
    if not path.is_file():
        if url:
            msg = (
                f"camera_info_url {url!r}: {path} does not exist; write it with "
                "`visnav calibrate ... -o FILE.yaml` and pass file:///absolute/FILE.yaml, "
                "or leave camera_info_url empty for an uncalibrated camera"
            )
            raise CameraDriverError(msg)
        note = (
            f"no calibration at {path} (camera_info_url is empty): publishing an "
            "uncalibrated camera_info (K all zero); calibrate with `visnav calibrate`"
        )
        return uncalibrated_camera_info(width, height), note
    try:
        info = read_camera_info_yaml(path)
    except CalibrationError as exc:
        raise CameraDriverError(f"camera_info_url {url!r}: {exc}") from exc
    return info, ""
