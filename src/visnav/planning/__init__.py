"""Global planning, local planning and the navigator (move_base).

The algorithms are plain classes: :class:`GlobalPlanner` (navfn / global_planner),
:class:`DWAPlanner` (dwa_local_planner), :class:`RegulatedPurePursuit` (nav2), the
recovery behaviours and the :class:`Navigator` state machine. The graph node
(:class:`visnav.planning.nodes.NavigatorNode`) lives in :mod:`visnav.planning.nodes`.
"""

from __future__ import annotations

from visnav.planning.dwa import DWAParams, DWAPlanner, velocity_samples
from visnav.planning.errors import PlanningError
from visnav.planning.global_planner import (
    GlobalPlanner,
    GlobalPlannerParams,
    PlanResult,
    PlanStatus,
    path_to_msg,
    weight_table,
)
from visnav.planning.local_planner import (
    ControlResult,
    LocalPlanner,
    Pose2D,
    angle_diff,
    compose_2d,
    footprint_in_collision,
    invert_2d,
    transform_global_plan,
    transform_poses,
)
from visnav.planning.navigator import (
    GoalHandle,
    GoalStatus,
    NavError,
    Navigator,
    NavigatorParams,
    NavState,
    default_recoveries,
)
from visnav.planning.pure_pursuit import (
    RegulatedPurePursuit,
    RPPParams,
    carrot_curvature,
    circle_segment_intersection,
)
from visnav.planning.recovery import (
    BackUpRecovery,
    ClearCostmapRecovery,
    Recovery,
    RecoveryContext,
    RecoveryStep,
    RotateRecovery,
)
from visnav.planning.rotation_shim import RotationShim

__all__ = [
    "BackUpRecovery",
    "ClearCostmapRecovery",
    "ControlResult",
    "DWAParams",
    "DWAPlanner",
    "GlobalPlanner",
    "GlobalPlannerParams",
    "GoalHandle",
    "GoalStatus",
    "LocalPlanner",
    "NavError",
    "NavState",
    "Navigator",
    "NavigatorParams",
    "PlanResult",
    "PlanStatus",
    "PlanningError",
    "Pose2D",
    "RPPParams",
    "Recovery",
    "RecoveryContext",
    "RecoveryStep",
    "RegulatedPurePursuit",
    "RotateRecovery",
    "RotationShim",
    "angle_diff",
    "carrot_curvature",
    "circle_segment_intersection",
    "compose_2d",
    "default_recoveries",
    "footprint_in_collision",
    "invert_2d",
    "path_to_msg",
    "transform_global_plan",
    "transform_poses",
    "velocity_samples",
    "weight_table",
]
