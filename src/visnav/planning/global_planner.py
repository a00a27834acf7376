"""Global planning on a costmap: navfn / global_planner semantics (Dijkstra or A*).

Cell costs become traversal weights as in global_planner's ``getCost``::

    cost <  lethal_cost - 1 (252)          -> neutral_cost + cost_factor * cost (<= 252)
    cost == NO_INFORMATION, allow_unknown  -> the same formula (so 252)
    anything else                          -> blocked

with global_planner's defaults ``neutral_cost`` 50, ``cost_factor`` 3.0, ``lethal_cost``
253, ``allow_unknown`` true. The border of the map is blocked (``outlineMap``) and the
robot's own cell is always free (``clearRobotCell``). The potential spreads from the
robot's cell (``use_dijkstra`` true: Dijkstra, false: A* with the Euclidean distance
times ``neutral_cost``), by the eikonal update (``use_quadratic`` true) or exactly on
the 8-connected grid graph (false). The path is then read from the goal back to the
robot by gradient descent in half-cell steps (navfn; ``use_grid_path`` false) or over
grid cells (true), and returned robot -> goal.

``default_tolerance`` (navfn, 0.0): when the goal cannot be reached, the reachable point
closest to the goal within that many metres (a square window, as navfn) is used.

Differences (and why):

* the eikonal update is solved exactly instead of global_planner's polynomial fit;
* plans fail at once with a reason (goal outside the map, in an obstacle or unknown
  space, no path) instead of only returning false;
* path poses face along the path (global_planner's ``orientation_mode`` "Forward"), the
  last one takes the goal's orientation;
* propagation stops when the goal cell is expanded (navfn's ``atStart``), or covers
  the whole reachable map when the goal is blocked and a tolerance is set;
* with A* and the eikonal update the potential at the goal can exceed Dijkstra's
  slightly (as in global_planner); in graph mode A* is exact.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.costmap_2d import NO_INFORMATION, Costmap2D
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Path, Point, Pose, PoseStamped
from visnav.planning._potential import gradient_path, grid_path, propagate
from visnav.planning.errors import PlanningError
from visnav.tf.transforms import quaternion_from_yaw

__all__ = [
    "GlobalPlanner",
    "GlobalPlannerParams",
    "PlanResult",
    "PlanStatus",
    "path_to_msg",
    "weight_table",
]


class PlanStatus(enum.Enum):
    """Outcome of a planning request."""

    OK = "ok"
    START_OUTSIDE_MAP = "start_outside_map"
    GOAL_OUTSIDE_MAP = "goal_outside_map"
    GOAL_IN_OBSTACLE = "goal_in_obstacle"
    NO_PATH = "no_path"


@dataclass(frozen=True)
class GlobalPlannerParams:
    """global_planner / navfn parameters (defaults are theirs)."""

    neutral_cost: float = 50.0
    cost_factor: float = 3.0
    lethal_cost: int = 253
    allow_unknown: bool = True
    default_tolerance: float = 0.0
    use_dijkstra: bool = True
    use_quadratic: bool = True
    use_grid_path: bool = False
    outline_map: bool = True

    def __post_init__(self) -> None:
        if not (self.neutral_cost > 0 and math.isfinite(self.neutral_cost)):
            msg = f"neutral_cost is {self.neutral_cost}; expected a finite value > 0"
            raise PlanningError(msg)
        if not (self.cost_factor >= 0 and math.isfinite(self.cost_factor)):
            msg = f"cost_factor is {self.cost_factor}; expected a finite value >= 0"
            raise PlanningError(msg)
        if not 1 <= self.lethal_cost <= 255:
            msg = f"lethal_cost is {self.lethal_cost}; expected 1..255"
            raise PlanningError(msg)
        if not (self.default_tolerance >= 0 and math.isfinite(self.default_tolerance)):
            msg = f"default_tolerance is {self.default_tolerance}; expected metres >= 0"
            raise PlanningError(msg)


def weight_table(params: GlobalPlannerParams) -> NDArray[np.float32]:
    """Cost (0..255) -> crossing weight (inf = blocked), global_planner's ``getCost``."""
    c = np.arange(256, dtype=np.float64)
    w = np.minimum(c * params.cost_factor + params.neutral_cost, params.lethal_cost - 1)
    passable = c < params.lethal_cost - 1
    if params.allow_unknown:
        passable[NO_INFORMATION] = True
    return np.where(passable, w, np.inf).astype(np.float32)


