"""Robot footprints: a polygon in the base frame, or a circle of ``robot_radius``.

Semantics of costmap_2d's ``footprint.cpp``:

* ``footprint`` is a polygon ``[[x, y], ...]`` (at least 3 points) in the robot base
  frame; a string in the YAML form ``"[[0.2, 0.1], [0.2, -0.1], [-0.2, -0.1]]"`` is
  parsed; an empty footprint falls back to ``robot_radius`` (default 0.46 m);
* ``footprint_padding`` (0.01 m) moves every vertex away from the centre by that much
  per axis (``sign(x) * padding``);
* a circle becomes a 16-vertex polygon for rasterising;
* the inscribed radius is the smallest distance from the centre to an edge, the
  circumscribed radius the largest vertex distance.

Difference: a circular footprint stays a circle of ``robot_radius + footprint_padding``
(``is_circular``), so collision checks use the exact circle (the centre cell's inflated
cost) and its inscribed radius is that radius; costmap_2d pads a 16-gon, whose
inscribed radius is 2 % smaller.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.mapping.errors import CostmapError

__all__ = [
    "DEFAULT_ROBOT_RADIUS",
    "Footprint",
    "make_footprint_from_radius",
    "min_max_distances",
    "pad_footprint",
    "parse_footprint",
    "transform_footprint",
]

DEFAULT_ROBOT_RADIUS = 0.46
_MIN_POINTS = 3


def make_footprint_from_radius(radius: float, n: int = 16) -> NDArray[np.float64]:
    """A regular ``n``-gon with vertices on a circle of ``radius`` (costmap_2d uses 16)."""
    angles = np.arange(n) * (2 * math.pi / n)
    return np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)


def parse_footprint(value: Any) -> NDArray[np.float64]:
    """Parse a footprint: a ``[[x, y], ...]`` list or its string form; ``[]`` -> empty.

    Raises:
        CostmapError: not a list of at least 3 ``[x, y]`` pairs of finite numbers.
    """
    parsed = value
    if isinstance(value, str):
        text = value.strip()
        if text in ("", "[]"):
            return np.empty((0, 2))
        try:
            parsed = ast.literal_eval(text)
        except (ValueError, SyntaxError) as exc:
            msg = (
                f"footprint {value!r} is not a list: expected '[[x1, y1], [x2, y2], ...]' "
                "with at least 3 points in metres"
            )
            raise CostmapError(msg) from exc
    try:
        pts = np.asarray(parsed, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        msg = f"footprint {value!r}: expected a list of [x, y] pairs of numbers"
        raise CostmapError(msg) from exc
    if pts.size == 0:
        return np.empty((0, 2))
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < _MIN_POINTS:
        msg = (
            f"footprint {value!r} has shape {pts.shape}: expected at least 3 [x, y] points, "
            "e.g. [[0.2, 0.15], [0.2, -0.15], [-0.2, -0.15], [-0.2, 0.15]]"
        )
        raise CostmapError(msg)
    if not np.isfinite(pts).all():
        msg = f"footprint {value!r} has non-finite coordinates: expected finite metres"
        raise CostmapError(msg)
    return pts


def pad_footprint(points: ArrayLike, padding: float) -> NDArray[np.float64]:
    """Move each vertex ``padding`` metres away from the centre along each axis."""
    pts: NDArray[np.float64] = np.asarray(points, dtype=np.float64).copy()
    pts += np.sign(pts) * padding
    return pts


def min_max_distances(points: ArrayLike) -> tuple[float, float]:
    """``(inscribed, circumscribed)`` radii of a polygon around the origin."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return 0.0, 0.0
    circ = float(np.hypot(pts[:, 0], pts[:, 1]).max())
    a = pts
    b = np.roll(pts, -1, axis=0)
    ab = b - a
    len2 = (ab**2).sum(axis=1)
    t = np.clip(np.where(len2 > 0, -(a * ab).sum(axis=1) / np.where(len2 > 0, len2, 1), 0), 0, 1)
    closest = a + t[:, None] * ab
    insc = float(np.hypot(closest[:, 0], closest[:, 1]).min())
    return insc, circ


def transform_footprint(points: ArrayLike, x: float, y: float, yaw: float) -> NDArray[np.float64]:
    """The footprint placed at pose ``(x, y, yaw)`` in the world."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.empty_like(pts)
    out[:, 0] = x + c * pts[:, 0] - s * pts[:, 1]
    out[:, 1] = y + s * pts[:, 0] + c * pts[:, 1]
    return out


@dataclass(frozen=True)
class Footprint:
    """A robot footprint: padded polygon plus its radii.

    Build with :meth:`from_params`. ``points`` is the padded polygon (a 16-gon for a
    circular robot); ``is_circular`` tells collision checks to use the exact circle.
    """

    points: NDArray[np.float64]
    inscribed_radius: float
    circumscribed_radius: float
    is_circular: bool
    radius: float = 0.0
    perimeter: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 2)))

    @classmethod
    def from_params(
        cls,
        *,
        footprint: Any = "[]",
        robot_radius: float = DEFAULT_ROBOT_RADIUS,
        footprint_padding: float = 0.01,
        perimeter_spacing: float = 0.025,
    ) -> Footprint:
        """Build from costmap_2d's ``footprint``, ``robot_radius`` and ``footprint_padding``.

        Args:
            footprint: polygon (list or string); empty uses ``robot_radius``.
            robot_radius: radius of a circular robot (metres).
            footprint_padding: padding added to the polygon, or to ``robot_radius``
                (costmap_2d pads the 16-gon it makes of the radius).
            perimeter_spacing: spacing of the points sampled along the polygon's edges
                for collision checks.

        Raises:
            CostmapError: a malformed polygon or a non-positive radius.
        """
        pts = parse_footprint(footprint)
        if len(pts) == 0:
            if not (math.isfinite(robot_radius) and robot_radius > 0):
                msg = f"robot_radius is {robot_radius}: expected a radius > 0 m (or a footprint)"
                raise CostmapError(msg)
            r = float(robot_radius) + float(footprint_padding)
            poly = make_footprint_from_radius(r)
            return cls(
                poly,
                r,
                r,
                is_circular=True,
                radius=r,
                perimeter=_perimeter(poly, perimeter_spacing),
            )
        poly = pad_footprint(pts, footprint_padding)
        insc, circ = min_max_distances(poly)
        return cls(
            poly, insc, circ, is_circular=False, perimeter=_perimeter(poly, perimeter_spacing)
        )


def _perimeter(poly: NDArray[np.float64], spacing: float) -> NDArray[np.float64]:
    out = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        n = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing))
        t = np.arange(n)[:, None] / n
        out.append(a + t * (b - a))
    return np.concatenate(out, axis=0)
