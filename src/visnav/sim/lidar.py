"""Ray sensors in MuJoCo: batched ray casting and Gazebo's range conventions.

:class:`RayCaster` casts every ray of a :class:`~visnav.description.gazebo_specs.RaySpec`
from the sensor frame (the link frame composed with the sensor ``<pose>``) with one
``mujoco.mj_multiRay`` call, as Gazebo's ``MultiRayShape`` lays the rays out: ray
``(j, i)`` (vertical row ``j``, horizontal column ``i``, index ``j * samples_h + i``) has
yaw ``min + i * (max - min) / (samples - 1)`` and pitch likewise (0 for an axis with one
sample), direction ``(cos p cos y, cos p sin y, sin p)`` in the sensor frame.

What a ray hits: collision geometry only, of the world, of other robots and of the
robot itself, except the sensor's own link (its body is excluded; a ray starting inside
the link's collision shape would otherwise hit it). A colliding world mesh is hit on its
own triangles (its ray geom, :data:`~visnav.sim.world_spec.MESH_RAY_GROUP`), not on the
convex pieces MuJoCo collides with, as Gazebo's rays hit the mesh. Visual-only geoms
(robot visuals in MuJoCo group 1 are filtered by group; a world's visual-only shapes have
no contacts and are looked through). Like Gazebo's rays, which start at ``range_min``, a
surface closer than ``range_min`` is not seen: that ray is cast again from ``range_min``.

Raw ranges (:meth:`RayCaster.cast`) are the hit distance from the sensor origin, or
``range_max`` without a hit (Gazebo's ``MultiRayShape::GetRange``). :func:`scan_ranges`
then turns them into the ranges Gazebo's ray sensor publishes: interpolated to
``samples * resolution`` ranges per axis when ``resolution`` is not 1, +inf at or beyond
``range_max``, -inf at or below ``range_min`` (REP 117), and the ``<noise>`` (a bias drawn
once, plus N(mean, stddev) per ray) added to the others, clamped to the range limits.
:func:`velodyne_points` applies velodyne_simulator's filtering and layout.

Where visnav differs from Gazebo: intensities are 0 (Gazebo's default ``laser_retro``;
``<laser_retro>`` is not read); point coordinates use the angles the rays were cast at
(Gazebo's cloud conversions place a single-sample axis at ``min_angle`` though it casts
it at 0); a ray that starts at ``range_min`` inside a shape reports that shape's far
side (MuJoCo's ray from inside a geom).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from visnav.sim.world_spec import MESH_PIECE_GROUP, MESH_RAY_GROUP

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from visnav.description.gazebo_specs import GaussianNoise, RayScan, RaySpec
    from visnav.sim.rebind import IdMap

__all__ = [
    "ROBOT_VISUAL_GROUP",
    "VELODYNE_DTYPE",
    "RayCaster",
    "RayNoise",
    "axis_angles",
    "published_angles",
    "ray_directions",
    "scan_ranges",
    "spherical_to_xyz",
    "velodyne_points",
]

ROBOT_VISUAL_GROUP = 1
"""MuJoCo geom group of robot visual geoms (:mod:`visnav.sim.robot`): rays skip it."""

VELODYNE_DTYPE = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "ring", "time"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
        "offsets": [0, 4, 8, 12, 16, 18],
        "itemsize": 22,
    }
)
"""velodyne_simulator's point layout (as velodyne_pointcloud's XYZIRT): 22-byte points."""

_MAX_RECASTS = 32
_EPS = 1e-6


def axis_angles(samples: int, lo: float, hi: float) -> NDArray[np.float64]:
    """Angles of ``samples`` rays from ``lo`` to ``hi`` (a single ray at 0, as Gazebo)."""
    if samples <= 1:
        return np.zeros(1)
    return lo + np.arange(samples, dtype=np.float64) * ((hi - lo) / (samples - 1))


def ray_directions(horizontal: RayScan, vertical: RayScan) -> NDArray[np.float64]:
    """Unit ray directions in the sensor frame, shape ``(V * H, 3)``, vertical rows outer."""
    yaw = axis_angles(horizontal.samples, horizontal.min_angle, horizontal.max_angle)
    pitch = axis_angles(vertical.samples, vertical.min_angle, vertical.max_angle)
    p, y = np.meshgrid(pitch, yaw, indexing="ij")
    dirs = np.stack([np.cos(p) * np.cos(y), np.cos(p) * np.sin(y), np.sin(p)], axis=-1)
    return dirs.reshape(-1, 3)


class RayNoise:
    """Gazebo's ``GaussianNoiseModel`` on arrays: a bias drawn once (random sign) + N(mean, std)."""

    def __init__(self, noise: GaussianNoise, rng: np.random.Generator) -> None:
        self.mean = noise.mean
        self.stddev = noise.stddev
        self.active = noise.active
        bias = float(rng.normal(noise.bias_mean, noise.bias_stddev)) if noise.active else 0.0
        self.bias = -bias if noise.active and rng.uniform() < 0.5 else bias

    def apply(self, values: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
        """``values`` with noise added (unchanged when the noise is inactive)."""
        if not self.active:
            return values
        return values + rng.normal(self.mean, self.stddev, values.shape) + self.bias


class RayCaster:
    """Casts a ray sensor's rays in a MuJoCo model with one batched call.

    Args:
        model: the compiled model.
        spec: the ray sensor.
        body: MuJoCo body id of the sensor's link (excluded from the casts; 0, the world
            body, excludes nothing).
        t_link_sensor: the sensor frame in the link frame (4x4).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        spec: RaySpec,
        *,
        body: int,
        t_link_sensor: NDArray[np.float64],
    ) -> None:
        self.model = model
        self.spec = spec
        self.body = int(body)
        self._exclude = self.body if self.body > 0 else -1
        self._t_link_sensor = np.asarray(t_link_sensor, dtype=np.float64)
        self.directions = ray_directions(spec.horizontal, spec.vertical)
        self.shape = (spec.vertical.samples, spec.horizontal.samples)
        n = self.directions.shape[0]
        self.rays = n
        groups = np.ones(mujoco.mjNGROUP, dtype=np.uint8)
        groups[ROBOT_VISUAL_GROUP] = 0
        groups[MESH_PIECE_GROUP] = 0  # a world mesh is hit through its ray geom instead
        self._groups = groups
        self._see_through_geoms(model)
        self._dirs = np.zeros((n, 3))
        self._dist = np.zeros(n)
        self._geom = np.zeros(n, dtype=np.int32)
        self._one = np.zeros(1, dtype=np.int32)

    def rebind(self, ids: IdMap) -> None:
        """Cast in a recompiled model (a spawned model is hit, a deleted one is not)."""
        self.model = ids.model
        self.body = ids.body(self.body) if self.body > 0 else self.body
        self._exclude = self.body if self.body > 0 else -1
        self._see_through_geoms(ids.model)

    def _see_through_geoms(self, model: mujoco.MjModel) -> None:
        group = np.clip(np.asarray(model.geom_group), 0, mujoco.mjNGROUP - 1)
        self._collides = (
            (np.asarray(model.geom_contype) != 0)
            | (np.asarray(model.geom_conaffinity) != 0)
            | (group == MESH_RAY_GROUP)
        )
        self._see_through = bool(np.any(~self._collides & (self._groups[group] != 0)))

    def sensor_pose(self, data: mujoco.MjData) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World position (3,) and rotation (3x3) of the sensor frame."""
        rot_link = np.asarray(data.xmat[self.body], dtype=np.float64).reshape(3, 3)
        pos_link = np.asarray(data.xpos[self.body], dtype=np.float64)
        rot = rot_link @ self._t_link_sensor[:3, :3]
        pos = pos_link + rot_link @ self._t_link_sensor[:3, 3]
        return pos, rot

    def cast(self, data: mujoco.MjData) -> NDArray[np.float64]:
        """Raw ranges, shape ``(vertical samples, horizontal samples)``: ``range_max`` = no hit.

        Needs the kinematics of ``data`` (``mj_step1`` / ``mj_forward`` done).
        """
        spec = self.spec
        origin, rot = self.sensor_pose(data)
        dirs = np.matmul(self.directions, rot.T, out=self._dirs)
        mujoco.mj_multiRay(
            self.model, data, origin, dirs.reshape(-1), self._groups, 1, self._exclude,
            self._geom, self._dist, None, self.rays, spec.range_max,
        )  # fmt: skip
        dist, geom = self._dist, self._geom
        hit = geom >= 0
        ranges = np.where(hit, np.minimum(dist, spec.range_max), spec.range_max)
        bad = hit & (dist < spec.range_min)
        if self._see_through:  # visual-only geoms (no contacts) in the cast groups
            bad |= hit & ~self._collides[np.maximum(geom, 0)]
        for k in np.flatnonzero(bad):
            ranges[k] = min(self._recast(data, origin, dirs[k], dist[k]), spec.range_max)
        return ranges.reshape(self.shape)

    def _recast(
        self,
        data: mujoco.MjData,
        origin: NDArray[np.float64],
        direction: NDArray[np.float64],
        first: float,
    ) -> float:
        """Follow one ray past a too-close or visual-only hit; inf when nothing else is hit."""
        spec = self.spec
        t, d = 0.0, first
        for _ in range(_MAX_RECASTS):
            t = spec.range_min if t + d < spec.range_min else t + d + _EPS
            if t >= spec.range_max:
                return math.inf
            d = mujoco.mj_ray(
                self.model, data, origin + t * direction, direction, self._groups, 1,
                self._exclude, self._one,
            )  # fmt: skip
            geom = int(self._one[0])
            if geom < 0:
                return math.inf
            if t + d >= spec.range_min and self._collides[geom]:
                return float(t + d)
        return math.inf


def _interpolate(raw: NDArray[np.float64], count: int, axis: int) -> NDArray[np.float64]:
    """Gazebo's linear interpolation of ``raw`` to ``count`` samples along ``axis``."""
    n = raw.shape[axis]
    if count == n:
        return raw
    pos = np.zeros(1) if count == 1 else np.arange(count) * ((n - 1) / (count - 1))
    a = np.floor(pos).astype(np.int64)
    b = np.minimum(a + 1, n - 1)
    w = pos - a
    shape = [1, 1]
    shape[axis] = count
    w = w.reshape(shape)
    out: NDArray[np.float64] = (
        np.take(raw, a, axis=axis) * (1.0 - w) + np.take(raw, b, axis=axis) * w
    )
    return out


def scan_ranges(
    raw: NDArray[np.float64],
    spec: RaySpec,
    noise: RayNoise | None = None,
    rng: np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """The ranges Gazebo's ray sensor publishes, shape ``(vertical count, horizontal count)``.

    Interpolated when ``resolution`` is not 1; +inf at or beyond ``range_max``, -inf at
    or below ``range_min``; noise (when given and active) on the others, clamped to
    ``[range_min, range_max]``.
    """
    r = _interpolate(raw, spec.horizontal.count, 1)
    r = _interpolate(r, spec.vertical.count, 0)
    inside = r
    if noise is not None and noise.active and rng is not None:
        inside = np.clip(noise.apply(r, rng), spec.range_min, spec.range_max)
    out: NDArray[np.float64] = np.where(
        r >= spec.range_max, math.inf, np.where(r <= spec.range_min, -math.inf, inside)
    )
    return out


def published_angles(spec: RaySpec) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Azimuths (horizontal count,) and inclinations (vertical count,) of published ranges."""
    h, v = spec.horizontal, spec.vertical
    return (
        axis_angles(h.count, h.min_angle, h.max_angle),
        axis_angles(v.count, v.min_angle, v.max_angle),
    )


def spherical_to_xyz(
    ranges: NDArray[np.float64], azimuth: NDArray[np.float64], inclination: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Points ``(V, H, 3)`` of ranges ``(V, H)`` at azimuths ``(H,)`` and inclinations ``(V,)``."""
    ca, sa = np.cos(azimuth)[None, :], np.sin(azimuth)[None, :]
    ci, si = np.cos(inclination)[:, None], np.sin(inclination)[:, None]
    return np.stack([ranges * ci * ca, ranges * ci * sa, ranges * si], axis=-1)


def velodyne_points(
    ranges: NDArray[np.float64],
    spec: RaySpec,
    rng: np.random.Generator,
    intensities: NDArray[np.float64] | None = None,
) -> NDArray[Any]:
    """velodyne_simulator's cloud of scan ``ranges`` ``(V, H)`` as a structured array.

    Points go azimuth by azimuth, ring by ring within each (``ring`` = vertical row,
    ``time`` 0). A point outside ``(max(min_range, range_min), min(max_range, range_max))``
    or below ``min_intensity`` is dropped; ``gaussian_noise`` is added to the kept ones,
    which are dropped again if the noise moves them out of range. With
    ``organize_cloud`` nothing is dropped: such points are NaN and the array is
    ``(H, V)`` (cloud height = azimuths, width = rings), otherwise 1-D.
    """
    lo = max(spec.plugin_min_range, spec.range_min)
    hi = min(spec.plugin_max_range, spec.range_max)
    r = np.asarray(ranges, dtype=np.float64).T  # (H, V): azimuth outer, ring inner
    inten = np.zeros_like(r) if intensities is None else np.asarray(intensities, np.float64).T
    azimuth, inclination = published_angles(spec)
    keep = (r > lo) & (r < hi) & (inten >= spec.min_intensity)
    candidate = np.ones_like(keep) if spec.organize_cloud else keep
    noisy = r
    if spec.gaussian_noise != 0.0:
        with np.errstate(invalid="ignore"):  # inf + noise on dropped rays, unused
            noisy = np.where(candidate, r + rng.normal(0.0, spec.gaussian_noise, r.shape), r)
    valid = candidate & (noisy > lo) & (noisy < hi)
    rr = np.where(valid, noisy, np.nan)  # NaN propagates into x, y, z of dropped points
    flat = rr * np.cos(inclination)[None, :]
    out = np.zeros(r.shape, dtype=VELODYNE_DTYPE)
    out["x"] = flat * np.cos(azimuth)[:, None]
    out["y"] = flat * np.sin(azimuth)[:, None]
    out["z"] = rr * np.sin(inclination)[None, :]
    out["intensity"] = np.where(valid, inten, np.nan)
    out["ring"] = np.arange(r.shape[1], dtype=np.uint16)[None, :]
    if spec.organize_cloud:
        return out
    kept: NDArray[Any] = out[valid]
    return kept
