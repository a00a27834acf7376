"""ego-planner's 3D grid map: log-odds occupancy from ray casting, inflated for planning.

The algorithm of ``plan_env/grid_map.cpp`` (ZJU FAST-Lab ego-planner) on numpy
buffers with numba kernels:

* **Update** (:meth:`GridMap.update_from_depth`, :meth:`GridMap.update_from_points`):
  every ray from the sensor to a measured point counts a *hit* in the voxel of the
  point and a *miss* in each voxel it crosses on the way back to the sensor; a ray
  longer than ``max_ray_length`` (or leaving the map) is cut there and counts
  only misses. Each voxel touched by an update then gets one log-odds step,
  ``logit(p_hit)`` if its hits are at least its misses and ``logit(p_miss)``
  otherwise, clamped to ``[logit(p_min), logit(p_max)]``. Unknown voxels start
  just below ``logit(p_min)``; a voxel is *occupied* above ``logit(p_occ)`` (with
  the defaults, six consecutive hits from unknown).
* **Depth filter**: pixels every ``skip_pixel`` inside a ``depth_filter_margin``
  border; no return or farther than ``depth_filter_maxdist`` is a free ray to
  ``max_ray_length``; nearer than ``depth_filter_mindist`` is dropped.
* **Local map**: voxels touched outside ``local_update_range`` of the sensor are
  reset before their update; a shell beyond ``local_map_margin`` of the updated
  box is forgotten (unknown).
* **Inflation**: each occupied voxel marks the cube of half-width
  ``ceil(obstacles_inflation / resolution)`` voxels in the inflated buffer, which
  the planner queries; a virtual ceiling layer at ``virtual_ceil_height`` and a
  virtual ground layer at ``virtual_ground_height`` are marked too, and any point
  outside the map counts as occupied (ego-planner's ``-1``).

Differences from ego-planner: clouds are ray cast from their sensor origin like
depth images (upstream marks world-frame cloud points straight into the inflated
buffer); the depth filter reads the pixel it tests (upstream tests the next one);
inflation is rebuilt from occupied voxels up to ``inf_step`` outside the updated
box (upstream only inside it, so obstacles at its edge lost their inflation);
``min_ray_length`` drops cloud points that near the sensor (upstream reads it but
does not use it); a virtual ground layer is added.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from visnav.mapping import _grid_kernels as kernels
from visnav.mapping.errors import MappingError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["GridMap", "GridMapError", "GridMapParams", "GridView", "UpdateResult", "logit"]

UNKNOWN_FLAG = 0.01


class GridMapError(MappingError, ValueError):
    """Invalid grid map parameters or inputs."""


def logit(p: float) -> float:
    """``log(p / (1 - p))``."""
    return math.log(p / (1.0 - p))


Vec3 = tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class GridMapParams:
    """Grid map parameters with ego-planner's names and defaults (``grid_map/...``).

    Upstream's ``depth_filter_tolerance`` feeds a consistency check that is commented out
    there, so it is not a parameter here (a launch file setting it gets the
    unknown-parameter warning).

    Attributes:
        resolution: Voxel edge (m).
        map_size: Extent x, y, z (m); x and y centred on ``map_center``.
        map_center: Centre of the map in x, y (m); ego-planner uses the origin.
        ground_height: Bottom of the map (m).
        local_update_range: Half-extents of the box around the sensor that is updated (m).
        obstacles_inflation: Inflation radius (m), rounded up to whole voxels.
        local_map_margin: Voxels kept around the updated box before forgetting.
        use_depth_filter: Apply the depth filter (margin, skip, min/max distance).
        depth_filter_maxdist: Farthest depth taken as an obstacle (m).
        depth_filter_mindist: Nearest depth used (m).
        depth_filter_margin: Image border skipped (pixels).
        k_depth_scaling_factor: Raw units per metre of 16UC1 depth images.
        skip_pixel: Pixel stride of the depth filter.
        p_hit: Hit probability.
        p_miss: Miss probability.
        p_min: Lower clamp probability.
        p_max: Upper clamp probability.
        p_occ: Occupancy threshold probability.
        min_ray_length: Cloud points nearer to the sensor are dropped (m).
        max_ray_length: Longest ray (m); farther points become free rays.
        virtual_ceil_height: Height of the virtual ceiling layer (m); below -0.5 disables it.
        virtual_ground_height: Height of the virtual ground layer (m); None disables it.
        visualization_truncate_height: Published cells above this are omitted (m).
    """

    resolution: float = 0.1
    map_size: Vec3 = (40.0, 40.0, 3.0)
    map_center: tuple[float, float] = (0.0, 0.0)
    ground_height: float = -0.01
    local_update_range: Vec3 = (5.5, 5.5, 4.5)
    obstacles_inflation: float = 0.099
    local_map_margin: int = 500
    use_depth_filter: bool = True
    depth_filter_maxdist: float = 5.0
    depth_filter_mindist: float = 0.2
    depth_filter_margin: int = 2
    k_depth_scaling_factor: float = 1000.0
    skip_pixel: int = 2
    p_hit: float = 0.65
    p_miss: float = 0.35
    p_min: float = 0.12
    p_max: float = 0.90
    p_occ: float = 0.80
    min_ray_length: float = 0.1
    max_ray_length: float = 4.5
    virtual_ceil_height: float = 2.5
    virtual_ground_height: float | None = -0.01
    visualization_truncate_height: float = 2.4

    def __post_init__(self) -> None:
        def fail(name: str, value: object, expected: str) -> None:
            msg = f"grid_map: {name} is {value!r}; expected {expected}"
            raise GridMapError(msg)

        if not (math.isfinite(self.resolution) and self.resolution > 0):
            fail("resolution", self.resolution, "a length > 0 m")
        for name in ("map_size", "local_update_range"):
            values = getattr(self, name)
            if len(values) != 3 or not all(math.isfinite(v) and v > 0 for v in values):
                fail(name, values, "three lengths > 0 m")
        for name in ("p_hit", "p_miss", "p_min", "p_max", "p_occ"):
            value = getattr(self, name)
            if not 0.0 < value < 1.0:
                fail(name, value, "a probability strictly between 0 and 1")
        if not self.p_min < self.p_occ < self.p_max:
            fail("p_occ", self.p_occ, f"between p_min {self.p_min} and p_max {self.p_max}")
        if self.p_hit <= 0.5 or self.p_miss >= 0.5:
            fail("p_hit/p_miss", (self.p_hit, self.p_miss), "p_hit > 0.5 and p_miss < 0.5")
        if self.skip_pixel < 1:
            fail("skip_pixel", self.skip_pixel, "an integer >= 1")
        if self.depth_filter_margin < 0 or self.local_map_margin < 0:
            fail("margins", (self.depth_filter_margin, self.local_map_margin), "integers >= 0")
        if not (self.max_ray_length > 0 and self.obstacles_inflation >= 0):
            fail(
                "max_ray_length/obstacles_inflation",
                (self.max_ray_length, self.obstacles_inflation),
                "max_ray_length > 0 and obstacles_inflation >= 0",
            )


@dataclass(frozen=True)
class GridView:
    """What planning kernels need to query the inflated map (shared buffers, no copy)."""

    inflate: NDArray[np.uint8]
    origin: NDArray[np.float64]
    resolution: float
    dims: NDArray[np.int64]


@dataclass(frozen=True)
class UpdateResult:
    """What one update did.

    Attributes:
        rays: Rays cast.
        voxels: Voxels whose log-odds changed hands (touched by a ray).
        bound_min: Lower index corner of the updated box.
        bound_max: Upper index corner of the updated box.
    """

    rays: int
    voxels: int
    bound_min: tuple[int, int, int]
    bound_max: tuple[int, int, int]


class GridMap:
    """The map: log-odds buffer, inflated buffer and the scratch buffers of ray casting.

    Args:
        params: Parameters (ego-planner's defaults when omitted).

    Raises:
        GridMapError: Invalid parameters.
    """

    def __init__(self, params: GridMapParams | None = None) -> None:
        self.params = p = params or GridMapParams()
        self.resolution = float(p.resolution)
        size = np.asarray(p.map_size, dtype=np.float64)
        self.origin = np.array(
            [p.map_center[0] - size[0] / 2, p.map_center[1] - size[1] / 2, p.ground_height]
        )
        self.dims = np.array([math.ceil(s / p.resolution - 1e-9) for s in size], dtype=np.int64)
        self.map_max = self.origin + self.dims * self.resolution
        n = int(np.prod(self.dims))
        self.log_hit = logit(p.p_hit)
        self.log_miss = logit(p.p_miss)
        self.clamp_min = logit(p.p_min)
        self.clamp_max = logit(p.p_max)
        self.occupied_log = logit(p.p_occ)
        self.unknown_value = self.clamp_min - UNKNOWN_FLAG
        self._occ = np.full(n, self.unknown_value, dtype=np.float32)
        self._inflate = np.zeros(n, dtype=np.uint8)
        self._cnt_all = np.zeros(n, dtype=np.int32)
        self._cnt_hit = np.zeros(n, dtype=np.int32)
        self._flag_end = np.zeros(n, dtype=np.int32)
        self._flag_traverse = np.zeros(n, dtype=np.int32)
        self._cache = np.zeros(n, dtype=np.int64)
        self._raycast_num = 0
        self.local_bound_min = np.zeros(3, dtype=np.int64)
        self.local_bound_max = self.dims - 1
        self.inf_step = math.ceil(p.obstacles_inflation / p.resolution - 1e-9)
        self.update_count = 0  # changes to the map (updates, marks, resets)

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxels along x, y, z."""
        return int(self.dims[0]), int(self.dims[1]), int(self.dims[2])

    @property
    def log_odds(self) -> NDArray[np.float32]:
        """The log-odds buffer as an ``(nx, ny, nz)`` view (writes go to the map)."""
        return self._occ.reshape(self.shape)

    @property
    def inflated(self) -> NDArray[np.uint8]:
        """The inflated buffer as an ``(nx, ny, nz)`` view (1 = blocked)."""
        return self._inflate.reshape(self.shape)

    def view(self) -> GridView:
        """The buffers the planner's kernels read (shared, not copied)."""
        return GridView(self._inflate, self.origin, self.resolution, self.dims)

    def pos_to_index(self, points: ArrayLike) -> NDArray[np.int64]:
        """Voxel indices of ``(..., 3)`` points (not bounded)."""
        pts = np.asarray(points, dtype=np.float64)
        idx: NDArray[np.int64] = np.floor((pts - self.origin) * (1.0 / self.resolution)).astype(
            np.int64
        )
        return idx

    def index_to_pos(self, index: ArrayLike) -> NDArray[np.float64]:
        """Centres of ``(..., 3)`` voxel indices."""
        idx = np.asarray(index, dtype=np.float64)
        pos: NDArray[np.float64] = (idx + 0.5) * self.resolution + self.origin
        return pos

    def is_in_map(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether ``(N, 3)`` points lie inside the map (1e-4 m off its faces)."""
        pts = _points(points)
        inside: NDArray[np.bool_] = np.all(
            (pts >= self.origin + 1e-4) & (pts <= self.map_max - 1e-4), axis=1
        )
        return inside

    # ------------------------------------------------------------------ queries
    def inflate_occupancy(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Planning occupancy of ``(N, 3)`` points: inflated, or outside the map."""
        pts = _points(points)
        return kernels.query_inflate(pts, self._inflate, self.origin, self.resolution, self.dims)

    def occupancy(self, points: ArrayLike) -> NDArray[np.int8]:
        """Raw occupancy of ``(N, 3)`` points: 1 occupied, 0 free/unknown, -1 outside."""
        pts = _points(points)
        return kernels.query_occupancy(
            pts, self._occ, self.origin, self.resolution, self.dims, self.occupied_log
        )

    def occupied_cells(
        self,
        *,
        inflated: bool = False,
        margin: int = 0,
        truncate_height: float | None = None,
    ) -> NDArray[np.float64]:
        """Centres of the occupied (or inflated) voxels in the last updated box.

        Args:
            inflated: Report the inflated buffer instead of occupied log-odds.
            margin: Voxels added around the updated box (ego-planner's local_map_margin).
            truncate_height: Omit cells whose centre is above this height (m).

        Returns:
            ``(N, 3)`` voxel centres.
        """
        lo = np.clip(self.local_bound_min - margin, 0, self.dims - 1)
        hi = np.clip(self.local_bound_max + margin, 0, self.dims - 1) + 1
        if inflated:
            block = self.inflated[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] != 0
        else:
            block = self.log_odds[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] > self.occupied_log
        idx = np.argwhere(block) + lo
        cells = self.index_to_pos(idx)
        if truncate_height is not None:
            cells = cells[cells[:, 2] <= truncate_height]
        return cells

    # ------------------------------------------------------------------ updates
    def update_from_depth(
        self,
        depth: ArrayLike,
        *,
        intrinsics: tuple[float, float, float, float],
        T_world_camera: ArrayLike,  # noqa: N803  (visnav's transform naming)
    ) -> UpdateResult | None:
        """Fuse one depth image (ego-planner's projectDepthImage + raycastProcess + inflation).

        Args:
            depth: ``(H, W)`` depth: uint16 in ``1 / k_depth_scaling_factor`` m (16UC1)
                or float in metres (32FC1).
            intrinsics: ``fx, fy, cx, cy`` of the (rectified) depth image.
            T_world_camera: Pose of the optical frame (z forward) in the map frame.

        Returns:
            What the update did, or None when the camera is outside the map.

        Raises:
            GridMapError: A malformed image or pose.
        """
        image = np.asarray(depth)
        if image.ndim != 2 or image.dtype.kind not in "uf":
            msg = (
                f"depth image has shape {image.shape} and dtype {image.dtype}: expected (H, W) "
                "uint16 millimetres (16UC1) or float metres (32FC1)"
            )
            raise GridMapError(msg)
        pose = _pose(T_world_camera)
        fx, fy, cx, cy = (float(v) for v in intrinsics)
        if not (fx > 0 and fy > 0):
            msg = f"depth intrinsics fx={fx}, fy={fy}: expected focal lengths > 0 pixels"
            raise GridMapError(msg)
        p = self.params
        scale = 1.0 / p.k_depth_scaling_factor if image.dtype.kind == "u" else 1.0
        if image.dtype.kind == "f" and image.dtype != np.float32:
            image = image.astype(np.float32)
        points = kernels.depth_to_points(
            np.ascontiguousarray(image),
            scale,
            np.array([fx, fy, cx, cy]),
            np.ascontiguousarray(pose[:3, :3]),
            np.ascontiguousarray(pose[:3, 3]),
            p.use_depth_filter,
            p.depth_filter_margin,
            p.skip_pixel,
            p.depth_filter_mindist,
            p.depth_filter_maxdist,
            p.max_ray_length,
        )
        return self._raycast(points, pose[:3, 3])

    def update_from_points(
        self, points: ArrayLike, *, sensor_origin: ArrayLike
    ) -> UpdateResult | None:
        """Fuse one cloud of map-frame points measured from ``sensor_origin``.

        Points nearer than ``min_ray_length`` to the sensor and non-finite points
        are dropped; the rest are ray cast as depth-image points are.

        Returns:
            What the update did, or None when the sensor is outside the map.
        """
        pts = _points(points)
        origin = np.asarray(sensor_origin, dtype=np.float64).reshape(3)
        dist = np.linalg.norm(pts - origin, axis=1)
        keep = np.isfinite(dist) & (dist >= self.params.min_ray_length)
        return self._raycast(np.ascontiguousarray(pts[keep]), origin)

    def _raycast(
        self, points: NDArray[np.float64], sensor: NDArray[np.float64]
    ) -> UpdateResult | None:
        if not (np.all(np.isfinite(sensor)) and bool(self.is_in_map(sensor[None])[0])):
            return None
        self._raycast_num += 1
        if self._raycast_num >= np.iinfo(np.int32).max:
            self._flag_end[:] = 0
            self._flag_traverse[:] = 0
            self._raycast_num = 1
        p = self.params
        n_cache, lo, hi = kernels.raycast_points(
            points,
            np.ascontiguousarray(sensor, dtype=np.float64),
            self.origin,
            self.resolution,
            self.dims,
            p.max_ray_length,
            p.ground_height,
            self._cnt_all,
            self._cnt_hit,
            self._flag_end,
            self._flag_traverse,
            self._cache,
            self._raycast_num,
        )
        rng = np.asarray(p.local_update_range, dtype=np.float64)
        local_min = np.clip(self.pos_to_index(sensor - rng), 0, self.dims - 1)
        local_max = np.clip(self.pos_to_index(sensor + rng), 0, self.dims - 1)
        kernels.process_cache(
            self._cache,
            n_cache,
            self._occ,
            self._cnt_all,
            self._cnt_hit,
            self.dims,
            local_min,
            local_max,
            self.log_hit,
            self.log_miss,
            self.clamp_min,
            self.clamp_max,
        )
        self.local_bound_min = lo
        self.local_bound_max = hi
        self._clear_and_inflate(lo, hi)
        self.update_count += 1
        return UpdateResult(
            rays=int(points.shape[0]),
            voxels=int(n_cache),
            bound_min=(int(lo[0]), int(lo[1]), int(lo[2])),
            bound_max=(int(hi[0]), int(hi[1]), int(hi[2])),
        )

    def _layer(self, height: float | None, lower_limit: float) -> int:
        if height is None or height <= lower_limit:
            return -1
        return math.floor((height - float(self.origin[2])) / self.resolution)

    def _clear_and_inflate(self, lo: NDArray[np.int64], hi: NDArray[np.int64]) -> None:
        p = self.params
        kernels.clear_and_inflate(
            self._occ,
            self._inflate,
            self.dims,
            lo,
            hi,
            p.local_map_margin,
            self.unknown_value,
            self.occupied_log,
            self.inf_step,
            self._layer(p.virtual_ceil_height, -0.5),
            self._layer(p.virtual_ground_height, -math.inf),
        )

    def mark_occupied(self, points: ArrayLike) -> int:
        """Set the voxels of ``(N, 3)`` map points to occupied (``p_max``) and re-inflate.

        For prior maps, tests and benchmarks; the updated box becomes the
        bounding box of the points.

        Returns:
            How many points fell inside the map.
        """
        pts = _points(points)
        lo, hi, count = kernels.mark_occupied(
            pts, self._occ, self.origin, self.resolution, self.dims, np.float32(self.clamp_max)
        )
        if count:
            self.local_bound_min = lo
            self.local_bound_max = hi
            self._clear_and_inflate(lo, hi)
            self.update_count += 1
        return int(count)

    def reset(self) -> None:
        """Forget everything (all voxels unknown, nothing inflated)."""
        self._occ[:] = self.unknown_value
        self._inflate[:] = 0
        self.local_bound_min = np.zeros(3, dtype=np.int64)
        self.local_bound_max = self.dims - 1
        self.update_count += 1


def _points(points: ArrayLike) -> NDArray[np.float64]:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 1 and pts.shape[0] == 3:
        pts = pts[None]
    if pts.ndim != 2 or pts.shape[1] != 3:
        msg = f"points have shape {pts.shape}: expected (N, 3)"
        raise GridMapError(msg)
    return np.ascontiguousarray(pts)


def _pose(matrix: ArrayLike) -> NDArray[np.float64]:
    pose = np.asarray(matrix, dtype=np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        msg = f"camera pose has shape {pose.shape}: expected a finite 4x4 T_world_camera"
        raise GridMapError(msg)
    return pose
