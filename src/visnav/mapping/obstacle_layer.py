"""The obstacle layer: marking and ray-trace clearing from sensors (costmap_2d's ``ObstacleLayer``).

Each update, in costmap_2d's order:

1. a rolling costmap moves the layer's grid with the robot;
2. every *clearing* observation clears (FREE) the cells on the ray from the sensor
   origin to each point, up to ``raytrace_range`` (end cell included, rays clipped
   to the map edge; a sensor origin outside the map clears nothing);
3. every *marking* observation marks LETHAL the cell of each point whose 3D distance
   from the origin is below ``obstacle_range`` and whose z is at most the layer's
   ``max_obstacle_height``;
4. the robot footprint is cleared (``footprint_clearing_enabled``) and the layer is
   combined into the master with ``combination_method`` (0 overwrite, 1 maximum).

Sensor messages are taken into the global frame through a :class:`visnav.tf.Buffer`
at their stamp. A message whose transform is not available yet waits (at most
``max_pending`` per source, tf2's message filter behaviour) and is retried at the
next update.

Differences: laser scans are transformed with the transform at the scan stamp
(costmap_2d's "high fidelity" projection interpolates per beam); clearing of the
cells under the footprint happens in the layer before combining, as costmap_2d does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.mapping._raytrace import raytrace_set
from visnav.mapping.costmap_2d import (
    FREE_SPACE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Bounds,
    Costmap2D,
)
from visnav.mapping.errors import ObservationError
from visnav.mapping.footprint import transform_footprint
from visnav.mapping.layer import CostmapLayer
from visnav.mapping.observation import (
    Observation,
    ObservationBuffer,
    ObservationSource,
    cloud_points,
    scan_points,
)
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import LaserScan, PointCloud2
from visnav.tf.buffer import Buffer
from visnav.tf.errors import ExtrapolationException, TransformException

__all__ = ["ObstacleLayer"]


@dataclass
class _Pending:
    msg: LaserScan | PointCloud2
    received_ns: int


class ObstacleLayer(CostmapLayer):
    """Obstacles from laser scans and point clouds.

    Args:
        name: plugin name.
        sources: the observation sources.
        tf: the transform buffer used to bring messages into the global frame
            (needed by :meth:`add_scan` / :meth:`add_cloud`, not by :meth:`add_points`).
        footprint_clearing_enabled: clear the cells under the robot (True).
        max_obstacle_height: highest point that marks (2.0 m).
        combination_method: 0 overwrite, 1 maximum (1).
        track_unknown_space: None follows the layered costmap.
        max_pending: messages per source waiting for their transform.
        enabled: take part in updates.

    Raises:
        ObservationError: two sources with the same name, or a bad combination method.
    """

    def __init__(
        self,
        name: str = "obstacle_layer",
        *,
        sources: Sequence[ObservationSource] = (),
        tf: Buffer | None = None,
        footprint_clearing_enabled: bool = True,
        max_obstacle_height: float = 2.0,
        combination_method: int = 1,
        track_unknown_space: bool | None = None,
        max_pending: int = 10,
        enabled: bool = True,
    ) -> None:
        super().__init__(name, enabled=enabled)
        if combination_method not in (0, 1):
            msg = f"{name}: combination_method is {combination_method}; expected 0 or 1"
            raise ObservationError(msg)
        names = [s.name for s in sources]
        if len(set(names)) != len(names):
            msg = f"{name}: observation source names repeat: {names}"
            raise ObservationError(msg)
        self.buffers = {s.name: ObservationBuffer(s) for s in sources}
        self.tf = tf
        self.footprint_clearing_enabled = footprint_clearing_enabled
        self.max_obstacle_height = max_obstacle_height
        self.combination_method = combination_method
        self.track_unknown_space = track_unknown_space
        self.max_pending = max_pending
        self._pending: dict[str, list[_Pending]] = {s.name: [] for s in sources}
        self.transformed_footprint: NDArray[np.float64] = np.empty((0, 2))
        self.tf_error = ""
        self.dropped = 0

    def on_initialize(self) -> None:
        """Resolve ``track_unknown_space``."""
        if self.track_unknown_space is None:
            self.track_unknown_space = self.layered.track_unknown_space
        self.grid.default_value = NO_INFORMATION if self.track_unknown_space else FREE_SPACE

    @property
    def is_clearable(self) -> bool:
        """Obstacle layers are cleared by recovery behaviours."""
        return True

    # ------------------------------------------------------------------ input
    def _buffer(self, source: str) -> ObservationBuffer:
        try:
            return self.buffers[source]
        except KeyError:
            msg = f"{self.name}: no observation source {source!r}; sources: {list(self.buffers)}"
            raise ObservationError(msg) from None

    def add_points(
        self,
        source: str,
        points_sensor: NDArray[np.float64],
        T_global_sensor: NDArray[np.float64],  # noqa: N803
        *,
        stamp_ns: int,
        now_ns: int,
        T_global_origin: NDArray[np.float64] | None = None,  # noqa: N803
        empty_text: str = "",
    ) -> None:
        """Buffer points already paired with their transform (no TF needed)."""
        self._buffer(source).buffer_points(
            np.asarray(points_sensor, dtype=np.float64).reshape(-1, 3),
            T_global_sensor,
            stamp_ns=stamp_ns,
            now_ns=now_ns,
            T_global_origin=T_global_origin,
            empty_text=empty_text,
        )

    def add_scan(self, source: str, msg: LaserScan, now_ns: int) -> bool:
        """Buffer a scan; False when it waits for its transform.

        A message whose transform fails for another reason than "not yet" (unknown
        frame, too old) is dropped; ``tf_error`` keeps the reason.
        """
        return self._add(source, msg, now_ns)

    def add_cloud(self, source: str, msg: PointCloud2, now_ns: int) -> bool:
        """Buffer a cloud; False when it waits for its transform."""
        return self._add(source, msg, now_ns)

    def _add(self, source: str, msg: LaserScan | PointCloud2, now_ns: int) -> bool:
        self._buffer(source)
        queue = self._pending[source]
        while queue and self._try(source, queue[0].msg, now_ns):
            queue.pop(0)
        if not queue and self._try(source, msg, now_ns):
            return True
        queue.append(_Pending(msg, now_ns))
        if len(queue) > self.max_pending:
            queue.pop(0)
            self.dropped += 1
        return False

    def _try(self, source: str, msg: LaserScan | PointCloud2, now_ns: int) -> bool:
        """Buffer ``msg``; False when its transform is not there yet (it should wait)."""
        buf = self.buffers[source]
        src = buf.source
        if self.tf is None:
            text = f"{self.name}: add_scan/add_cloud need a tf Buffer; pass tf= or use add_points"
            raise ObservationError(text)
        frame = msg.header.frame_id
        stamp = time_to_ns(msg.header.stamp)
        global_frame = self.layered.global_frame
        try:
            T = self.tf.lookup_transform_matrix(global_frame, frame, stamp)  # noqa: N806
            T_origin = (  # noqa: N806
                self.tf.lookup_transform_matrix(global_frame, src.sensor_frame, stamp)
                if src.sensor_frame
                else None
            )
        except TransformException as exc:
            if not _not_yet(exc):
                self.dropped += 1
                self.tf_error = (
                    f"{self.name}: dropped a message on '{src.resolved_topic}': no transform from "
                    f"'{frame}' to '{global_frame}': {exc}"
                )
                return True
            self.tf_error = (
                f"{self.name}: no transform from '{frame}' to '{global_frame}' at the stamp of "
                f"a message on '{src.resolved_topic}': {exc}"
            )
            return False
        self.tf_error = ""
        if isinstance(msg, LaserScan):
            pts, n = scan_points(msg, inf_is_valid=src.inf_is_valid, cache=buf.scan_cache)
            empty = "" if n else "the scan has no ranges (zero beams)"
        else:
            pts = cloud_points(msg)
            empty = "" if msg.width * msg.height else "the cloud has no points (width x height 0)"
        buf.buffer_points(
            pts, T, stamp_ns=stamp, now_ns=now_ns, T_global_origin=T_origin, empty_text=empty
        )
        return True

    def _retry_pending(self, now_ns: int) -> None:
        for source, queue in self._pending.items():
            while queue and self._try(source, queue[0].msg, now_ns):
                queue.pop(0)

    # ------------------------------------------------------------------ update
    def is_current(self, now_ns: int) -> bool:
        """All sources current (see :meth:`ObservationBuffer.is_current`)."""
        reasons = []
        for buf in self.buffers.values():
            ok, why = buf.is_current(now_ns)
            if not ok:
                reasons.append(why)
        if reasons and self.tf_error:
            reasons.append(self.tf_error)
        self.current = not reasons
        self.reason = "; ".join(reasons)
        return self.current

    def update_bounds(
        self, robot_x: float, robot_y: float, robot_yaw: float, bounds: Bounds
    ) -> None:
        """Roll, clear, mark and touch the footprint (see the module docs)."""
        layered = self.layered
        if layered.rolling_window:
            g = self.grid
            g.update_origin(robot_x - g.size_in_meters_x / 2, robot_y - g.size_in_meters_y / 2)
        if not self.enabled:
            return
        if self._pending and self.tf is not None:
            self._retry_pending(layered.now_ns)
        clearing: list[Observation] = []
        marking: list[Observation] = []
        for buf in self.buffers.values():
            kept = buf.get_observations()
            if buf.source.clearing:
                clearing.extend(kept)
            if buf.source.marking:
                marking.extend(kept)
        for obs in clearing:
            self.raytrace_freespace(obs, bounds)
        for obs in marking:
            self.mark(obs, bounds)
        self.update_footprint(robot_x, robot_y, robot_yaw, bounds)

    def mark(self, obs: Observation, bounds: Bounds) -> None:
        """Mark the observation's points as LETHAL (height and obstacle_range checks)."""
        pts = obs.points
        if len(pts) == 0:
            return
        d2 = ((pts - obs.origin) ** 2).sum(axis=1)
        ok = (pts[:, 2] <= self.max_obstacle_height) & (d2 < obs.obstacle_range**2)
        mx, my, inside = self.grid.world_to_map_array(pts[:, :2])
        ok &= inside
        if not ok.any():
            return
        self.grid.data[my[ok], mx[ok]] = LETHAL_OBSTACLE
        sel = pts[ok]
        bounds.touch(float(sel[:, 0].min()), float(sel[:, 1].min()))
        bounds.touch(float(sel[:, 0].max()), float(sel[:, 1].max()))

    def raytrace_freespace(self, obs: Observation, bounds: Bounds) -> None:
        """Clear the cells from the sensor origin to each point (costmap_2d's rules)."""
        g = self.grid
        ox, oy = float(obs.origin[0]), float(obs.origin[1])
        start = g.world_to_map(ox, oy)
        if start is None:
            self.reason = (
                f"{self.name}: the sensor origin ({ox:.2f}, {oy:.2f}) is outside the costmap; "
                "it cannot ray-trace from there"
            )
            return
        pts = obs.points
        bounds.touch(ox, oy)
        if len(pts) == 0:
            return
        wx, wy = _clip_to_map(g, ox, oy, pts[:, 0].copy(), pts[:, 1].copy())
        mx, my, inside = g.world_to_map_array(np.stack([wx, wy], axis=1))
        if not inside.any():
            return
        ends = np.stack([mx[inside], my[inside]], axis=1)
        cells = float(g.cell_distance(obs.raytrace_range))
        raytrace_set(g.data, start[0], start[1], ends, cells, FREE_SPACE)
        # updateRaytraceBounds: the ray's end, cut at raytrace_range
        dx = wx[inside] - ox
        dy = wy[inside] - oy
        dist = np.hypot(dx, dy)
        scale = np.minimum(1.0, obs.raytrace_range / np.where(dist > 0, dist, 1.0))
        ex = ox + dx * scale
        ey = oy + dy * scale
        bounds.touch(float(ex.min()), float(ey.min()))
        bounds.touch(float(ex.max()), float(ey.max()))

    def update_footprint(
        self, robot_x: float, robot_y: float, robot_yaw: float, bounds: Bounds
    ) -> None:
        """Place the footprint at the robot and touch its corners."""
        if not self.footprint_clearing_enabled:
            return
        fp = transform_footprint(self.layered.footprint.points, robot_x, robot_y, robot_yaw)
        self.transformed_footprint = fp
        for x, y in fp:
            bounds.touch(float(x), float(y))

    def update_costs(self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int) -> None:
        """Clear the footprint, then combine into the master."""
        if not self.enabled:
            return
        if self.footprint_clearing_enabled and len(self.transformed_footprint):
            self.grid.set_convex_polygon_cost(self.transformed_footprint, FREE_SPACE)
        if self.combination_method == 0:
            self.update_with_overwrite(master, x0, y0, xn, yn)
        else:
            self.update_with_max(master, x0, y0, xn, yn)

    def reset(self) -> None:
        """Clear the grid and the buffered observations."""
        super().reset()
        for buf in self.buffers.values():
            buf.clear()
        now = self.layered.now_ns if self._layered is not None else 0
        for buf in self.buffers.values():
            buf.reset_last_updated(now)


