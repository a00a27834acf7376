"""Image checks on sampled frames: layout, encoding, RGB/BGR swap, black/blank/saturated, depth.

RGB/BGR swap heuristic (a warning, never an error; see ``docs/doctor.md``). Per sampled
8-bit colour frame, read in the order its encoding declares:

* known colour (``--expect`` ``known_color``): the region's mean colour is compared with
  the declared colour as is and with R and B exchanged; the closer one decides;
* sky: a bright, smooth top band (upper 20 % of rows) is blue in a real sky; a top band
  whose red exceeds blue by 25+ levels while green lies between them reads as a blue sky
  once R and B are exchanged, so it votes "swapped";
* ground: the lower third of natural and indoor scenes (soil, wood, grass, floors under
  warm light) has more red than blue; ``(mean R - mean B) / mean < -0.2`` votes
  "swapped" unless the sky cue says the frame is right.

The topic is reported when at least 60 % of its sampled frames vote "swapped". Limits:
blue floors or carpets, sunsets, underwater or strongly tinted scenes, and scenes with
neither sky nor ground in view fool or escape it; a ``known_color`` region is the
reliable way. Simulated worlds whose sky is black give the sky cue nothing to judge.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.doctor.context import CheckContext
from visnav.doctor.expect import KnownColor
from visnav.doctor.findings import Finding, Severity
from visnav.doctor.observation import TopicData
from visnav.msgs.errors import MessageError
from visnav.msgs.image import bytes_per_pixel, image_to_numpy

__all__ = ["check_images", "depth_values", "swap_votes"]

IMAGE = "sensor_msgs/msg/Image"
_COLOR8 = {"rgb8": (0, 1, 2), "rgba8": (0, 1, 2), "bgr8": (2, 1, 0), "bgra8": (2, 1, 0)}
_DEPTH = ("32FC1", "16UC1", "32FC", "16UC")
_STRIDE = 4  # statistics on every 4th row and column
_SHORT_FAR_CLIP_M = 1.0  # a depth far clip nearer than this is short for any navigation


def _layout_error(msg: Any) -> dict[str, Any] | None:
    """Return evidence when the image's encoding, step and data size disagree."""
    enc = str(msg.encoding)
    width, height, step = int(msg.width), int(msg.height), int(msg.step)
    size = len(msg.data)
    try:
        bpp = bytes_per_pixel(enc)
    except MessageError as exc:
        return {"encoding": enc, "problem": str(exc).split(";")[0]}
    row = width * bpp
    ev: dict[str, Any] = {
        "encoding": enc,
        "width": width,
        "height": height,
        "step": step,
        "data_bytes": size,
        "bytes_per_pixel": bpp,
    }
    if width == 0 or height == 0:
        ev["problem"] = "zero width or height"
        return ev
    if step < row:
        ev["problem"] = f"step {step} < width * bytes_per_pixel = {row}"
        return ev
    if size != step * height:
        ev["problem"] = f"data has {size} bytes, step * height = {step * height}"
        if size and size % height == 0 and size // height != step:
            ev["step_the_data_implies"] = size // height
            implied_bpp = size / (height * width)
            if implied_bpp != bpp:
                ev["bytes_per_pixel_the_data_implies"] = round(implied_bpp, 3)
        return ev
    return None


def _rgb(array: NDArray[Any], encoding: str) -> NDArray[np.float64]:
    order = _COLOR8[encoding]
    sub = array[::_STRIDE, ::_STRIDE]
    return np.stack([sub[..., i] for i in order], axis=-1).astype(np.float64)


def _band_mean(rgb: NDArray[np.float64], y0: float, y1: float) -> NDArray[np.float64]:
    h = rgb.shape[0]
    band = rgb[int(h * y0) : max(int(h * y1), int(h * y0) + 1)]
    return np.asarray(band.reshape(-1, 3).mean(axis=0), dtype=np.float64)


