"""Monocular chessboard calibration and the ROS camera_info YAML format.

:func:`calibrate_from_images` does what ROS's ``camera_calibration`` does for one
camera: find the chessboard's inner corners (``cv2.findChessboardCorners`` +
``cv2.cornerSubPix``), solve ``cv2.calibrateCamera`` and derive the projection
matrix with ``cv2.getOptimalNewCameraMatrix`` (``R`` is the identity). As in ROS,
``pattern`` counts *inner* corners (columns x rows, ``9x6`` for a board of 10 x 7
squares), ``square`` is the side of one square in metres, and by default two
radial coefficients are estimated (``k3`` fixed at 0, ROS's ``--k-coefficients 2``).

Where it differs from ROS, on purpose (measured on OpenCV's sample chessboards
``left01..14.jpg``, whose OpenCV tutorial pipeline gives RMS 0.409 px, fx 536.5):

* the ``cornerSubPix`` window is OpenCV's 11 px half-size capped at 0.4 x the corner
  spacing (:func:`~visnav.perception.chessboard.refine_radius`); ROS's half-spacing
  window reaches the neighbouring squares on small boards (RMS 1.32 px, fx 553.8,
  cx 9 px off); visnav gives RMS 0.245 px, fx 534.3;
* views that cannot determine the focal length are refused instead of giving a wrong
  K (:mod:`~visnav.perception.calibration_views`: repeated poses, boards parallel to
  the image plane);
* images above 64 MP are refused from their file header before decoding
  (:mod:`~visnav.perception.calibration_images`); large ones are searched on a
  ~1280 x 960 copy (ROS: ~640 x 480) and refined at full resolution.

:func:`write_camera_info_yaml` and :func:`read_camera_info_yaml` use the YAML
layout of ``camera_calibration_parsers`` (what ``camera_info_url`` files hold)::

    image_width: 640
    image_height: 480
    camera_name: narrow_stereo
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [...]}
    projection_matrix: {rows: 3, cols: 4, data: [...]}

:func:`calibrate` is the library function behind ``visnav calibrate``: images from
a directory, a bag or a live topic, an optional YAML output.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.types import CameraInfo, Header, Image
from visnav.perception._calibration_common import (
    CalibrationError,
    WarningLogger,
    default_logger,
)
from visnav.perception.calibration_images import read_gray_image
from visnav.perception.calibration_sources import (
    IMAGE_EXTENSIONS,
    SpinUntil,
    collect_views_from_topic,
    images_from_bag,
    list_image_files,
    select_views,
)
from visnav.perception.calibration_views import check_views
from visnav.perception.camera_info_yaml import (
    camera_info_from_matrices,
    load_calibration_yaml,
    read_camera_info_yaml,
    resolve_camera_info_url,
    write_camera_info_yaml,
)
from visnav.perception.chessboard import (
    check_image_size,
    find_chessboard,
    image_message_gray,
    object_points,
    parse_pattern,
    to_gray,
)

__all__ = [
    "IMAGE_EXTENSIONS",
    "CalibrationError",
    "CalibrationResult",
    "ImageSource",
    "calibrate",
    "calibrate_from_images",
    "find_chessboard",
    "images_from_bag",
    "list_image_files",
    "load_calibration_yaml",
    "parse_pattern",
    "read_camera_info_yaml",
    "resolve_camera_info_url",
    "select_views",
    "write_camera_info_yaml",
]

ImageSource = str | os.PathLike[str] | NDArray[Any] | Image | tuple[str, NDArray[Any]]
"""One calibration image: a file, a BGR/gray array, an Image message or (name, array)."""


@dataclasses.dataclass(frozen=True)
class CalibrationResult:
    """The outcome of a chessboard calibration.

    Attributes:
        camera_name: written to the YAML ``camera_name``.
        image_size: (width, height) in pixels.
        K: 3x3 camera matrix.
        D: distortion coefficients (5 for plumb_bob, 8 for rational_polynomial).
        R: 3x3 rectification matrix (identity for a monocular camera).
        P: 3x4 projection matrix ``[K' | 0]`` of the rectified image.
        distortion_model: ``"plumb_bob"`` or ``"rational_polynomial"``.
        rms: overall RMS reprojection error in pixels (``cv2.calibrateCamera``'s).
        per_image_errors: (image name, RMS reprojection error in px) per used view.
        rejected: (image name, reason) per image that was not used.
        pattern: inner corners (columns, rows).
        square: square size in metres.
    """

    camera_name: str
    image_size: tuple[int, int]
    K: NDArray[np.float64]
    D: NDArray[np.float64]
    R: NDArray[np.float64]
    P: NDArray[np.float64]
    distortion_model: str
    rms: float
    per_image_errors: tuple[tuple[str, float], ...]
    rejected: tuple[tuple[str, str], ...]
    pattern: tuple[int, int]
    square: float

    def to_camera_info(self, header: Header | None = None) -> CameraInfo:
        """Return the calibration as a ``sensor_msgs/CameraInfo``."""
        return camera_info_from_matrices(
            self.image_size,
            self.distortion_model,
            self.D,
            self.K,
            self.R,
            self.P,
            header=header,
        )

    def summary(self) -> str:
        """Return a human-readable report: RMS, intrinsics and per-image errors."""
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        lines = [
            f"camera {self.camera_name!r}: {self.image_size[0]}x{self.image_size[1]}, "
            f"{len(self.per_image_errors)} views, chessboard {self.pattern[0]}x{self.pattern[1]}"
            f" inner corners, {self.square} m squares",
            f"RMS reprojection error: {self.rms:.4f} px",
            f"fx {fx:.3f}  fy {fy:.3f}  cx {cx:.3f}  cy {cy:.3f}",
            f"{self.distortion_model}: " + ", ".join(f"{v:.6g}" for v in self.D),
            "per-image RMS error (px):",
        ]
        lines += [f"  {name}: {err:.4f}" for name, err in self.per_image_errors]
        if self.rejected:
            lines.append("not used:")
            lines += [f"  {name}: {reason}" for name, reason in self.rejected]
        return "\n".join(lines)


# ------------------------------------------------------------- calibration


def _load(source: ImageSource, index: int) -> tuple[str, NDArray[np.uint8]]:
    """Return (display name, gray uint8 pixels) of one calibration image."""
    if isinstance(source, tuple):
        name, array = source
        return str(name), _sized(to_gray(array, str(name)), str(name))
    if isinstance(source, np.ndarray):
        name = f"image {index}"
        return name, _sized(to_gray(source, name), name)
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        return path.name, read_gray_image(path)
    if hasattr(source, "encoding") and hasattr(source, "data"):
        name = f"image {index}"
        return name, _sized(image_message_gray(source, name), name)
    text = f"image {index} is a {type(source).__name__}: expected a path, an array or an Image"
    raise CalibrationError(text)


def _sized(gray: NDArray[np.uint8], name: str) -> NDArray[np.uint8]:
    check_image_size(int(gray.shape[1]), int(gray.shape[0]), name)
    return gray


def _calibration_flags(distortion_model: str, k_coefficients: int) -> int:
    if distortion_model == "plumb_bob":
        if not 0 <= k_coefficients <= 3:
            text = f"k_coefficients is {k_coefficients!r}: plumb_bob estimates 0 to 3 radial terms"
            raise CalibrationError(text)
        flags = 0
    elif distortion_model == "rational_polynomial":
        if not 0 <= k_coefficients <= 6:
            text = (
                f"k_coefficients is {k_coefficients!r}: rational_polynomial estimates 0 to 6 "
                "radial terms"
            )
            raise CalibrationError(text)
        flags = cv2.CALIB_RATIONAL_MODEL
    else:
        text = (
            f"distortion_model is {distortion_model!r}: expected 'plumb_bob' or "
            "'rational_polynomial'"
        )
        raise CalibrationError(text)
    fixed = [cv2.CALIB_FIX_K1, cv2.CALIB_FIX_K2, cv2.CALIB_FIX_K3]
    fixed += [cv2.CALIB_FIX_K4, cv2.CALIB_FIX_K5, cv2.CALIB_FIX_K6]
    limit = 3 if distortion_model == "plumb_bob" else 6
    for i in range(k_coefficients, limit):
        flags |= fixed[i]
    return flags


def calibrate_from_images(
    images: Iterable[ImageSource],
    pattern: str | Sequence[int] = (9, 6),
    square: float = 0.025,
    *,
    camera_name: str = "camera",
    distortion_model: str = "plumb_bob",
    k_coefficients: int = 2,
    fix_principal_point: bool = False,
    fix_aspect_ratio: bool = False,
    zero_tangent_dist: bool = False,
    alpha: float = 0.0,
    min_views: int = 5,
    check_degenerate: bool = True,
    logger: WarningLogger | None = None,
) -> CalibrationResult:
    """Calibrate one camera from chessboard views.

    Args:
        images: image files, BGR/gray arrays, ``Image`` messages or (name, array).
        pattern: inner corners, ``"9x6"`` or (columns, rows).
        square: side of one square in metres (> 0).
        camera_name: the name stored in the result (and the YAML).
        distortion_model: ``"plumb_bob"`` (5 coefficients) or ``"rational_polynomial"`` (8).
        k_coefficients: radial terms to estimate (ROS's ``--k-coefficients``, default 2:
            k3 and higher fixed at 0).
        fix_principal_point: keep cx, cy at the image centre.
        fix_aspect_ratio: estimate fx with fy = fx.
        zero_tangent_dist: fix p1 = p2 = 0.
        alpha: 0 keeps only valid pixels in the rectified image (P), 1 keeps all
            source pixels (``cv2.getOptimalNewCameraMatrix``).
        min_views: fewest usable views to attempt a calibration (distinct board poses).
        check_degenerate: refuse views that cannot determine the focal length (see
            :func:`visnav.perception.calibration_views.check_views`: repeated board
            poses, or every board nearly parallel to the image plane) instead of
            returning a wrong K.
        logger: where per-image warnings go (default this module's logger).

    Returns:
        The :class:`CalibrationResult`.

    Raises:
        CalibrationError: an unreadable or oversized image, fewer than ``min_views``
            usable views, degenerate views, or invalid parameters. Views of another size
            than most views are skipped with one warning each (not used in the result).
    """
    pattern = parse_pattern(pattern)
    if isinstance(square, bool) or not isinstance(square, (int, float)) or not square > 0:
        text = f"square is {square!r}: expected the square side in metres, > 0 (e.g. 0.025)"
        raise CalibrationError(text)
    if not 0.0 <= alpha <= 1.0:
        text = f"alpha is {alpha!r}: expected a number in [0, 1]"
        raise CalibrationError(text)
    flags = _calibration_flags(distortion_model, k_coefficients)
    if fix_principal_point:
        flags |= cv2.CALIB_FIX_PRINCIPAL_POINT
    if fix_aspect_ratio:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    if zero_tangent_dist:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    log: WarningLogger = logger if logger is not None else default_logger()

    size: tuple[int, int] | None = None
    # Board views by image size: the size with the most views is calibrated, the others
    # are skipped with a warning each (a folder may hold a stray image of another size).
    views: dict[tuple[int, int], list[tuple[str, NDArray[np.float32]]]] = {}
    rejected: list[tuple[str, str]] = []
    total = 0
    for index, source in enumerate(images):
        total += 1
        name, gray = _load(source, index)
        this_size = (int(gray.shape[1]), int(gray.shape[0]))
        size = this_size if size is None else size
        corners, reason = find_chessboard(gray, pattern)
        if corners is None:
            log.warning(f"{name}: {reason}; image skipped")
            rejected.append((name, reason))
            continue
        views.setdefault(this_size, []).append((name, corners))
    if views:
        size = max(views, key=lambda s: len(views[s]))  # ties: the size seen first
        for other, others in views.items():
            if other == size:
                continue
            for name, _ in others:
                reason = (
                    f"image is {other[0]}x{other[1]} but {len(views[size])} views are "
                    f"{size[0]}x{size[1]}: one calibration is of one camera mode"
                )
                log.warning(f"{name}: {reason}; image skipped")
                rejected.append((name, reason))
    names = [name for name, _ in views.get(size or (0, 0), [])]
    image_points = [corners for _, corners in views.get(size or (0, 0), [])]
    if size is None or len(image_points) < min_views:
        text = (
            f"only {len(image_points)} of {total} images show the full {pattern[0]}x{pattern[1]} "
            f"chessboard{_common_reason(rejected)}: at least {min_views} views are needed. "
            "Check --pattern (inner corners, columns x rows), that the whole board is visible, "
            "and vary its position, tilt and distance"
        )
        raise CalibrationError(text)
    if check_degenerate:
        check_views(names, image_points, pattern, min_views=min_views, logger=log)
    return _solve(
        names,
        image_points,
        size,
        pattern,
        float(square),
        flags=flags,
        distortion_model=distortion_model,
        camera_name=camera_name,
        alpha=alpha,
        rejected=rejected,
    )


def _common_reason(rejected: list[tuple[str, str]]) -> str:
    """`` (N rejected: reason)`` for the most frequent rejection reason, or ""."""
    if not rejected:
        return ""
    reasons = [reason for _, reason in rejected]
    top = max(set(reasons), key=reasons.count)
    return f" ({reasons.count(top)} rejected: {top})"


def _solve(
    names: list[str],
    image_points: list[NDArray[np.float32]],
    size: tuple[int, int],
    pattern: tuple[int, int],
    square: float,
    *,
    flags: int,
    distortion_model: str,
    camera_name: str,
    alpha: float,
    rejected: list[tuple[str, str]],
) -> CalibrationResult:
    objp = object_points(pattern, square)
    board = [objp] * len(image_points)
    n_coeffs = 8 if distortion_model == "rational_polynomial" else 5
    k0 = np.eye(3)
    d0 = np.zeros(n_coeffs)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-9)
    try:
        rms, k, d, rvecs, tvecs = cv2.calibrateCamera(
            board,
            [p.reshape(-1, 1, 2) for p in image_points],
            size,
            k0,
            d0,
            flags=flags,
            criteria=criteria,
        )
    except cv2.error as exc:
        text = f"cv2.calibrateCamera failed on {len(image_points)} views: {exc}"
        raise CalibrationError(text) from exc
    k_mat: NDArray[np.float64] = np.asarray(k, dtype=np.float64)
    d_vec: NDArray[np.float64] = np.asarray(d, dtype=np.float64).reshape(-1)[:n_coeffs]
    if d_vec.size < n_coeffs:
        d_vec = np.concatenate([d_vec, np.zeros(n_coeffs - d_vec.size)])
    errors = []
    for name, pts, rvec, tvec in zip(names, image_points, rvecs, tvecs, strict=True):
        projected, _ = cv2.projectPoints(objp, rvec, tvec, k_mat, d_vec)
        residual = projected.reshape(-1, 2) - pts
        errors.append((name, float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))))
    new_k, _ = cv2.getOptimalNewCameraMatrix(k_mat, d_vec, size, alpha)
    p = np.zeros((3, 4))
    p[:, :3] = np.asarray(new_k, dtype=np.float64)
    return CalibrationResult(
        camera_name=camera_name,
        image_size=size,
        K=k_mat,
        D=d_vec,
        R=np.eye(3),
        P=p,
        distortion_model=distortion_model,
        rms=float(rms),
        per_image_errors=tuple(errors),
        rejected=tuple(rejected),
        pattern=pattern,
        square=square,
    )


def calibrate(
    *,
    images: str | os.PathLike[str] | Sequence[ImageSource] | None = None,
    bag: str | os.PathLike[str] | None = None,
    topic: str | None = None,
    node: Any = None,
    spin_until: SpinUntil | None = None,
    pattern: str | Sequence[int] = (9, 6),
    square: float = 0.025,
    output: str | os.PathLike[str] | None = None,
    camera_name: str | None = None,
    max_views: int = 40,
    min_view_distance: float = 0.2,
    timeout_s: float = 60.0,
    logger: WarningLogger | None = None,
    **options: Any,
) -> CalibrationResult:
    """Calibrate from a directory, a bag or a live topic; optionally write the YAML.

    The library function behind ``visnav calibrate --images DIR | --topic T | --bag B
    --pattern 9x6 --square 0.025 [-o camera.yaml]``. Give exactly one source:

    * ``images``: a directory (every image file in it is used) or a list of images;
    * ``bag`` and ``topic``: Image or CompressedImage messages of ``topic`` in a bag;
    * ``topic`` with ``node`` and ``spin_until`` (e.g. ``context.spin_until``): a live
      topic (``image_raw`` or ``image_raw/compressed``), until ``max_views`` views
      are collected or ``timeout_s`` passes.

    Bag and topic frames are thinned as ROS's calibrator does: a frame is used only
    if its board position, size or tilt differs from every view kept so far
    (L1 distance > ``min_view_distance``).

    Args:
        images: see above.
        bag: see above.
        topic: see above.
        node: a ``visnav.graph.Node`` for the live topic.
        spin_until: ``spin_until(predicate, timeout_s)`` that runs the node's callbacks.
        pattern: inner corners, ``"9x6"`` or (columns, rows).
        square: square side in metres.
        output: write the calibration YAML here.
        camera_name: stored in the YAML (default ``"camera"``).
        max_views: most views taken from a bag or topic.
        min_view_distance: how different a bag/topic view must be to be kept.
        timeout_s: how long to listen to a live topic.
        logger: where warnings go.
        **options: passed to :func:`calibrate_from_images` (``distortion_model``,
            ``k_coefficients``, ``fix_principal_point``, ``alpha``, ``min_views``...).

    Returns:
        The :class:`CalibrationResult` (print :meth:`CalibrationResult.summary`).

    Raises:
        CalibrationError: no or several sources, or any calibration error.
    """
    pattern = parse_pattern(pattern)
    name = camera_name if camera_name is not None else "camera"
    live = topic is not None and bag is None
    chosen = [
        s
        for s, given in (("images", images is not None), ("bag", bag is not None), ("topic", live))
        if given
    ]
    if len(chosen) != 1:
        text = (
            f"calibrate needs exactly one image source (images=DIR, bag=B with topic=T, or a "
            f"live topic=T); got {chosen or 'none'}"
        )
        raise CalibrationError(text)
    sources: Iterable[ImageSource]
    if images is not None:
        if isinstance(images, (str, os.PathLike)):
            sources = list_image_files(images)
        else:
            sources = list(images)
    elif bag is not None:
        if topic is None:
            text = f"{bag}: pass topic=... to say which image topic of the bag to use"
            raise CalibrationError(text)
        sources = select_views(
            images_from_bag(bag, topic),
            pattern,
            max_views=max_views,
            min_view_distance=min_view_distance,
        )
    else:
        if node is None or spin_until is None or topic is None:
            text = (
                f"calibrating from the live topic {topic!r} needs node= and spin_until= "
                "(a running graph)"
            )
            raise CalibrationError(text)
        sources = collect_views_from_topic(
            node,
            spin_until,
            topic,
            pattern,
            max_views=max_views,
            min_view_distance=min_view_distance,
            timeout_s=timeout_s,
        )
    result = calibrate_from_images(
        sources, pattern, square, camera_name=name, logger=logger, **options
    )
    if output is not None:
        write_camera_info_yaml(output, result)
    return result
