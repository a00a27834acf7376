"""camera_info checks: K, size, field of view, distortion, and agreement with the image.

An image topic ``<ns>/<name>`` pairs with ``<ns>/camera_info`` (image_transport's rule).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.doctor.observation import TopicData

__all__ = ["D_LENGTHS", "check_camera_info", "info_topic_for"]

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"

D_LENGTHS = {"plumb_bob": (5,), "rational_polynomial": (8,), "equidistant": (4,)}
"""Distortion models and the lengths of D they take (image_geometry's models)."""

_FX_TOLERANCE = 0.02


def info_topic_for(image_topic: str) -> str:
    """The camera_info topic of an image topic (sibling ``camera_info``)."""
    return image_topic.rsplit("/", 1)[0] + "/camera_info"


def _pairs(ctx: CheckContext) -> list[tuple[TopicData, TopicData | None]]:
    out = []
    for image in ctx.topics_of_type(IMAGE):
        info = ctx.obs.topics.get(info_topic_for(image.name))
        out.append((image, info if info is not None and info.count else None))
    return out


def check_camera_info(ctx: CheckContext) -> Iterator[Finding]:
    """Every camera_info check."""
    paired: dict[str, TopicData] = {}
    names = ctx.all_topic_names()
    for image, info in _pairs(ctx):
        if info is None:
            expected = info_topic_for(image.name)
            if expected not in names:
                yield Finding(
                    Severity.INFO,
                    "camera_info.missing",
                    f"{image.name} has no camera_info ({expected} does not exist)",
                    {"image_topic": image.name, "expected_camera_info": expected},
                    f"publish the calibration on {expected} (same header as each image) if "
                    "anything projects or rectifies these images",
                    image.name,
                )
            continue
        paired[info.name] = image
        yield from _pair(ctx, image, info)
        yield from _unrectified_consumers(ctx, image, info)
    for info in ctx.topics_of_type(CAMERA_INFO):
        if info.samples:
            yield from _intrinsics(ctx, info, paired.get(info.name))


def _rect_needed(ctx: CheckContext, info: TopicData) -> tuple[bool, str]:
    ns = info.name.rsplit("/", 1)[0]
    exp = ctx.expected(info.name)
    if exp is not None and exp.rectify:
        return True, "--expect rectify: true"
    for name in sorted(ctx.all_topic_names()):
        if name.startswith(ns + "/image_rect"):
            return True, f"{name} exists"
    return False, ""


_NOT_CONSUMERS = ("record", "rviz", "viewer", "image_view", "rqt", "rerun")
"""Node names that show or store images without using their geometry."""


def _unrectified_consumers(
    ctx: CheckContext, image: TopicData, info: TopicData
) -> Iterator[Finding]:
    """A node reads distorted raw images while no rectified topic exists (live graph only).

    SLAM, feature tracking and projection assume a pinhole: on a lens with distortion
    they need ``image_rect`` (image_proc's rectify), or their own undistortion.
    """
    if not info.samples or "image_raw" not in image.name.rsplit("/", 1)[-1]:
        return
    msg = info.samples[-1].msg
    d = np.asarray(msg.d, dtype=np.float64).reshape(-1)
    if not d.size or not np.any(d != 0.0):
        return
    ns = image.name.rsplit("/", 1)[0]
    if any(name.startswith(ns + "/image_rect") for name in ctx.all_topic_names()):
        return
    readers = sorted(
        {
            e.node_fqn
            for e in ctx.endpoints(image.name, "subscription")
            if not any(word in e.node_name.lower() for word in _NOT_CONSUMERS)
        }
    )
    if not readers:
        return
    yield Finding(
        Severity.WARNING,
        "camera_info.unrectified_consumer",
        f"{', '.join(readers)} read(s) {image.name}, distorted ({msg.distortion_model} "
        f"D={np.round(d, 4).tolist()}), and no {ns}/image_rect exists",
        {
            "image_topic": image.name,
            "camera_info_topic": info.name,
            "consumers": readers,
            "distortion_model": str(msg.distortion_model),
            "d": d.tolist(),
            "expected_rectified_topic": f"{ns}/image_rect",
        },
        f"run image_proc in namespace {ns or '/'} (it publishes {ns}/image_rect from "
        f"{image.name} and {info.name}) and remap the consumers' input to {ns}/image_rect, "
        "or make sure each consumer undistorts with D itself",
        image.name,
    )


def _intrinsics(ctx: CheckContext, info: TopicData, image: TopicData | None) -> Iterator[Finding]:
    name = info.name
    msg = info.samples[-1].msg
    k = np.asarray(msg.k, dtype=np.float64).reshape(-1)
    p = np.asarray(msg.p, dtype=np.float64).reshape(-1)
    d = np.asarray(msg.d, dtype=np.float64).reshape(-1)
    width, height = int(msg.width), int(msg.height)
    img_w = img_h = None
    if image is not None and image.samples:
        img_w, img_h = int(image.samples[-1].msg.width), int(image.samples[-1].msg.height)
    base: dict[str, Any] = {"topic": name, "k": k.tolist(), "width": width, "height": height}
    if k.size != 9 or not np.any(k):
        yield Finding(
            Severity.ERROR,
            "camera_info.k_zero",
            f"{name}: K is all zero (camera not calibrated)",
            base,
            "calibrate the camera (visnav calibrate) and load the YAML in the driver, or set "
            "K from the field of view: fx = fy = width / (2 tan(hfov / 2)), cx, cy = centre",
            name,
        )
        return
    if p.size == 12 and not np.any(p):
        yield Finding(
            Severity.ERROR,
            "camera_info.k_zero",
            f"{name}: P is all zero while K is set (rectified projection missing)",
            {**base, "p": p.tolist()},
            "fill P (for an unrectified monocular camera P = [K | 0]); image_proc and "
            "depth_image_proc project with P",
            name,
        )
    fx, fy, cx, cy = float(k[0]), float(k[4]), float(k[2]), float(k[5])
    yield from _size(name, base, (fx, fy, cx, cy), (width, height), (img_w, img_h))
    yield from _fov(ctx, name, image, fx, width or img_w or 0)
    yield from _distortion(ctx, info, str(msg.distortion_model), d)


def _size(
    name: str,
    base: dict[str, Any],
    kvals: tuple[float, float, float, float],
    info_size: tuple[int, int],
    image_size: tuple[int | None, int | None],
) -> Iterator[Finding]:
    fx, fy, cx, cy = kvals
    width, height = info_size
    img_w, img_h = image_size
    problems = []
    if img_w is not None and (width, height) != (img_w, img_h):
        problems.append(f"camera_info is {width}x{height} but the images are {img_w}x{img_h}")
    w = img_w or width
    h = img_h or height
    if fx <= 0 or fy <= 0:
        problems.append(f"fx {fx:g}, fy {fy:g} must be > 0")
    if w and h and not (0 < cx < w and 0 < cy < h):
        problems.append(f"principal point ({cx:g}, {cy:g}) lies outside the {w}x{h} image")
    elif w and h and (abs(cx - w / 2) > 0.2 * w or abs(cy - h / 2) > 0.2 * h):
        problems.append(
            f"principal point ({cx:g}, {cy:g}) is far from the centre ({w / 2:g}, {h / 2:g}): "
            "K of another resolution?"
        )
    if problems:
        yield Finding(
            Severity.ERROR,
            "camera_info.k_vs_size",
            f"{name}: K does not fit the image size: {problems[0]}",
            {**base, "image_width": img_w, "image_height": img_h, "problems": problems},
            "publish the calibration made at this resolution (scale fx, fy, cx, cy by the "
            "resolution ratio if the driver bins or crops), and set width/height to the images'",
            name,
        )


def _fov(
    ctx: CheckContext, name: str, image: TopicData | None, fx: float, width: int
) -> Iterator[Finding]:
    decl = ctx.declared.get(name)
    if (decl is None or decl.hfov is None) and image is not None:
        decl = ctx.declared.get(image.name)
    if decl is None or decl.hfov is None or width <= 0 or fx <= 0:
        return
    expected = width / (2.0 * math.tan(decl.hfov / 2.0))
    rel = fx / expected - 1.0
    if abs(rel) <= _FX_TOLERANCE:
        return
    implied = 2.0 * math.atan(width / (2.0 * fx))
    yield Finding(
        Severity.ERROR,
        "camera_info.fx_vs_fov",
        f"{name}: fx {fx:.4g} implies a {math.degrees(implied):.1f} deg field of view, "
        f"declared {math.degrees(decl.hfov):.1f} deg",
        {
            "topic": name,
            "fx": round(fx, 4),
            "width": width,
            "declared_hfov_rad": round(decl.hfov, 6),
            "expected_fx": round(expected, 4),
            "implied_hfov_rad": round(implied, 6),
            "declared_by": decl.source,
        },
        f"set fx = fy = width / (2 tan(hfov / 2)) = {expected:.4g}, or correct the declared "
        "horizontal_fov (hfov in radians, not degrees)",
        name,
    )


def _distortion(
    ctx: CheckContext, info: TopicData, model: str, d: np.ndarray[Any, Any]
) -> Iterator[Finding]:
    name = info.name
    ev = {"topic": name, "distortion_model": model, "d_length": int(d.size), "d": d.tolist()}
    lengths = D_LENGTHS.get(model)
    if lengths is not None:
        if d.size not in lengths:
            yield Finding(
                Severity.ERROR,
                "camera_info.d_length",
                f"{name}: {model} takes {lengths[0]} coefficients, D has {d.size}",
                {**ev, "expected_length": lengths[0]},
                f"publish D with {lengths[0]} values for {model} "
                f"({'k1, k2, p1, p2, k3' if model == 'plumb_bob' else 'the model order'}), "
                "or name the model the coefficients belong to",
                name,
            )
        return
    needed, why = _rect_needed(ctx, info)
    if not model and not d.size and not needed:
        return
    if needed or d.size:
        severity = Severity.ERROR if needed else Severity.WARNING
        title = f"{name}: distortion_model {model!r} is unknown, " + (
            "but the images are rectified" if needed else f"D has {d.size} values"
        )
        yield Finding(
            severity,
            "camera_info.distortion_unknown",
            title,
            {**ev, "rectification_needed": needed, **({"because": why} if why else {})},
            "set distortion_model to plumb_bob (5 values), rational_polynomial (8) or "
            "equidistant (4) with matching D; use plumb_bob with zeros for an ideal lens",
            name,
        )
    elif model:
        yield Finding(
            Severity.WARNING,
            "camera_info.distortion_unknown",
            f"{name}: distortion_model {model!r} is not one image_geometry knows",
            ev,
            "use plumb_bob, rational_polynomial or equidistant",
            name,
        )


def _pair(ctx: CheckContext, image: TopicData, info: TopicData) -> Iterator[Finding]:
    img_frame, info_frame = image.frame_id, info.frame_id
    if img_frame != info_frame:
        yield Finding(
            Severity.ERROR,
            "camera_info.frame_mismatch",
            f"{image.name} is in '{img_frame}' but {info.name} in '{info_frame}'",
            {
                "image_topic": image.name,
                "image_frame_id": img_frame,
                "camera_info_topic": info.name,
                "camera_info_frame_id": info_frame,
            },
            "publish camera_info with the image's header (same frame_id and stamp)",
            image.name,
        )
    if not (image.has_stamps and info.has_stamps) or image.count < 3 or info.count < 3:
        return
    info_stamps = np.unique(info.stamp_ns)
    lo, hi = int(info_stamps[0]), int(info_stamps[-1])
    img = image.stamp_ns[(image.stamp_ns >= lo) & (image.stamp_ns <= hi)]
    if img.size < 3:
        img = image.stamp_ns
    idx = np.clip(np.searchsorted(info_stamps, img), 1, max(info_stamps.size - 1, 1))
    left = info_stamps[idx - 1]
    right = info_stamps[np.minimum(idx, info_stamps.size - 1)]
    nearest = np.minimum(np.abs(img - left), np.abs(img - right))
    matched = float((nearest == 0).mean())
    if matched >= 0.9:
        return
    yield Finding(
        Severity.ERROR,
        "camera_info.stamp_mismatch",
        f"{image.name} and {info.name} stamps do not match ({matched:.0%} of images have a "
        "camera_info with the same stamp)",
        {
            "image_topic": image.name,
            "camera_info_topic": info.name,
            "matched_fraction": round(matched, 3),
            "median_offset_s": round(float(np.median(nearest)) / 1e9, 6),
            "max_offset_s": round(float(nearest.max()) / 1e9, 6),
        },
        "stamp each camera_info with its image's header.stamp (copy the header): exact-time "
        "synchronisers (image_transport CameraSubscriber, image_proc) drop unmatched pairs",
        image.name,
    )