def swap_votes(
    rgb: NDArray[np.float64], known: KnownColor | None = None
) -> tuple[bool | None, dict[str, Any]]:
    """Vote on one frame (R, G, B order as declared): True swapped, False right, None unsure.

    Returns the vote and the cue values (evidence).
    """
    ev: dict[str, Any] = {}
    if known is not None:
        h, w = rgb.shape[:2]
        x0, y0, x1, y1 = known.region
        region = rgb[int(y0 * h) : max(int(y1 * h), int(y0 * h) + 1),
                     int(x0 * w) : max(int(x1 * w), int(x0 * w) + 1)]  # fmt: skip
        mean = region.reshape(-1, 3).mean(axis=0)
        want = np.asarray(known.rgb)
        as_is = float(np.linalg.norm(mean - want))
        swapped = float(np.linalg.norm(mean[::-1] - want))
        ev["known_color"] = {"declared": list(known.rgb), "measured": mean.round(1).tolist()}
        ev["cue"] = "known colour"
        if swapped < 0.5 * as_is and as_is > 40:
            return True, ev
        return False, ev
    top = _band_mean(rgb, 0.0, 0.2)
    h = rgb.shape[0]
    top_band = rgb[: max(1, int(h * 0.2))]
    smooth = float(top_band.std()) < 0.35 * max(float(top_band.mean()), 1.0)
    bright = float(top.mean()) > 0.35 * 255
    sky: bool | None = None
    if bright and smooth:
        r, g, b = (float(v) for v in top)
        if b - r > 25:
            sky = False
        elif r - b > 25 and r >= g >= b:
            sky = True
        ev["top_band_rgb"] = top.round(1).tolist()
    bottom = _band_mean(rgb, 2.0 / 3.0, 1.0)
    ground: bool | None = None
    level = float(bottom.mean())
    if level > 8:
        warmth = float(bottom[0] - bottom[2]) / level
        ev["bottom_band_rgb"] = bottom.round(1).tolist()
        ev["bottom_warmth"] = round(warmth, 3)
        if warmth < -0.2:
            ground = True
        elif warmth > 0.2:
            ground = False
    if sky is not None:
        ev["cue"] = "sky"
        return sky, ev
    if ground is not None:
        ev["cue"] = "ground"
    return ground, ev


def depth_values(
    array: NDArray[Any], encoding: str
) -> tuple[NDArray[np.float64], dict[str, float]]:
    """Valid depth values of a frame (finite, > 0, subsampled) and the invalid fractions."""
    sub = np.asarray(array[::_STRIDE, ::_STRIDE], dtype=np.float64)
    n = max(sub.size, 1)
    finite = np.isfinite(sub)
    stats = {
        "nan_fraction": float(np.isnan(sub).sum()) / n,
        "inf_fraction": float(np.isinf(sub).sum()) / n,
        "zero_fraction": float((sub == 0).sum()) / n,
    }
    valid = sub[finite & (sub > 0)]
    del encoding
    return valid, stats


def check_images(ctx: CheckContext) -> Iterator[Finding]:
    """Every image check on every Image topic."""
    for topic in ctx.topics_of_type(IMAGE):
        if topic.samples:
            yield from _check_topic(ctx, topic)


def _check_topic(ctx: CheckContext, topic: TopicData) -> Iterator[Finding]:
    name = topic.name
    frames: list[tuple[Any, NDArray[Any]]] = []
    bad: dict[str, Any] | None = None
    for s in topic.samples:
        problem = _layout_error(s.msg)
        if problem is not None:
            bad = bad or problem
            continue
        try:
            frames.append((s.msg, image_to_numpy(s.msg)))
        except MessageError as exc:
            bad = bad or {"encoding": s.msg.encoding, "problem": str(exc).split(";")[0]}
    if bad is not None:
        yield Finding(
            Severity.ERROR,
            "images.size_mismatch",
            f"{name}: encoding {bad.get('encoding')!r} does not fit the data: {bad['problem']}",
            {"topic": name, **bad},
            "set step = width * bytes_per_pixel(encoding) and send step * height bytes; "
            "check that the encoding names the pixel format the driver fills",
            name,
        )
    if not frames:
        return
    encoding = str(frames[-1][0].encoding)
    yield from _encoding(ctx, name, encoding)
    if encoding in _DEPTH:
        yield from _depth(ctx, name, encoding, [a for _, a in frames])
        return
    yield from _levels(name, encoding, [a for _, a in frames])
    if encoding in _COLOR8:
        exp = ctx.expected(name)
        yield from _swap(name, encoding, [a for _, a in frames], exp.known_color if exp else None)


