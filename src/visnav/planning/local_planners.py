"""Local planners by name: move_base's ``base_local_planner`` / nav2's controller plugins.

:data:`LOCAL_PLANNERS` maps a plugin type to a ``module:function`` factory, imported
only when the planner is built; :data:`LOCAL_PLANNER_ALIASES` maps the other
accepted spellings (short names, nav2's ``pkg::Type``) to it. A factory takes the
node and the controller frequency, declares the planner's parameters (its params
dataclass, under its namespace) and returns a :class:`BuiltLocalPlanner`.

Adding a planner: write its module (algorithm + params dataclass + a ``make`` factory)
and add one line to :data:`LOCAL_PLANNERS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from visnav.graph.param_dataclass import declare_params
from visnav.planning.errors import PlanningError
from visnav.planning.local_planner import LocalPlanner
from visnav.plugin_registry import UnknownPluginError, canonical_name, resolve_factory

__all__ = [
    "DWA_DEFAULTS",
    "LOCAL_PLANNERS",
    "LOCAL_PLANNER_ALIASES",
    "BuiltLocalPlanner",
    "make_dwa",
    "make_local_planner",
    "make_rpp",
]

LOCAL_PLANNERS: Mapping[str, str] = {
    "dwa_local_planner/DWAPlannerROS": "visnav.planning.local_planners:make_dwa",
    "nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController": (
        "visnav.planning.local_planners:make_rpp"
    ),
}

LOCAL_PLANNER_ALIASES: Mapping[str, str] = {
    "dwa": "dwa_local_planner/DWAPlannerROS",
    "DWAPlannerROS": "dwa_local_planner/DWAPlannerROS",
    "rpp": "nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController",
    "pure_pursuit": "nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController",
    "RegulatedPurePursuit": (
        "nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController"
    ),
}

DWA_DEFAULTS: Mapping[str, Any] = {
    "xy_goal_tolerance": 0.15,
    "latch_xy_goal_tolerance": True,
}
"""Shipped DWA settings: dwa_local_planner's 0.1 m, unlatched, lets the robot spin in place
just outside the tolerance (its rollouts cannot make a 1 cm step)."""


@dataclass(frozen=True)
class BuiltLocalPlanner:
    """A local planner made by a factory.

    Attributes:
        planner: The planner.
        local_plan_topic: Where the node publishes its chosen trajectory (``~/NS/local_plan``).
    """

    planner: LocalPlanner
    local_plan_topic: str


def make_dwa(node: Any, *, controller_frequency: float) -> BuiltLocalPlanner:
    """dwa_local_planner: parameters ``DWAPlannerROS.*`` (:class:`DWAParams`)."""
    from visnav.planning.dwa import DWAParams, DWAPlanner  # noqa: PLC0415 - lazy plugin

    params = declare_params(
        node,
        DWAParams,
        prefix="DWAPlannerROS.",
        defaults={"controller_frequency": controller_frequency, **DWA_DEFAULTS},
    )
    return BuiltLocalPlanner(DWAPlanner(params), "~/DWAPlannerROS/local_plan")


def make_rpp(node: Any, *, controller_frequency: float) -> BuiltLocalPlanner:
    """nav2's regulated pure pursuit: parameters ``RegulatedPurePursuit.*`` (:class:`RPPParams`)."""
    from visnav.planning.pure_pursuit import RegulatedPurePursuit, RPPParams  # noqa: PLC0415

    params = declare_params(
        node,
        RPPParams,
        prefix="RegulatedPurePursuit.",
        defaults={"controller_frequency": controller_frequency},
    )
    return BuiltLocalPlanner(RegulatedPurePursuit(params), "~/RegulatedPurePursuit/local_plan")


def make_local_planner(kind: str, node: Any, *, controller_frequency: float) -> BuiltLocalPlanner:
    """Build the local planner named ``kind`` (``base_local_planner``'s value).

    Raises:
        PlanningError: ``kind`` is not registered (closest names suggested), or its
            factory does not import or returns no :class:`BuiltLocalPlanner`.
    """
    try:
        name = canonical_name(
            kind,
            LOCAL_PLANNERS,
            LOCAL_PLANNER_ALIASES,
            what="local planner",
            field="base_local_planner",
        )
        factory = resolve_factory(name, LOCAL_PLANNERS, what="local planner")
    except UnknownPluginError as exc:
        raise PlanningError(str(exc)) from exc
    built = factory(node, controller_frequency=controller_frequency)
    if not isinstance(built, BuiltLocalPlanner):
        msg = f"local planner {name!r}: its factory returned {type(built).__name__}, not a planner"
        raise PlanningError(msg)
    return built