@dataclass
class PlanResult:
    """A plan: poses ``(x, y, yaw)`` in the costmap frame, robot first, or why there is none.

    Attributes:
        status: the outcome.
        poses: (N, 3) plan (empty unless OK).
        reason: a sentence naming the problem (empty when OK).
        cost: potential at the goal used (the path cost in weight units).
        expanded: cells the search expanded.
        goal_used: the goal cell centre actually planned to (differs with a tolerance).
        potential: the potential grid (inf where not reached).
    """

    status: PlanStatus
    poses: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 3)))
    reason: str = ""
    cost: float = math.inf
    expanded: int = 0
    goal_used: tuple[float, float] | None = None
    potential: NDArray[np.float32] | None = None

    @property
    def ok(self) -> bool:
        """True when a path was found."""
        return self.status is PlanStatus.OK

    @property
    def length(self) -> float:
        """Path length in metres."""
        if len(self.poses) < 2:
            return 0.0
        return float(np.hypot(*np.diff(self.poses[:, :2], axis=0).T).sum())


class GlobalPlanner:
    """Plans on a :class:`~visnav.mapping.Costmap2D`.

    Args:
        params: planner parameters.
    """

    def __init__(self, params: GlobalPlannerParams | None = None) -> None:
        self.params = params or GlobalPlannerParams()
        self._table = weight_table(self.params)

    def weights(self, costmap: Costmap2D) -> NDArray[np.float32]:
        """Crossing weight of every cell (border blocked with ``outline_map``)."""
        w = self._table[costmap.data]
        if self.params.outline_map and w.size:
            w[0, :] = w[-1, :] = np.inf
            w[:, 0] = w[:, -1] = np.inf
        return w

    def make_plan(
        self,
        costmap: Costmap2D,
        start: tuple[float, float] | tuple[float, float, float],
        goal: tuple[float, float] | tuple[float, float, float],
        *,
        tolerance: float | None = None,
    ) -> PlanResult:
        """Plan from ``start`` to ``goal`` (world ``(x, y[, yaw])`` in the costmap's frame).

        Args:
            costmap: the costmap.
            start: robot position.
            goal: goal position (and yaw for the last pose).
            tolerance: metres the goal may move when unreachable (default
                ``default_tolerance``).
        """
        p = self.params
        tol = p.default_tolerance if tolerance is None else float(tolerance)
        s_cell = costmap.world_to_map(start[0], start[1])
        if s_cell is None:
            return PlanResult(
                PlanStatus.START_OUTSIDE_MAP,
                reason=(
                    f"the robot at ({start[0]:.2f}, {start[1]:.2f}) is outside the global "
                    f"costmap {_extent(costmap)}"
                ),
            )
        g_cell = costmap.world_to_map(goal[0], goal[1])
        if g_cell is None:
            return PlanResult(
                PlanStatus.GOAL_OUTSIDE_MAP,
                reason=(
                    f"the goal ({goal[0]:.2f}, {goal[1]:.2f}) is outside the global costmap "
                    f"{_extent(costmap)}; planning will always fail to it"
                ),
            )
        w = self.weights(costmap)
        sx, sy = s_cell
        gx, gy = g_cell
        w[sy, sx] = (
            min(float(w[sy, sx]), p.neutral_cost) if np.isfinite(w[sy, sx]) else p.neutral_cost
        )
        goal_blocked = not np.isfinite(w[gy, gx])
        if goal_blocked and tol <= 0:
            return PlanResult(
                PlanStatus.GOAL_IN_OBSTACLE,
                reason=self._blocked_text(costmap, goal, int(costmap.data[gy, gx])),
            )
        pot, expanded = propagate(
            w,
            sx,
            sy,
            gx,
            gy,
            p.use_quadratic,
            not p.use_dijkstra,
            not goal_blocked,
            p.neutral_cost,
            p.neutral_cost,
        )
        if not np.isfinite(pot[gy, gx]):
            best = self._within_tolerance(costmap, pot, goal, tol) if tol > 0 else None
            if best is None:
                if goal_blocked:
                    return PlanResult(
                        PlanStatus.GOAL_IN_OBSTACLE,
                        reason=self._blocked_text(costmap, goal, int(costmap.data[gy, gx]))
                        + f" and no reachable cell lies within the tolerance {tol:.2f} m",
                        expanded=expanded,
                        potential=pot,
                    )
                return PlanResult(
                    PlanStatus.NO_PATH,
                    reason=(
                        f"no path from ({start[0]:.2f}, {start[1]:.2f}) to ({goal[0]:.2f}, "
                        f"{goal[1]:.2f}): the goal is not connected to the robot through free "
                        "or (allowed) unknown cells"
                    ),
                    expanded=expanded,
                    potential=pot,
                )
            gx, gy = best
        cells = self._extract(pot, w, sx, sy, gx, gy)
        if len(cells) == 0:
            return PlanResult(
                PlanStatus.NO_PATH,
                reason="path extraction from the potential failed (no descent to the robot)",
                expanded=expanded,
                potential=pot,
            )
        cells = cells[::-1]
        xy = np.empty_like(cells)
        xy[:, 0] = costmap.origin_x + (cells[:, 0] + 0.5) * costmap.resolution
        xy[:, 1] = costmap.origin_y + (cells[:, 1] + 0.5) * costmap.resolution
        xy[0] = start[:2]
        if (gx, gy) == g_cell:
            xy[-1] = goal[:2]
        goal_yaw = float(goal[2]) if len(goal) > 2 else None
        poses = _orient(xy, goal_yaw)
        gx_w, gy_w = costmap.map_to_world(gx, gy)
        return PlanResult(
            PlanStatus.OK,
            poses=poses,
            cost=float(pot[gy, gx]),
            expanded=expanded,
            goal_used=(gx_w, gy_w),
            potential=pot,
        )

    def _extract(
        self,
        pot: NDArray[np.float32],
        w: NDArray[np.float32],
        sx: int,
        sy: int,
        gx: int,
        gy: int,
    ) -> NDArray[np.float64]:
        p = self.params
        if not p.use_grid_path and p.use_quadratic:
            h, wd = pot.shape
            cells = gradient_path(
                pot, sx, sy, gx, gy, 0.5, 4 * (h + wd) + 4 * int(math.hypot(gx - sx, gy - sy)) + 100
            )
            if len(cells):
                return cells
        return grid_path(pot, w, sx, sy, gx, gy, p.use_quadratic)

    def _within_tolerance(
        self,
        costmap: Costmap2D,
        pot: NDArray[np.float32],
        goal: tuple[float, ...],
        tol: float,
    ) -> tuple[int, int] | None:
        x0, y0 = costmap.world_to_map_enforce_bounds(goal[0] - tol, goal[1] - tol)
        x1, y1 = costmap.world_to_map_enforce_bounds(goal[0] + tol, goal[1] + tol)
        win = pot[y0 : y1 + 1, x0 : x1 + 1]
        if not np.isfinite(win).any():
            return None
        ys, xs = np.nonzero(np.isfinite(win))
        wx = costmap.origin_x + (xs + x0 + 0.5) * costmap.resolution
        wy = costmap.origin_y + (ys + y0 + 0.5) * costmap.resolution
        k = int(np.argmin((wx - goal[0]) ** 2 + (wy - goal[1]) ** 2))
        return int(xs[k] + x0), int(ys[k] + y0)

    def _blocked_text(self, costmap: Costmap2D, goal: tuple[float, ...], cost: int) -> str:
        if cost == NO_INFORMATION:
            return (
                f"the goal ({goal[0]:.2f}, {goal[1]:.2f}) is in unknown space and allow_unknown "
                "is false"
            )
        what = {254: "an obstacle", 253: "the inscribed radius of an obstacle"}.get(
            cost, "a cell too close to an obstacle"
        )
        return (
            f"the goal ({goal[0]:.2f}, {goal[1]:.2f}) is in {what} (cost {cost}, blocked from "
            f"{self.params.lethal_cost - 1})"
        )