def _encoding(ctx: CheckContext, name: str, encoding: str) -> Iterator[Finding]:
    decl = ctx.declared.get(name)
    if decl is None or decl.encoding is None or decl.encoding == encoding:
        return
    yield Finding(
        Severity.ERROR,
        "images.encoding_unexpected",
        f"{name} is {encoding}, declared {decl.encoding}",
        {
            "topic": name,
            "encoding": encoding,
            "declared": decl.encoding,
            "declared_by": decl.source,
        },
        f"publish {decl.encoding} (convert the data, not only the label) or correct the "
        "declaration; a consumer written for the declared encoding misreads these data",
        name,
    )


def _scale(array: NDArray[Any]) -> float:
    if array.dtype == np.uint8:
        return 255.0
    if array.dtype == np.uint16:
        return 65535.0
    return 1.0 if array.dtype.kind == "f" else float(np.iinfo(array.dtype).max)


def _levels(name: str, encoding: str, frames: list[NDArray[Any]]) -> Iterator[Finding]:
    black = blank = saturated = 0
    means, stds, sat_fracs = [], [], []
    for a in frames:
        sub = np.asarray(a[::_STRIDE, ::_STRIDE], dtype=np.float64)
        scale = _scale(a)
        mean, std = float(sub.mean()), float(sub.std())
        sat = float((sub >= 0.996 * scale).mean())
        means.append(mean / scale)
        stds.append(std / scale)
        sat_fracs.append(sat)
        if mean < 0.02 * scale and float(np.percentile(sub, 99)) < 0.05 * scale:
            black += 1
        elif sat > 0.5:
            saturated += 1
        elif std < 0.005 * scale:
            blank += 1
    n = len(frames)
    common = {"topic": name, "encoding": encoding, "frames_sampled": n}
    for check, count, what, fix in (
        (
            "images.black",
            black,
            "black",
            "check the exposure / gain, the lens cap, the lights of the scene, and that the "
            "driver copies pixels into the message",
        ),
        (
            "images.saturated",
            saturated,
            "saturated",
            "lower exposure or gain, or enable auto exposure",
        ),
        (
            "images.blank",
            blank,
            "uniform (no texture)",
            "the camera sees one flat colour or the driver sends a constant buffer: check the "
            "camera pose and the driver",
        ),
    ):
        if count:
            yield Finding(
                Severity.ERROR if count == n else Severity.WARNING,
                check,
                f"{name}: {count} of {n} sampled frames are {what}",
                {
                    **common,
                    "frames_affected": count,
                    "mean_level": round(float(np.mean(means)), 4),
                    "std_level": round(float(np.mean(stds)), 4),
                    "saturated_fraction": round(float(np.mean(sat_fracs)), 4),
                },
                fix,
                name,
            )


def _swap(
    name: str, encoding: str, frames: list[NDArray[Any]], known: KnownColor | None
) -> Iterator[Finding]:
    votes = []
    evidence: dict[str, Any] = {}
    for a in frames:
        vote, ev = swap_votes(_rgb(a, encoding), known)
        votes.append(vote)
        if vote:
            evidence = ev
    swapped = sum(1 for v in votes if v)
    if not swapped or swapped < 0.6 * len(votes):
        return
    other = {"rgb8": "bgr8", "bgr8": "rgb8", "rgba8": "bgra8", "bgra8": "rgba8"}[encoding]
    yield Finding(
        Severity.WARNING,
        "images.rgb_bgr_swap",
        f"{name}: colours look swapped (R and B): {encoding} data are probably {other}",
        {
            "topic": name,
            "encoding": encoding,
            "frames_voting_swapped": swapped,
            "frames_sampled": len(votes),
            **evidence,
        },
        f"if the driver fills {other[:3].upper()} order, publish encoding {other} (or convert "
        "with cv2.cvtColor); check the camera's pixel format (Gazebo <format> R8G8B8 vs "
        "B8G8R8). Heuristic: confirm by eye, or declare a known_color in --expect",
        name,
    )


