"""roslaunch nodes of the ROS 1 navigation stack and the TurtleBot3 tutorials, mapped onto visnav.

===========================================  ==================================================
roslaunch                                    visnav
===========================================  ==================================================
``map_server map_server`` (args ``MAP``)     ``map_server``: the map YAML argument ->
                                             ``yaml_filename`` (``map:=TOPIC`` args -> remaps)
``map_server map_saver`` (args ``-f NAME``   ``map_saver``: ``-f`` -> ``file``,
``--occ N --free N``, ``map:=TOPIC``)        ``--occ`` / ``--free`` -> ``threshold_occupied`` /
                                             ``threshold_free``; ``map:=TOPIC`` -> a remap
``amcl amcl``                                ``amcl``: ROS 1 names -> nav2's (``kld_err`` ->
                                             ``pf_err``, ``laser_max_beams`` -> ``max_beams``,
                                             ``odom_alpha1..4`` -> ``alpha1..4``,
                                             ``laser_z_hit`` -> ``z_hit``, ...);
                                             ``initial_pose_x|y|a`` -> ``initial_pose.*`` and
                                             ``set_initial_pose`` (ROS 1 amcl always starts
                                             there, at (0, 0, 0) by default)
``move_base move_base``                      ``move_base``: move_base's own parameters; the
                                             costmaps' pre-Hydro parameters
                                             (``static_map``, ``map_type``,
                                             ``observation_sources``, ``obstacle_range``,
                                             ``inflation_radius``, ...) -> visnav's layers, as
                                             costmap_2d's ``loadOldParameters``; ROS 1
                                             ``plugins`` lists (``{name, type}``);
                                             ``DWAPlannerROS/*``
``gmapping slam_gmapping``                   ``slam_gmapping`` (gmapping's parameters)
``explore_lite explore``                     ``explore_lite`` (m-explore's parameters)
``turtlebot3_teleop turtlebot3_teleop_key``  ``turtlebot3_teleop_key``: the global ``model``
                                             parameter -> ``model``
``teleop_twist_keyboard``                    ``teleop_twist_keyboard``
``teleop_twist_keyboard.py``
===========================================  ==================================================

A parameter visnav has no counterpart for is named in the import's notes (with why) or,
where ignoring it would change what the robot does, refused by name; nothing is dropped
silently. A node type whose visnav node is not in :data:`visnav.node_registry.BUILTIN_NODES`
is refused with that reason.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from visnav.node_registry import BUILTIN_NODES

if TYPE_CHECKING:
    from visnav.launch.description import NodeSpec
    from visnav.launch.ros_nodes import ParamServer, RosNode

__all__ = ["NAV_TRANSLATORS", "costmap_params_from_ros1"]

Translation = tuple["NodeSpec | None", list[str]]
Translator = Callable[["RosNode", "ParamServer", Mapping[str, str]], Translation]


def _missing(node: RosNode, executable: str) -> list[str]:
    if executable in BUILTIN_NODES:
        return []
    return [
        f"<node pkg={node.pkg!r} type={node.type!r}> ({node.fqn}): visnav's {executable!r} "
        "node is not available in this installation"
    ]


def _no_args(node: RosNode, executable: str) -> list[str]:
    if node.args:
        return [f"{executable} {node.fqn}: arguments {list(node.args)} are not mapped"]
    return []


def _note(params: ParamServer, node: RosNode, text: str) -> None:
    params.notes.append(f"{node.source}: {node.type} {node.fqn}: {text}")


# ---------------------------------------------------------------------- map_server
def _map_server(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    from visnav.mapping.map_io import MapFileError  # noqa: PLC0415 - only when mapped
    from visnav.mapping.map_server_node import map_server_args  # noqa: PLC0415

    private = params.private(node.fqn)
    issues = _missing(node, "map_server")
    remaps = node.remaps
    if node.args or "yaml_filename" not in private:
        try:
            values, extra = map_server_args(node.args)
        except MapFileError as exc:
            return None, [*issues, f"map_server {node.fqn}: {exc}"]
        private.update(values)
        remaps = (*extra, *remaps)
    return node.spec("map_server", private, remaps=remaps), issues


def _map_saver(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    from visnav.mapping.map_saver_node import (  # noqa: PLC0415 - only when mapped
        MapSaverArgsError,
        parse_map_saver_args,
    )

    private = params.private(node.fqn)
    issues = _missing(node, "map_saver")
    try:
        parsed = parse_map_saver_args(node.args)
    except MapSaverArgsError as exc:
        return None, [*issues, f"map_saver {node.fqn}: {exc}"]
    private.update(
        {"file": parsed.file, "threshold_occupied": parsed.occ, "threshold_free": parsed.free}
    )
    # alone in its process map_saver ends it after writing, as ROS 1's does
    spec = node.spec("map_saver", private, remaps=(*parsed.remaps, *node.remaps), process="own")
    return spec, issues


# ---------------------------------------------------------------------- amcl
_AMCL_RENAMES = {
    "kld_err": "pf_err",
    "kld_z": "pf_z",
    "laser_max_beams": "max_beams",
    "laser_z_hit": "z_hit",
    "laser_z_rand": "z_rand",
    "laser_sigma_hit": "sigma_hit",
    "odom_alpha1": "alpha1",
    "odom_alpha2": "alpha2",
    "odom_alpha3": "alpha3",
    "odom_alpha4": "alpha4",
    "odom_model_type": "robot_model_type",
}
_AMCL_BEAM_ONLY = ("laser_z_short", "laser_z_max", "laser_lambda_short")
_AMCL_NOT_USED = {
    "gui_publish_rate": "visnav publishes particlecloud after every filter update",
    "save_pose_rate": "visnav does not store the pose on the parameter server",
    "use_map_topic": "visnav's amcl always subscribes the map topic (ROS 1 amcl's true)",
    "odom_alpha5": "used only by amcl's omni model; visnav has the diff model only",
}


def _amcl(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    issues = _missing(node, "amcl") + _no_args(node, "amcl")
    private = params.private(node.fqn)
    out: dict[str, Any] = {}
    initial = {"initial_pose_x": "x", "initial_pose_y": "y", "initial_pose_a": "yaw"}
    # ROS 1 amcl starts from initial_pose_* (0, 0, 0) at once; nav2 waits for one
    out["set_initial_pose"] = True
    for key in ("x", "y", "yaw"):
        out[f"initial_pose.{key}"] = 0.0
    for key, value in private.items():
        if key in initial:
            try:
                out[f"initial_pose.{initial[key]}"] = float(value)
            except (TypeError, ValueError):
                issues.append(f"amcl {node.fqn}: {key} {value!r} is not a number")
        elif key in _AMCL_RENAMES:
            out[_AMCL_RENAMES[key]] = value
        elif key in _AMCL_BEAM_ONLY:
            model = str(private.get("laser_model_type", "likelihood_field"))
            if model == "beam":
                continue  # refused below with the model
            _note(
                params,
                node,
                f"{key}={value} is read only by amcl's beam model; the {model} model "
                "(amcl's too) does not use it",
            )
        elif key in _AMCL_NOT_USED:
            _note(params, node, f"{key}={value} is ignored: {_AMCL_NOT_USED[key]}")
        elif key.startswith("beam_skip") or key == "do_beamskip":
            if str(value).lower() in ("false", "0") or key != "do_beamskip":
                _note(params, node, f"{key}={value} is ignored (no beam skipping in visnav)")
            else:
                issues.append(f"amcl {node.fqn}: do_beamskip:=true is not available in visnav")
        else:
            out[key] = value
    if str(out.get("laser_model_type", "likelihood_field")) == "beam":
        issues.append(
            f"amcl {node.fqn}: laser_model_type beam is not available in visnav (use "
            "likelihood_field, amcl's default in the TurtleBot3 and nav tutorials)"
        )
    return node.spec("amcl", out), issues


# ---------------------------------------------------------------------- move_base
_COSTMAP_DIRECT = frozenset(
    {
        "global_frame",
        "robot_base_frame",
        "transform_tolerance",
        "update_frequency",
        "publish_frequency",
        "rolling_window",
        "width",
        "height",
        "resolution",
        "origin_x",
        "origin_y",
        "track_unknown_space",
        "footprint",
        "robot_radius",
        "footprint_padding",
    }
)
_OBSTACLE_OLD = frozenset(
    {"max_obstacle_height", "combination_method", "footprint_clearing_enabled"}
)
_SOURCE_DEFAULTS = (
    "obstacle_range",
    "raytrace_range",
    "max_obstacle_height",
    "min_obstacle_height",
)
_INFLATION_OLD = frozenset({"inflation_radius", "cost_scaling_factor", "inflate_unknown"})
_STATIC_OLD = frozenset(
    {"map_topic", "lethal_cost_threshold", "unknown_cost_value", "trinary_costmap"}
)
_COSTMAP_NOT_USED = {
    "always_send_full_costmap": "visnav publishes the whole costmap each time",
    "publish_voxel_map": "visnav has no voxel layer",
}
_LAYER_TYPES = {
    "costmap_2d::StaticLayer": "StaticLayer",
    "costmap_2d::ObstacleLayer": "ObstacleLayer",
    "costmap_2d::InflationLayer": "InflationLayer",
}


def _footprint_text(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return "[" + ", ".join(f"[{float(p[0])}, {float(p[1])}]" for p in value) + "]"
    return value


def costmap_params_from_ros1(
    name: str, values: Mapping[str, Any]
) -> tuple[dict[str, Any], list[str], list[str]]:
    """A ROS 1 costmap's parameters (flat ``a.b`` names under the costmap) as visnav's.

    Pre-Hydro parameters become layers as costmap_2d's ``loadOldParameters`` makes them:
    ``static_map: true`` a ``static_layer``, ``map_type`` ``costmap`` an
    ``obstacle_layer`` that gets ``observation_sources``, each source's parameters and
    ``obstacle_range`` / ``raytrace_range`` / ``max_obstacle_height`` as the sources'
    defaults, and an ``inflation_layer`` with ``inflation_radius`` /
    ``cost_scaling_factor``. A ``plugins`` list of ``{name, type}`` maps (costmap_2d's
    Hydro style) is used as it is.

    Args:
        name: the costmap's name (``global_costmap``), for messages.
        values: its parameters relative to it (``obstacle_range``, ``scan.topic``, ...).

    Returns:
        ``(params relative to the costmap, notes, issues)``.
    """
    out: dict[str, Any] = {}
    notes: list[str] = []
    issues: list[str] = []
    rest = dict(values)
    plugins_value = rest.pop("plugins", None)
    if plugins_value is not None:
        names: list[str] = []
        for item in plugins_value if isinstance(plugins_value, list) else []:
            if isinstance(item, Mapping) and "name" in item:
                names.append(str(item["name"]))
                kind = str(item.get("type", ""))
                out[f"{item['name']}.plugin"] = _LAYER_TYPES.get(kind, kind)
            else:
                names.append(str(item))
        if not isinstance(plugins_value, list):
            issues.append(f"{name}/plugins {plugins_value!r} is not a list")
        out["plugins"] = names
        out.update(rest)
        if "footprint" in out:
            out["footprint"] = _footprint_text(out["footprint"])
        return out, notes, issues
    static = rest.pop("static_map", None)
    map_type = str(rest.pop("map_type", "costmap"))
    if map_type == "voxel":
        issues.append(
            f"{name}/map_type voxel: visnav has no VoxelLayer (a 2D ObstacleLayer with "
            "min/max_obstacle_height); set map_type: costmap"
        )
    elif map_type != "costmap":
        issues.append(f"{name}/map_type {map_type!r}: expected costmap or voxel")
    use_static = str(static).lower() in ("true", "1") if static is not None else True
    plugins = (["static_layer"] if use_static else []) + ["obstacle_layer", "inflation_layer"]
    out["plugins"] = plugins
    sources_text = rest.pop("observation_sources", None)
    sources = str(sources_text).split() if sources_text is not None else []
    if sources_text is not None:
        out["obstacle_layer.observation_sources"] = " ".join(sources)
    source_defaults = {k: rest[k] for k in _SOURCE_DEFAULTS if k in rest}
    for key in _SOURCE_DEFAULTS:
        if key != "max_obstacle_height":  # also the layer's own (below)
            rest.pop(key, None)
    for src in sources:
        for key, value in source_defaults.items():
            out[f"obstacle_layer.{src}.{key}"] = value
    for key, value in rest.items():
        head = key.split(".", 1)[0]
        if key in _COSTMAP_DIRECT:
            out[key] = _footprint_text(value) if key == "footprint" else value
        elif head in sources or key in _OBSTACLE_OLD:
            out[f"obstacle_layer.{key}"] = value
        elif key in _INFLATION_OLD:
            out[f"inflation_layer.{key}"] = value
        elif key in _STATIC_OLD:
            if use_static:
                out[f"static_layer.{key}"] = value
            else:
                notes.append(f"{name}/{key}={value} is ignored: static_map is false")
        elif key in _COSTMAP_NOT_USED:
            notes.append(f"{name}/{key}={value} is ignored: {_COSTMAP_NOT_USED[key]}")
        else:
            out[key] = value  # the node names a parameter it does not declare
    return out, notes, issues


_DWA_HOLONOMIC = ("max_vel_y", "min_vel_y", "acc_lim_y", "vy_samples")
_DWA_NOT_USED = {
    "publish_traj_pc": "visnav publishes the chosen trajectory on ~/DWAPlannerROS/local_plan only",
    "publish_cost_grid_pc": "visnav publishes no cost grid cloud",
    "stop_time_buffer": "visnav's DWA has no stop-time check (its obstacle critic rejects a "
    "trajectory that enters a lethal or inscribed cell)",
    "restore_defaults": "dynamic_reconfigure's flag",
}
_MOVE_BASE_NOT_USED = {
    "shutdown_costmaps": "visnav keeps the costmaps running between goals (ROS's default false)",
}
_LOCAL_PLANNERS = {
    "dwa_local_planner/DWAPlannerROS": "dwa_local_planner/DWAPlannerROS",
    "nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController": (
        "nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController"
    ),
}
_GLOBAL_PLANNERS = ("navfn/NavfnROS", "global_planner/GlobalPlanner")
_NAVFN_WEIGHTS = {
    "GlobalPlanner.neutral_cost": 50.0,
    "GlobalPlanner.cost_factor": 0.8,
    "GlobalPlanner.lethal_cost": 254,
}
"""navfn's ``setCostmap``: cost c < 253 -> 50 + 0.8 c, 253 / 254 blocked, unknown 253."""


