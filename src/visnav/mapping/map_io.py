"""Map files in map_server's format: a YAML description beside a PGM (or PNG) image.

Writing follows ROS 1 ``map_saver`` (noetic): the image is an 8-bit binary PGM (``P5``)
with the comment ``# CREATOR: map_saver.cpp <resolution> m/pix``, the grid's row 0 (its
bottom, at ``origin``) as the image's last row; a cell ``0 <= v <= free`` (25) is 254
(free, white), ``v >= occupied`` (65) is 0 (occupied, black) and anything else (-1,
unknown) is 205. The YAML holds ``image``, ``resolution``, ``origin: [x, y, yaw]``,
``negate: 0``, ``occupied_thresh: 0.65`` and ``free_thresh: 0.196``.

Reading follows ``map_server``'s ``image_loader``: each pixel's channel mean ``c`` (with
``negate``, ``255 - c``) gives ``occ = (255 - c) / 255``; ``occ > occupied_thresh`` is 100,
``occ < free_thresh`` is 0, otherwise -1 in ``trinary`` mode (the default), in ``scale``
mode ``99 * (occ - free) / (occupied - free)`` truncated (-1 where the alpha channel is
0), and in ``raw`` mode the cell is ``c`` itself (as a signed byte, so 255 is -1). A
relative ``image`` is relative to the YAML file.

Where visnav differs, and why:

* the YAML's ``image`` is the PGM's file name, not the ``-f`` path as given (ROS 1
  writes ``maps/x.pgm`` for ``-f maps/x``, which map_server then resolves against
  ``maps/`` and cannot find); nav2's map_saver writes the file name too;
* bad files are refused with one line naming the file and field (map_server prints an
  error and exits or, for odd thresholds, loads a wrong map): a missing key or image,
  ``resolution <= 0``, an origin that is not 3 numbers, ``negate`` not 0/1, thresholds
  not ``0 <= free_thresh < occupied_thresh <= 1``, a PGM whose header disagrees with its
  data, and a PGM whose ``m/pix`` comment disagrees with the YAML's resolution;
* in ``scale`` mode only a real alpha channel can mark a cell unknown (map_server reads
  the last channel of an RGB image as alpha).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from visnav.mapping.errors import MappingError
from visnav.safe_yaml import load_yaml_file
from visnav.tf.errors import InvalidArgumentException
from visnav.tf.transforms import quaternion_from_yaw, yaw_from_quaternion

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from visnav.msgs.types import OccupancyGrid

__all__ = [
    "MapFileError",
    "MapMetadata",
    "OccupancyMap",
    "grid_to_pgm_pixels",
    "load_map",
    "pixels_to_grid",
    "read_map_yaml",
    "read_pgm",
    "save_map",
    "write_pgm",
]

MapMode = Literal["trinary", "scale", "raw"]
_MODES: tuple[MapMode, ...] = ("trinary", "scale", "raw")
_CREATOR = re.compile(rb"#\s*CREATOR:.*?([0-9.]+)\s*m/pix")


class MapFileError(MappingError, ValueError):
    """A map YAML or image that cannot be read (the message names the file and field)."""


@dataclass(frozen=True, kw_only=True)
class MapMetadata:
    """The fields of a map YAML file (map_server's keys).

    Attributes:
        image: The image path, resolved against the YAML's directory.
        resolution: Metres per cell (> 0).
        origin: ``(x, y, yaw)`` of the lower-left cell's corner in the map frame.
        negate: Whether white means occupied.
        occupied_thresh: Occupancy probability above which a cell is occupied.
        free_thresh: Occupancy probability below which a cell is free.
        mode: ``trinary``, ``scale`` or ``raw``.
    """

    image: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool = False
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196
    mode: MapMode = "trinary"


@dataclass(frozen=True)
class OccupancyMap:
    """A loaded map: ``data`` is ``(height, width)`` int8, row 0 at ``origin`` (ROS order).

    Attributes:
        data: Occupancy values (-1 unknown, 0 free ... 100 occupied).
        metadata: The YAML it came from.
    """

    data: NDArray[np.int8]
    metadata: MapMetadata

    def counts(self) -> dict[str, int]:
        """``free`` (0), ``occupied`` (>= 65, map_saver's threshold) and ``unknown`` (< 0) cells."""
        d = self.data
        return {
            "free": int(np.count_nonzero(d == 0)),
            "occupied": int(np.count_nonzero(d >= 65)),
            "unknown": int(np.count_nonzero(d < 0)),
        }

    def to_msg(self, *, frame_id: str = "map", stamp_ns: int = 0) -> OccupancyGrid:
        """This map as a ``nav_msgs/OccupancyGrid`` (map_server's ``/map``)."""
        from visnav.msgs.time import ns_to_time  # noqa: PLC0415
        from visnav.msgs.types import (  # noqa: PLC0415
            Header,
            MapMetaData,
            OccupancyGrid,
            Point,
            Pose,
        )

        x, y, yaw = self.metadata.origin
        height, width = self.data.shape
        stamp = ns_to_time(stamp_ns)
        info = MapMetaData(
            map_load_time=stamp,
            resolution=float(self.metadata.resolution),
            width=int(width),
            height=int(height),
            origin=Pose(
                position=Point(x=x, y=y, z=0.0),
                orientation=quaternion_from_yaw(yaw),
            ),
        )
        return OccupancyGrid(
            header=Header(stamp=stamp, frame_id=frame_id),
            info=info,
            data=np.ascontiguousarray(self.data).reshape(-1).copy(),
        )


def _fail(path: Path | str, field: str, problem: str, fix: str) -> MapFileError:
    return MapFileError(f"{path}: {field}: {problem}. Fix: {fix}")


def _number(raw: dict[str, Any], key: str, path: Path) -> float:
    if key not in raw:
        return math.nan
    value = raw[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(path, key, f"{value!r} is not a number", f"write {key}: <number>")
    return float(value)


def read_map_yaml(path: str | Path) -> MapMetadata:
    """Read and check a map_server YAML file.

    Raises:
        MapFileError: the file is missing or not YAML, a key is missing or invalid.
    """
    path = Path(path)
    raw = load_yaml_file(path, what="the map YAML", error=MapFileError)
    if not isinstance(raw, dict):
        raise _fail(path, "document", f"is {type(raw).__name__}, not a mapping", "write keys "
                    "image, resolution, origin, negate, occupied_thresh, free_thresh")  # fmt: skip
    for key in ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"):
        if key not in raw:
            raise _fail(path, key, "is missing (map_server needs it)", f"add {key}: ...")
    image = raw["image"]
    if not isinstance(image, str) or not image.strip():
        raise _fail(path, "image", f"{image!r} is not a file name", "write image: map.pgm")
    resolution = _number(raw, "resolution", path)
    if not (math.isfinite(resolution) and resolution > 0):
        raise _fail(path, "resolution", f"{resolution:g} m/cell", "write a resolution > 0")
    origin = raw["origin"]
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in origin)
        or not all(math.isfinite(float(v)) for v in origin)
    ):
        raise _fail(path, "origin", f"{origin!r} is not 3 numbers", "write origin: [x, y, yaw]")
    negate = raw["negate"]
    if negate not in (0, 1) or isinstance(negate, float):
        raise _fail(path, "negate", f"{negate!r} is not 0 or 1", "write negate: 0")
    occ = _number(raw, "occupied_thresh", path)
    free = _number(raw, "free_thresh", path)
    if not (0.0 <= free < occ <= 1.0):
        raise _fail(path, "free_thresh/occupied_thresh", f"{free:g} / {occ:g} are out of order",
                    "use 0 <= free_thresh < occupied_thresh <= 1 (0.196 and 0.65)")  # fmt: skip
    mode = raw.get("mode", "trinary")
    if mode not in _MODES:
        raise _fail(path, "mode", f"{mode!r} is not a map mode", "write trinary, scale or raw")
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    return MapMetadata(
        image=image_path, resolution=resolution,
        origin=(float(origin[0]), float(origin[1]), float(origin[2])),
        negate=bool(negate), occupied_thresh=occ, free_thresh=free, mode=mode,
    )  # fmt: skip


def _pgm_tokens(blob: bytes, path: Path) -> tuple[list[bytes], int, float | None]:
    """The 4 header tokens, the data offset and the map_saver ``m/pix`` comment (if any)."""
    tokens: list[bytes] = []
    comment_res: float | None = None
    i = 0
    while len(tokens) < 4:
        while i < len(blob) and blob[i : i + 1].isspace():
            i += 1
        if i >= len(blob):
            raise _fail(path, "PGM header", "ends early", "write a P5 (or P2) header")
        if blob[i : i + 1] == b"#":
            end = blob.find(b"\n", i)
            end = len(blob) if end < 0 else end
            found = _CREATOR.search(blob[i:end])
            if found is not None:
                try:
                    comment_res = float(found.group(1))
                except ValueError:
                    comment_res = None
            i = end
            continue
        start = i
        while i < len(blob) and not blob[i : i + 1].isspace() and blob[i : i + 1] != b"#":
            i += 1
        tokens.append(blob[start:i])
    return tokens, i + 1, comment_res


def read_pgm(path: str | Path) -> tuple[NDArray[np.uint8], float | None]:
    """Read an 8-bit PGM (``P5`` binary or ``P2`` text).

    Returns:
        The ``(height, width)`` pixels and the resolution of a map_saver comment (or None).

    Raises:
        MapFileError: not a PGM, not 8-bit, or the data disagree with the header.
    """
    path = Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise _fail(path, "image", f"cannot be read ({exc.strerror})", "check the path") from None
    tokens, offset, comment_res = _pgm_tokens(blob, path)
    magic = tokens[0]
    if magic not in (b"P5", b"P2"):
        raise _fail(path, "PGM magic", f"{magic[:8]!r} is not P5 or P2", "save a greyscale PGM")
    try:
        width, height, maxval = (int(t) for t in tokens[1:])
    except ValueError:
        raise _fail(path, "PGM header", f"{b' '.join(tokens[1:])!r} is not 3 integers",
                    "write width height maxval") from None  # fmt: skip
    if width <= 0 or height <= 0 or not 0 < maxval < 256:
        raise _fail(path, "PGM header", f"{width}x{height}, maxval {maxval}",
                    "use a positive size and an 8-bit maxval (255)")  # fmt: skip
    count = width * height
    if magic == b"P5":
        data = np.frombuffer(blob, dtype=np.uint8, count=-1, offset=min(offset, len(blob)))
        if data.size < count:
            raise _fail(path, "PGM data", f"{data.size} bytes for a {width}x{height} header",
                        "the image is truncated: save it again")  # fmt: skip
        pixels = data[:count]
    else:
        try:
            pixels = np.array(blob[offset:].split()[:count], dtype=np.int64)
        except ValueError:
            raise _fail(path, "PGM data", "holds a value that is not an integer",
                        "write whitespace-separated integers") from None  # fmt: skip
        if pixels.size < count or (pixels.size and not 0 <= pixels.min() <= pixels.max() <= maxval):
            raise _fail(path, "PGM data", f"{pixels.size} values in 0..{maxval} expected {count}",
                        "the image is truncated: save it again")  # fmt: skip
    scaled = pixels if maxval == 255 else np.rint(pixels.astype(np.float64) * 255.0 / maxval)
    return scaled.astype(np.uint8).reshape(height, width), comment_res


def _read_image(path: Path) -> tuple[NDArray[np.uint8], float | None]:
    """``(height, width[, channels])`` pixels (alpha last) and a map_saver resolution comment."""
    if not path.is_file():
        raise _fail(path, "image", "does not exist", "write the image beside the YAML "
                    "or fix the YAML's image: path")  # fmt: skip
    with path.open("rb") as handle:
        head = handle.read(2)
    if head in (b"P5", b"P2"):
        return read_pgm(path)
    import cv2  # noqa: PLC0415 - PNG and other formats only

    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise _fail(path, "image", "is not an image OpenCV can read", "save a PGM or PNG")
    if image.dtype != np.uint8:
        raise _fail(path, "image", f"has {image.dtype} pixels", "save an 8-bit image")
    return np.asarray(image, dtype=np.uint8), None


def pixels_to_grid(pixels: NDArray[np.uint8], metadata: MapMetadata) -> NDArray[np.int8]:
    """Occupancy values from image pixels by map_server's rules (module docstring).

    Args:
        pixels: ``(height, width)`` grey or ``(height, width, channels)`` with alpha last
            when there are 2 or 4 channels; image row 0 is the map's top.
        metadata: Mode, negate and thresholds.

    Returns:
        ``(height, width)`` int8 with row 0 at the map's origin (bottom).
    """
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    if channels == 1 and pixels.size > 256:  # grey (PGM): a 256-entry table of the same rules
        table = pixels_to_grid(np.arange(256, dtype=np.uint8).reshape(1, 256), metadata)[0]
        return np.ascontiguousarray(table[pixels.reshape(pixels.shape[:2])][::-1])
    values = pixels.reshape(pixels.shape[0], pixels.shape[1], channels).astype(np.float64)
    has_alpha = channels in (2, 4)
    averaged = channels if metadata.mode == "trinary" or not has_alpha else channels - 1
    mean = values[:, :, :averaged].sum(axis=2) / averaged
    alpha = values[:, :, -1] if has_alpha else np.full(mean.shape, 255.0)
    if metadata.negate:
        mean = 255.0 - mean
    if metadata.mode == "raw":
        out = mean.astype(np.uint8).view(np.int8)
    else:
        occ = (255.0 - mean) / 255.0
        occ_t, free_t = metadata.occupied_thresh, metadata.free_thresh
        out = np.full(mean.shape, -1, dtype=np.int8)
        if metadata.mode == "scale":
            ratio = (occ - free_t) / (occ_t - free_t)
            scaled = np.trunc(99.0 * ratio).astype(np.int8)
            middle = (occ <= occ_t) & (occ >= free_t) & (alpha >= 1.0)
            out[middle] = scaled[middle]
        out[occ > occ_t] = 100
        out[occ < free_t] = 0
    return np.ascontiguousarray(out[::-1])


def load_map(path: str | Path) -> OccupancyMap:
    """Load a map YAML and its image as map_server does.

    Raises:
        MapFileError: the YAML or the image is missing or invalid, or they disagree.
    """
    metadata = read_map_yaml(path)
    pixels, comment_res = _read_image(metadata.image)
    if comment_res is not None and not math.isclose(
        comment_res, metadata.resolution, rel_tol=0.0, abs_tol=0.0005 + 1e-9
    ):
        raise _fail(path, "resolution", f"{metadata.resolution:g} m/cell but {metadata.image.name} "
                    f"was saved at {comment_res:g} m/pix", "use the YAML written with the image "
                    "(or fix resolution)")  # fmt: skip
    return OccupancyMap(pixels_to_grid(pixels, metadata), metadata)


def grid_to_pgm_pixels(
    data: NDArray[np.integer[Any]], *, occupied: int = 65, free: int = 25
) -> NDArray[np.uint8]:
    """map_saver's trinary image of a grid (row 0 at the origin): 254 / 0 / 205, flipped."""
    grid = np.asarray(data)
    out = np.full(grid.shape, 205, dtype=np.uint8)
    out[(grid >= 0) & (grid <= free)] = 254
    out[grid >= occupied] = 0
    return np.ascontiguousarray(out[::-1])


def write_pgm(path: str | Path, pixels: NDArray[np.uint8], *, resolution: float) -> Path:
    """Write a ``P5`` PGM with map_saver's header comment."""
    path = Path(path)
    height, width = pixels.shape
    header = f"P5\n# CREATOR: map_saver.cpp {resolution:.3f} m/pix\n{width} {height}\n255\n"
    path.write_bytes(header.encode("ascii") + np.ascontiguousarray(pixels).tobytes())
    return path


def save_map(
    grid: OccupancyGrid, base: str | Path, *, occupied: int = 65, free: int = 25
) -> tuple[Path, Path]:
    """Write ``<base>.yaml`` and ``<base>.pgm`` as map_saver does.

    Args:
        grid: The map message.
        base: Path without extension (map_saver's ``-f``).
        occupied: Cells at or above this are black (map_saver ``--occ``).
        free: Cells in ``0..free`` are white (map_saver ``--free``).

    Returns:
        The YAML and PGM paths.

    Raises:
        MapFileError: the grid's size does not match its data, a threshold is invalid, or
            the origin orientation is non-finite or of zero length (all-zero reads as identity).
    """
    if not 0 <= free < occupied <= 100:
        msg = (
            f"map save: thresholds free={free} occupied={occupied}: expected "
            "0 <= free < occupied <= 100 (map_saver's --free 25 --occ 65)"
        )
        raise MapFileError(msg)
    info = grid.info
    width, height = int(info.width), int(info.height)
    data = np.asarray(grid.data, dtype=np.int8)
    if data.size != width * height or width == 0 or height == 0:
        msg = (
            f"map save: the OccupancyGrid is {width}x{height} but holds {data.size} cells; "
            "expected width*height > 0 cells (is the /map publisher sending a full grid?)"
        )
        raise MapFileError(msg)
    base = Path(base)
    yaml_path = base.with_name(base.name + ".yaml")
    pgm_path = base.with_name(base.name + ".pgm")
    pixels = grid_to_pgm_pixels(data.reshape(height, width), occupied=occupied, free=free)
    write_pgm(pgm_path, pixels, resolution=float(info.resolution))
    q = info.origin.orientation
    try:  # an unset (all-zero) orientation is read as the identity, as map_server writes it
        yaw = 0.0 if q.x == q.y == q.z == q.w == 0.0 else yaw_from_quaternion(q)
    except InvalidArgumentException as exc:
        msg = f"map save: info.origin.orientation: {exc}; publish a unit quaternion"
        raise MapFileError(msg) from exc
    p = info.origin.position
    yaml_path.write_text(
        f"image: {pgm_path.name}\nresolution: {float(info.resolution):f}\n"
        f"origin: [{float(p.x):f}, {float(p.y):f}, {yaw:f}]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n\n"
    )
    return yaml_path, pgm_path