def _depth(
    ctx: CheckContext, name: str, encoding: str, frames: list[NDArray[Any]]
) -> Iterator[Finding]:
    all_valid: list[NDArray[np.float64]] = []
    empty = 0
    fractions: dict[str, float] = {"nan_fraction": 0.0, "inf_fraction": 0.0, "zero_fraction": 0.0}
    for a in frames:
        valid, stats = depth_values(a, encoding)
        for k, v in stats.items():
            fractions[k] += v / len(frames)
        if valid.size < 0.001 * max(a[::_STRIDE, ::_STRIDE].size, 1):
            empty += 1
        else:
            all_valid.append(valid)
    n = len(frames)
    if empty:
        evidence: dict[str, Any] = {
            "topic": name,
            "encoding": encoding,
            "frames_sampled": n,
            "frames_without_depth": empty,
            **{k: round(v, 4) for k, v in fractions.items()},
        }
        fix = (
            "check the depth sensor's range (min/max depth, clip near/far) against the scene, "
            "and that the driver fills the buffer (NaN/0 mean 'no return')"
        )
        decl = ctx.declared.get(name)
        if decl is not None and decl.clip_far is not None and math.isfinite(decl.clip_far):
            evidence["declared_clip_far_m"] = decl.clip_far
            evidence["declared_by"] = decl.source
            if decl.clip_far < _SHORT_FAR_CLIP_M:
                fix = (
                    f"the sensor sees nothing beyond {decl.clip_far:g} m ({decl.source}): "
                    "raise <clip><far> (and the plugin's max_depth / pointCloudCutoffMax) to "
                    "the range of the real sensor, e.g. 10 m"
                )
        yield Finding(
            Severity.ERROR if empty == n else Severity.WARNING,
            "images.depth_invalid",
            f"{name}: {empty} of {n} sampled depth frames hold no valid depth",
            evidence,
            fix,
            name,
        )
    if all_valid:
        yield from _depth_unit(ctx, name, encoding, np.concatenate(all_valid))


def _depth_unit(
    ctx: CheckContext, name: str, encoding: str, values: NDArray[np.float64]
) -> Iterator[Finding]:
    med = float(np.median(values))
    p99 = float(np.percentile(values, 99))
    decl = ctx.declared.get(name)
    far = (
        decl.clip_far
        if decl is not None and decl.clip_far and math.isfinite(decl.clip_far)
        else None
    )
    exp = ctx.expected(name)
    wants = exp.depth_unit if exp is not None else None
    ev: dict[str, Any] = {
        "topic": name,
        "encoding": encoding,
        "median_value": round(med, 4),
        "p99_value": round(p99, 4),
    }
    if far is not None:
        ev["declared_clip_far_m"] = far
    if wants is not None:
        ev["consumer_expects"] = "32FC1 metres" if wants == "m" else "16UC1 millimetres"
    title = fix = None
    if encoding.startswith("32F"):
        limit = 5.0 * far if far is not None else 100.0
        if med > max(limit, 20.0):
            title = f"{name}: 32FC1 values look like millimetres (median {med:.4g})"
            fix = (
                "32FC1 depth is metres (REP 118): divide by 1000 in the publisher, or publish "
                "16UC1 if the data are integer millimetres"
            )
        elif wants == "mm":
            title = f"{name}: 32FC1 metres but the consumer expects 16UC1 millimetres"
            fix = (
                "publish 16UC1 millimetres (depth_image_proc convert_metric reversed), or "
                "configure the consumer for 32FC1 metres"
            )
    elif encoding.startswith("16U"):
        if med < 20.0 and p99 < 200.0:
            title = f"{name}: 16UC1 values look like metres (median {med:.4g})"
            fix = "16UC1 depth is millimetres: multiply by 1000 before the integer conversion"
        elif wants == "m":
            title = (
                f"{name}: 16UC1 values (median {med:.4g} mm) are ~1000x a 32FC1 consumer's range"
            )
            fix = (
                "convert to 32FC1 metres (depth_image_proc/convert_metric) before the consumer, "
                "or configure the consumer for 16UC1 millimetres"
            )
    if title is not None and fix is not None:
        yield Finding(Severity.ERROR, "images.depth_unit", title, ev, fix, name)
