"""Closed loop in the simulator: the quadrotor flies through a seeded forest (slow)."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import Header, Odometry, PoseStamped, make, ns_to_time
from visnav.planning.ego_planner.nodes import EgoPlannerNode, TrajServerNode


@pytest.fixture
def mujoco_gl(monkeypatch: pytest.MonkeyPatch) -> str:
    """Select EGL for MuJoCo rendering (unless the environment already chose a backend)."""
    if os.environ.get("MUJOCO_GL", "").strip().lower() not in ("egl", "osmesa"):
        monkeypatch.setenv("MUJOCO_GL", "egl")
    return os.environ["MUJOCO_GL"]


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.usefixtures("mujoco_gl")
def test_quadrotor_flies_through_a_forest_without_touching_it() -> None:
    import mujoco

    from visnav.description.world import load_world
    from visnav.sim.simulator import RobotSpawn, Simulator
    from visnav.sim.world_geometry import obstacle_distance

    world = load_world("forest", seed=0)
    with Context(transport="local") as ctx:
        sim = Simulator(
            world, [RobotSpawn(source="quadrotor", namespace="/drone")], context=ctx, seed=0
        )
        robot = sim.robot()
        root = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, robot.handles.root_body)
        drone = {b for b in range(sim.model.nbody) if b == root or sim.model.body_rootid[b] == root}
        probe = Node("scenario", context=ctx, use_sim_time=True)
        odoms: list[Odometry] = []
        probe.create_subscription(Odometry, "/drone/odom", odoms.append, 100)
        hold = probe.create_publisher(PoseStamped, "/drone/command/pose", 1)
        goal_pub = probe.create_publisher(PoseStamped, "/move_base_simple/goal", 1)
        start, goal = world.metadata["start"], world.metadata["goal"]
        takeoff = make(PoseStamped)
        takeoff.header = Header(stamp=ns_to_time(0), frame_id="world")
        takeoff.pose.position.x, takeoff.pose.position.y = start[0], start[1]
        takeoff.pose.position.z = 1.0
        takeoff.pose.orientation.w = 1.0
        hold.publish(takeoff)
        sim.run(3.0)
        # the quadrotor's collision box is 0.36 m square: inflate by its radius (upstream: 0.099)
        planner = EgoPlannerNode(
            context=ctx,
            namespace="/drone",
            parameter_overrides={"use_sim_time": True, "grid_map.obstacles_inflation": 0.3},
        )
        TrajServerNode(context=ctx, namespace="/drone", parameter_overrides={"use_sim_time": True})
        sim.run(0.5)
        target = make(PoseStamped)
        target.header = Header(stamp=ns_to_time(sim.now_ns), frame_id="world")
        target.pose.position.x, target.pose.position.y = goal[0], goal[1]
        target.pose.orientation.w = 1.0
        goal_pub.publish(target)
        first = len(odoms)
        t0 = sim.now_ns
        contacts = 0

        def done() -> bool:
            nonlocal contacts
            data = sim.data
            for c in data.contact[: data.ncon]:
                b1 = int(sim.model.geom_bodyid[c.geom1])
                b2 = int(sim.model.geom_bodyid[c.geom2])
                if (b1 in drone) != (b2 in drone):
                    contacts += 1
            return planner.fsm.goals_reached > 0

        sim.run(45.0, until=done)
        flight_s = (sim.now_ns - t0) / 1e9
        pos = np.array(
            [
                [o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z]
                for o in odoms[first:]
            ]
        )
    assert planner.fsm.goals_reached == 1
    assert math.dist(pos[-1, :2], goal) < 0.3
    assert contacts == 0
    clearance = float(obstacle_distance(world, pos).min())
    assert clearance > 0.26  # the body's circumscribed radius in the plane
    mean_speed = float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()) / flight_s
    assert mean_speed >= 1.5
    times = np.array([r.total_s for r in planner.manager.records[1:]])
    assert np.median(times) < 0.005