def _extent(costmap: Costmap2D) -> str:
    return (
        f"x [{costmap.origin_x:.2f}, {costmap.origin_x + costmap.size_in_meters_x:.2f}], "
        f"y [{costmap.origin_y:.2f}, {costmap.origin_y + costmap.size_in_meters_y:.2f}]"
    )


def _orient(xy: NDArray[np.float64], goal_yaw: float | None) -> NDArray[np.float64]:
    n = len(xy)
    out = np.zeros((n, 3))
    out[:, :2] = xy
    if n >= 2:
        d = np.diff(xy, axis=0)
        out[:-1, 2] = np.arctan2(d[:, 1], d[:, 0])
        out[-1, 2] = out[-2, 2]
    if goal_yaw is not None and n:
        out[-1, 2] = goal_yaw
    return out


def path_to_msg(poses: NDArray[np.float64], frame_id: str, stamp_ns: int = 0) -> Path:
    """``nav_msgs/Path`` of ``(x, y, yaw)`` poses."""
    stamp = ns_to_time(stamp_ns)
    header = Header(stamp=stamp, frame_id=frame_id)
    out = []
    for x, y, yaw in np.asarray(poses, dtype=np.float64).reshape(-1, 3):
        q = quaternion_from_yaw(yaw)
        out.append(
            PoseStamped(
                header=Header(stamp=stamp, frame_id=frame_id),
                pose=Pose(position=Point(x=float(x), y=float(y), z=0.0), orientation=q),
            )
        )
    return Path(header=header, poses=out)
