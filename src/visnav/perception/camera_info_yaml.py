"""camera_info YAML files in the format of ROS's camera_calibration_parsers.

The layout (what ``camera_info_url`` files hold)::

    image_width: 640
    image_height: 480
    camera_name: narrow_stereo
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [...]}
    projection_matrix: {rows: 3, cols: 4, data: [...]}

(the matrices are written in block style with a flow ``data`` list, as ROS does).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import yaml

from visnav.msgs.types import CameraInfo, Header, RegionOfInterest, Time
from visnav.perception._calibration_common import CalibrationError, WarningLogger, default_logger
from visnav.safe_yaml import load_yaml_file

__all__ = [
    "CalibrationLike",
    "camera_info_from_matrices",
    "load_calibration_yaml",
    "read_camera_info_yaml",
    "resolve_camera_info_url",
    "write_camera_info_yaml",
]

_REQUIRED_FIELDS = (
    "image_width",
    "image_height",
    "camera_matrix",
    "distortion_coefficients",
    "rectification_matrix",
    "projection_matrix",
)


class CalibrationLike(Protocol):
    """A calibration result: a camera name and a ``to_camera_info()`` method."""

    @property
    def camera_name(self) -> str:
        """The camera's name."""

    def to_camera_info(self) -> CameraInfo:
        """Return the calibration as a CameraInfo."""