def _dwa(
    node: RosNode, params: ParamServer, values: Mapping[str, Any], issues: list[str]
) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in values.items():
        if key in _DWA_HOLONOMIC:
            zero = False
            with contextlib.suppress(TypeError, ValueError):
                zero = float(value) == 0.0
            if zero or key == "acc_lim_y":
                _note(
                    params,
                    node,
                    f"DWAPlannerROS/{key}={value} is ignored: visnav's DWA samples no y "
                    "velocity (a differential-drive base)",
                )
            else:
                issues.append(
                    f"move_base {node.fqn}: DWAPlannerROS/{key}={value}: visnav's DWA drives a "
                    "differential-drive base and samples no y velocity; set it to 0"
                )
        elif key in _DWA_NOT_USED:
            _note(params, node, f"DWAPlannerROS/{key}={value} is ignored: {_DWA_NOT_USED[key]}")
        else:
            out[f"DWAPlannerROS.{key}"] = value
    return out


def _move_base(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    issues = _missing(node, "move_base") + _no_args(node, "move_base")
    private = params.private(node.fqn)
    out: dict[str, Any] = {}
    groups: dict[str, dict[str, Any]] = {"global_costmap": {}, "local_costmap": {}}
    dwa: dict[str, Any] = {}
    local = str(private.pop("base_local_planner", "base_local_planner/TrajectoryPlannerROS"))
    if local not in _LOCAL_PLANNERS:
        issues.append(
            f"move_base {node.fqn}: base_local_planner {local!r} is not available (visnav "
            f"has {', '.join(_LOCAL_PLANNERS)}; move_base's default is "
            "base_local_planner/TrajectoryPlannerROS, set dwa_local_planner/DWAPlannerROS)"
        )
    out["base_local_planner"] = _LOCAL_PLANNERS.get(local, local)
    # the ROS local planner as it is: no nav2 rotation shim in front of it
    out["use_rotation_shim"] = False
    # move_base's default global planner is navfn/NavfnROS (the TurtleBot3 files keep it)
    glob = str(private.pop("base_global_planner", "navfn/NavfnROS"))
    if glob == "navfn/NavfnROS":
        # navfn's own cell weights (COST_NEUTRAL 50 + COST_FACTOR 0.8 x cost, inscribed and
        # lethal cells blocked, unknown 253): the weight keeps growing up to the inscribed
        # band, so paths keep to the middle of a gap. global_planner's defaults (factor 3,
        # capped at 252) are flat for every cost above 67, i.e. within ~0.5 m of a wall
        # with the TurtleBot3's inflation, and their paths graze obstacles.
        out.update(_NAVFN_WEIGHTS)
        _note(
            params,
            node,
            "base_global_planner navfn/NavfnROS runs as visnav's GlobalPlanner with navfn's "
            "cell weights (neutral 50, factor 0.8, inscribed cells blocked; parameters "
            "NavfnROS/*)",
        )
    elif glob == "global_planner/GlobalPlanner":
        _note(
            params,
            node,
            f"base_global_planner {glob} runs as visnav's GlobalPlanner (global_planner's "
            "Dijkstra on the costmap; parameters GlobalPlanner/*)",
        )
    else:
        issues.append(
            f"move_base {node.fqn}: base_global_planner {glob!r} is not available (visnav "
            f"has {' and '.join(_GLOBAL_PLANNERS)})"
        )
    for key, value in private.items():
        head, _, tail = key.partition(".")
        if head in groups and tail:
            groups[head][tail] = value
        elif head == "DWAPlannerROS" and tail:
            dwa[tail] = value
        elif head in ("NavfnROS", "GlobalPlanner") and tail:
            out[f"GlobalPlanner.{tail}"] = value
        elif key in _MOVE_BASE_NOT_USED:
            _note(params, node, f"{key}={value} is ignored: {_MOVE_BASE_NOT_USED[key]}")
        elif head.endswith("PlannerROS") or head == "TrajectoryPlannerROS":
            _note(
                params,
                node,
                f"{key} belongs to the {head} local planner, which this move_base does not run",
            )
        else:
            out[key] = value
    for name, values in groups.items():
        mapped, notes, problems = costmap_params_from_ros1(name, values)
        out.update({f"{name}.{k}": v for k, v in mapped.items()})
        for text in notes:
            _note(params, node, text)
        issues.extend(f"move_base {node.fqn}: {text}" for text in problems)
    out.update(_dwa(node, params, dwa, issues))
    return node.spec("move_base", out), issues


# ---------------------------------------------------------------------- the new nodes
_GMAPPING_NOT_READ = {
    "inverted_laser": "slam_gmapping reads the laser's mounting from TF (the parameter is "
    "deprecated upstream)",
    "tf_delay": "visnav's slam_gmapping stamps map -> odom every transform_publish_period",
}


def _slam_gmapping(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    issues = _missing(node, "slam_gmapping") + _no_args(node, "slam_gmapping")
    private = params.private(node.fqn)
    for key, why in _GMAPPING_NOT_READ.items():
        if key in private:
            _note(params, node, f"{key}={private.pop(key)} is ignored: {why}")
    return node.spec("slam_gmapping", private), issues


def _passthrough(executable: str) -> Translator:
    def translate(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
        del packages
        issues = _missing(node, executable) + _no_args(node, executable)
        return node.spec(executable, params.private(node.fqn)), issues

    return translate


def _turtlebot3_teleop_key(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    issues = _missing(node, "turtlebot3_teleop_key") + _no_args(node, "turtlebot3_teleop_key")
    private = params.private(node.fqn)
    # turtlebot3_teleop_key reads rospy.get_param("model", "burger"): a global name
    found = params.search(node.namespace, "model")
    if "model" not in private and found is not None:
        private["model"] = params.get(found)
    return node.spec("turtlebot3_teleop_key", private), issues


NAV_TRANSLATORS: Mapping[tuple[str, str], Translator] = {
    ("map_server", "map_server"): _map_server,
    ("map_server", "map_saver"): _map_saver,
    ("amcl", "amcl"): _amcl,
    ("move_base", "move_base"): _move_base,
    ("gmapping", "slam_gmapping"): _slam_gmapping,
    ("explore_lite", "explore"): _passthrough("explore_lite"),
    ("turtlebot3_teleop", "turtlebot3_teleop_key"): _turtlebot3_teleop_key,
    ("teleop_twist_keyboard", "teleop_twist_keyboard.py"): _passthrough("teleop_twist_keyboard"),
    ("teleop_twist_keyboard", "teleop_twist_keyboard"): _passthrough("teleop_twist_keyboard"),
}
"""Translators of this module by ``(pkg, type)``."""