def _clip_to_map(
    g: Costmap2D, ox: float, oy: float, wx: NDArray[np.float64], wy: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cut rays that leave the map at its edge (costmap_2d's raytraceFreespace clipping)."""
    x_lo, y_lo = g.origin_x, g.origin_y
    x_hi, y_hi = x_lo + g.size_in_meters_x, y_lo + g.size_in_meters_y
    with np.errstate(divide="ignore", invalid="ignore"):
        a = wx - ox
        b = wy - oy
        m = wx < x_lo
        t = (x_lo - ox) / a
        wy = np.where(m, oy + b * t, wy)
        wx = np.where(m, x_lo, wx)
        m = wy < y_lo
        t = (y_lo - oy) / b
        wx = np.where(m, ox + a * t, wx)
        wy = np.where(m, y_lo, wy)
        m = wx > x_hi
        t = (x_hi - ox) / a
        wy = np.where(m, oy + b * t, wy)
        wx = np.where(m, x_hi - 0.001, wx)
        m = wy > y_hi
        t = (y_hi - oy) / b
        wx = np.where(m, ox + a * t, wx)
        wy = np.where(m, y_hi - 0.001, wy)
    return wx, wy


def _not_yet(exc: TransformException) -> bool:
    """Whether a lookup failed only because the transform for that time has not arrived."""
    return isinstance(exc, ExtrapolationException) and exc.requested_ns > exc.latest_ns