def camera_info_from_matrices(
    size: tuple[int, int],
    distortion_model: str,
    d: Any,
    k: Any,
    r: Any,
    p: Any,
    *,
    header: Header | None = None,
) -> CameraInfo:
    """Return a ``CameraInfo`` from image size (width, height) and D, K, R, P (any shape).

    Binning is 0 and the ROI empty (full resolution), as calibration files describe.
    """
    return CameraInfo(
        header=header if header is not None else Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        height=int(size[1]),
        width=int(size[0]),
        distortion_model=distortion_model,
        d=np.asarray(d, dtype=np.float64).reshape(-1).copy(),
        k=np.asarray(k, dtype=np.float64).reshape(9).copy(),
        r=np.asarray(r, dtype=np.float64).reshape(9).copy(),
        p=np.asarray(p, dtype=np.float64).reshape(12).copy(),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def _yaml_matrix(name: str, rows: int, cols: int, data: Any) -> list[str]:
    values = ", ".join(repr(float(v)) for v in np.asarray(data, dtype=np.float64).reshape(-1))
    return [f"{name}:", f"  rows: {rows}", f"  cols: {cols}", f"  data: [{values}]"]


def write_camera_info_yaml(
    path: str | os.PathLike[str],
    calibration: CalibrationLike | CameraInfo,
    *,
    camera_name: str | None = None,
) -> Path:
    """Write a calibration in the YAML format ROS's camera_calibration_parsers reads.

    Args:
        path: the output file; missing parent directories are created.
        calibration: a ``CameraInfo`` or a calibration result
            (:class:`~visnav.perception.calibration.CalibrationResult`).
        camera_name: overrides the result's name (a ``CameraInfo`` has none;
            default ``"camera"``).

    Returns:
        The path written.

    Raises:
        CalibrationError: the file cannot be written.
    """
    if isinstance(calibration, CameraInfo):
        info = calibration
        name = camera_name if camera_name is not None else "camera"
    else:
        info = calibration.to_camera_info()
        name = camera_name if camera_name is not None else calibration.camera_name
    d = np.asarray(info.d, dtype=np.float64).reshape(-1)
    lines = [
        f"image_width: {int(info.width)}",
        f"image_height: {int(info.height)}",
        f"camera_name: {_yaml_scalar(name)}",
        *_yaml_matrix("camera_matrix", 3, 3, info.k),
        f"distortion_model: {_yaml_scalar(info.distortion_model)}",
        *_yaml_matrix("distortion_coefficients", 1, int(d.size), d),
        *_yaml_matrix("rectification_matrix", 3, 3, info.r),
        *_yaml_matrix("projection_matrix", 3, 4, info.p),
    ]
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as exc:
        text = f"{out}: cannot write the calibration file: {exc}"
        raise CalibrationError(text) from exc
    return out


def _yaml_scalar(value: str) -> str:
    """Return ``value`` as a plain YAML scalar when that reads back unchanged, else quoted."""
    dumped = yaml.safe_dump(value, default_flow_style=True, width=10_000).strip()
    return dumped.removesuffix("...").strip()


def resolve_camera_info_url(url: str | os.PathLike[str], *, camera_name: str | None = None) -> Path:
    """Return the file a ``camera_info_url`` names, as camera_info_manager resolves it.

    ``file:///abs/camera.yaml`` and plain paths are files; ``${NAME}`` is replaced by
    ``camera_name`` and ``${ROS_HOME}`` by ``$ROS_HOME`` (default ``~/.ros``); an empty
    URL means ``${ROS_HOME}/camera_info/${NAME}.yaml``.

    Raises:
        CalibrationError: ``package://`` URLs (no ROS package index here), other
            schemes, or ``${NAME}`` without a camera name.
    """
    text = os.fspath(url)
    if text == "":
        text = "${ROS_HOME}/camera_info/${NAME}.yaml"
    ros_home = os.environ.get("ROS_HOME") or str(Path.home() / ".ros")
    text = text.replace("${ROS_HOME}", ros_home)
    if "${NAME}" in text:
        if not camera_name:
            msg = f"camera_info_url {os.fspath(url)!r} uses ${{NAME}}: pass camera_name"
            raise CalibrationError(msg)
        text = text.replace("${NAME}", camera_name)
    if text.startswith("file://"):
        return Path(text[len("file://") :])
    if text.startswith("package://"):
        msg = (
            f"camera_info_url {os.fspath(url)!r}: package:// URLs need a ROS package index, "
            "which visnav does not have; use file:///absolute/path.yaml or a plain path"
        )
        raise CalibrationError(msg)
    if re.match(r"^[A-Za-z][A-Za-z0-9+.-]*://", text):
        msg = f"camera_info_url {os.fspath(url)!r}: unsupported scheme; use file:// or a path"
        raise CalibrationError(msg)
    return Path(os.path.expanduser(text))  # noqa: PTH111 (Path.expanduser raises on "~user" with no such user)


def _matrix(doc: dict[str, Any], field: str, shape: tuple[int, int] | None, where: str) -> Any:
    node = doc[field]
    if not isinstance(node, dict) or not {"rows", "cols", "data"} <= set(node):
        text = f"{where}: field {field!r} must be a mapping with rows, cols and data"
        raise CalibrationError(text)
    rows, cols, data = node["rows"], node["cols"], node["data"]
    if not isinstance(rows, int) or not isinstance(cols, int) or rows < 0 or cols < 0:
        text = f"{where}: {field}.rows/cols are {rows!r}/{cols!r}: expected non-negative integers"
        raise CalibrationError(text)
    if shape is not None and (rows, cols) != shape:
        text = f"{where}: {field} is {rows}x{cols}: expected {shape[0]}x{shape[1]}"
        raise CalibrationError(text)
    if not isinstance(data, list) or len(data) != rows * cols:
        count = len(data) if isinstance(data, list) else type(data).__name__
        text = f"{where}: {field}.data has {count} values: expected rows * cols = {rows * cols}"
        raise CalibrationError(text)
    try:
        return np.asarray([float(v) for v in data], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        text = f"{where}: {field}.data holds a non-number: {exc}"
        raise CalibrationError(text) from exc


def load_calibration_yaml(
    path: str | os.PathLike[str], *, logger: WarningLogger | None = None
) -> tuple[str, CameraInfo]:
    """Read a ROS calibration YAML file; return (camera_name, CameraInfo).

    As camera_calibration_parsers: a missing ``camera_name`` reads as ``"unknown"``, a
    missing ``distortion_model`` as ``"plumb_bob"`` (with a warning); every other
    field is required.

    Args:
        path: a file path or ``file://`` URL (see :func:`resolve_camera_info_url`).
        logger: where the missing-distortion-model warning goes.

    Raises:
        CalibrationError: the file cannot be read, is not YAML, or a field is missing
            or malformed (the message names the file and the field).
    """
    file = resolve_camera_info_url(path)
    where = str(file)
    if file.suffix.lower() == ".ini":
        text = f"{where}: INI calibration files are not supported; use the YAML format"
        raise CalibrationError(text)
    doc = load_yaml_file(file, what="the camera_info YAML", error=CalibrationError)
    if not isinstance(doc, dict):
        text = f"{where}: expected a YAML mapping of calibration fields, got {type(doc).__name__}"
        raise CalibrationError(text)
    missing = [f for f in _REQUIRED_FIELDS if f not in doc]
    if missing:
        text = (
            f"{where}: missing field {missing[0]!r} (a ROS calibration file needs "
            f"{', '.join(_REQUIRED_FIELDS)})"
        )
        raise CalibrationError(text)
    width, height = doc["image_width"], doc["image_height"]
    for field, value in (("image_width", width), ("image_height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            text = f"{where}: {field} is {value!r}: expected a non-negative integer"
            raise CalibrationError(text)
    k = _matrix(doc, "camera_matrix", (3, 3), where)
    r = _matrix(doc, "rectification_matrix", (3, 3), where)
    p = _matrix(doc, "projection_matrix", (3, 4), where)
    d = _matrix(doc, "distortion_coefficients", None, where)
    model = doc.get("distortion_model")
    if model is None:
        (logger if logger is not None else default_logger()).warning(
            f"{where}: no distortion_model; assuming plumb_bob (as ROS does)"
        )
        model = "plumb_bob"
    camera_name = doc.get("camera_name")
    name = "unknown" if camera_name is None else str(camera_name)
    return name, camera_info_from_matrices((width, height), str(model), d, k, r, p)


def read_camera_info_yaml(
    path: str | os.PathLike[str], *, logger: WarningLogger | None = None
) -> CameraInfo:
    """Read a ROS calibration YAML file (path or ``file://`` URL) into a ``CameraInfo``.

    See :func:`load_calibration_yaml`, which also returns the camera name.
    """
    return load_calibration_yaml(path, logger=logger)[1]
