"""The TurtleBot3 burger beside a pillar: move_base's default global planner is navfn.

ROBOTIS' move_base.launch sets no ``base_global_planner``, so ROS runs navfn/NavfnROS,
whose cell weight ``50 + 0.8 cost`` keeps rising all the way to the inscribed band. With
global_planner's defaults (``50 + 3 cost`` capped at 252) every cell with a cost above 67,
i.e. within ~0.5 m of an obstacle with the burger's inflation (radius 1.0, scaling 3.0),
weighs the same, and the plan from (0.425, 1.575) to seed 1's first goal grazed the
pillar at (-1.1, 1.1) by 0.1 m: the burger, reversing along it, parked its padded rear
corners in the pillar's lethal cells and every DWA trajectory and recovery collided.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from visnav.graph import Context, Node
from visnav.launch import Launcher, load_launch
from visnav.launch.description import NodeSpec
from visnav.launch.ros_nodes import ParamServer, RosNode, translate_node
from visnav.mapping.costmap_2d import NO_INFORMATION, Costmap2D
from visnav.mapping.inflation_layer import compute_cost
from visnav.mapping.map_io import load_map
from visnav.msgs.types import Odometry
from visnav.planning.global_planner import GlobalPlanner, GlobalPlannerParams

TB3 = Path(__file__).resolve().parents[1] / "data" / "turtlebot3"
NAV = TB3 / "turtlebot3_navigation"
MAP = NAV / "maps" / "map.yaml"
ENV = {"ROS_PACKAGE_PATH": str(TB3), "TURTLEBOT3_MODEL": "burger"}
PILLARS = np.array([(a, b) for a in (-1.1, 0.0, 1.1) for b in (-1.1, 0.0, 1.1)])
START, GOAL = (0.425, 1.575), (-2.075, -0.725, 2.83)  # seed 1's first goal from there


def _move_base_params() -> dict[str, object]:
    desc = load_launch(
        NAV / "launch" / "turtlebot3_navigation.launch", {"open_rviz": "false"}, env=ENV
    )
    return dict({n.fqn: n for n in desc.nodes}["/move_base"].params)


def _global_costmap() -> Costmap2D:
    """ROBOTIS' map inflated as the burger's global costmap (padded footprint 0.051 inscribed)."""
    occupancy = load_map(MAP)
    md, data = occupancy.metadata, np.asarray(occupancy.data)
    costmap = Costmap2D(data.shape[1], data.shape[0], md.resolution, md.origin[0], md.origin[1])
    lethal = data >= 65
    cells = ndimage.distance_transform_edt(~lethal)
    cost = compute_cost(
        cells, resolution=md.resolution, inscribed_radius=0.051, cost_scaling_factor=3.0
    )
    cost = np.where(cells * md.resolution > 1.0, 0, cost)
    costmap.data[:] = np.where((data < 0) & (cost == 0), NO_INFORMATION, cost)
    return costmap


def _pillar_clearance(xy: np.ndarray) -> float:
    d = np.hypot(xy[:, None, 0] - PILLARS[None, :, 0], xy[:, None, 1] - PILLARS[None, :, 1])
    return float(d.min() - 0.15)


def test_robotis_move_base_plans_with_navfn_weights() -> None:
    mb = _move_base_params()
    gp = {k.split(".", 1)[1]: v for k, v in mb.items() if k.startswith("GlobalPlanner.")}
    assert gp == {"neutral_cost": 50.0, "cost_factor": 0.8, "lethal_cost": 254}
    costmap = _global_costmap()
    navfn = GlobalPlanner(GlobalPlannerParams(**gp)).make_plan(costmap, START, GOAL)
    assert navfn.ok
    # navfn keeps to the middle of the 0.8 m gaps between the pillars
    assert _pillar_clearance(navfn.poses[:, :2]) > 0.3
    # global_planner's defaults saturate and graze a pillar (the stuck burger)
    flat = GlobalPlanner(GlobalPlannerParams()).make_plan(costmap, START, GOAL)
    assert _pillar_clearance(flat.poses[:, :2]) < 0.15


def _translate_move_base(planner: str | None) -> tuple[dict[str, object], list[str]]:
    params = ParamServer()
    params.set("/move_base/base_local_planner", "dwa_local_planner/DWAPlannerROS", "t")
    if planner is not None:
        params.set("/move_base/base_global_planner", planner, "t")
    node = RosNode(
        pkg="move_base",
        type="move_base",
        name="move_base",
        namespace="/",
        args=(),
        remaps=(),
        respawn=False,
        respawn_delay=0.0,
        required=False,
        source="t.launch:1",
    )
    spec, issues = translate_node(node, params, {})
    return (dict(spec.params) if spec is not None else {}), issues


def test_global_planner_choice_sets_the_cell_weights() -> None:
    for planner in (None, "navfn/NavfnROS"):  # move_base's default is navfn
        mb, issues = _translate_move_base(planner)
        assert (mb["GlobalPlanner.cost_factor"], mb["GlobalPlanner.lethal_cost"]) == (0.8, 254)
        assert not issues
    mb, issues = _translate_move_base("global_planner/GlobalPlanner")
    assert not any(k.startswith("GlobalPlanner.") for k in mb)  # global_planner's defaults
    assert not issues
    _, issues = _translate_move_base("carrot_planner/CarrotPlanner")
    assert any("carrot_planner/CarrotPlanner" in i for i in issues)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_burger_passes_the_pillar_it_got_stuck_beside(domain: int) -> None:
    """20 simulated seconds of turtlebot3_world + turtlebot3_navigation.launch (~1 min)."""
    world = load_launch(TB3 / "turtlebot3_gazebo" / "launch" / "turtlebot3_world.launch", env=ENV)
    nav = load_launch(
        NAV / "launch" / "turtlebot3_navigation.launch", {"open_rviz": "false"}, env=ENV
    )
    x0, y0, yaw0 = 0.425, 1.575, 0.31
    sim = {"lockstep": True, "realtime": False, "duration": 20.0, "spawn": [x0, y0, 0.0, yaw0]}
    nodes = [
        replace(n, params={**n.params, **sim}) if n.executable == "sim" else n for n in world.nodes
    ]
    sim_time = [replace(n, use_sim_time=True) for n in nav.nodes]
    goals = NodeSpec(
        executable="tb3_goals",
        name="tb3_goals",
        namespace="/",
        use_sim_time=True,
        params={
            "map": str(MAP),
            "seed": 1,
            "goals": 1,
            "initial_x": x0,
            "initial_y": y0,
            "initial_yaw": yaw0,
            "min_step": 2.0,
        },
    )
    desc = replace(world, nodes=[*nodes, *sim_time, goals])
    ctx = Context(transport="local", domain=domain)
    probe = Node("probe", context=ctx)
    poses: list[tuple[float, float]] = []
    probe.create_subscription(
        Odometry,
        "/odom",
        lambda m: poses.append((m.pose.pose.position.x, m.pose.pose.position.y)),
        50,
    )
    launcher = Launcher(desc, domain=ctx.domain, context=ctx)
    launcher.run(threading.Event())
    goal_node = next(n for n in launcher.shared_nodes if n.get_name() == "tb3_goals")
    assert np.allclose(goal_node.goals[0][:2], GOAL[:2])
    xy = np.array(poses)
    # the burger got past the pillar at (-1.1, 1.1), never closer than its footprint allows
    assert _pillar_clearance(xy) > 0.2
    assert ((xy[:, 0] < -1.0) & (xy[:, 1] < 0.8)).any()
