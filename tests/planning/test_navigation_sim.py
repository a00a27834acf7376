"""The whole chain in MuJoCo: depth camera -> scan -> map + costmaps -> plans -> cmd_vel -> car."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import (
    Header,
    Odometry,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    ns_to_time,
)
from visnav.tf.ros import StaticTransformBroadcaster

pytestmark = pytest.mark.slow

RADIUS = 0.3


@pytest.fixture
def mujoco_gl(monkeypatch: pytest.MonkeyPatch) -> str:
    if os.environ.get("MUJOCO_GL", "").strip().lower() not in ("egl", "osmesa"):
        monkeypatch.setenv("MUJOCO_GL", "egl")
    return os.environ["MUJOCO_GL"]


def test_car_maps_and_reaches_goals_in_the_office(mujoco_gl: str) -> None:
    del mujoco_gl
    import mujoco

    from visnav.description.world import load_world
    from visnav.mapping import LETHAL_OBSTACLE, Costmap2D
    from visnav.mapping.nodes import MapperNode
    from visnav.perception.nodes import DepthImageToLaserScanNode
    from visnav.planning import GlobalPlanner, GlobalPlannerParams, GoalStatus
    from visnav.planning.nodes import NavigatorNode
    from visnav.sim.simulator import RobotSpawn, Simulator
    from visnav.sim.world_geometry import true_occupancy_grid

    world = load_world("office")
    grid, origin = true_occupancy_grid(world, 0.05)
    from scipy import ndimage

    truth_cm = Costmap2D(grid.shape[1], grid.shape[0], 0.05, origin[0], origin[1])
    clearance = ndimage.distance_transform_edt(~grid) * 0.05
    truth_cm.data[:] = np.where(clearance <= RADIUS, LETHAL_OBSTACLE, 0)
    shortest = GlobalPlanner(GlobalPlannerParams(cost_factor=0.0))
    with Context(transport="local") as ctx:
        sim = Simulator(
            world,
            [RobotSpawn(source="car", args={"camera_rate": "1", "ideal_sensors": "true"})],
            context=ctx,
        )
        robot_bodies = {
            mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, b)
            for b in sim.robot().handles.bodies.values()
        }
        DepthImageToLaserScanNode(
            context=ctx,
            use_sim_time=True,
            remappings={
                "depth": "/depth_camera/depth/image_raw",
                "depth_camera_info": "/depth_camera/depth/camera_info",
            },
            parameter_overrides={"output_frame": "depth_camera_link", "scan_height": 10},
        )
        MapperNode(
            context=ctx,
            use_sim_time=True,
            parameter_overrides={
                "width": 24.0,
                "height": 19.0,
                "origin_x": -12.0,
                "origin_y": -9.5,
            },
        )
        nav = NavigatorNode(
            context=ctx,
            use_sim_time=True,
            parameter_overrides={
                "global_costmap.robot_radius": RADIUS,
                "local_costmap.robot_radius": RADIUS,
            },
        )
        ctx.spin_some()  # take the simulator's latched /tf_static before adding map -> odom
        helper = Node("scenario", context=ctx)
        StaticTransformBroadcaster(helper).send_transform(
            TransformStamped(
                header=Header(stamp=ns_to_time(0), frame_id="map"),
                child_frame_id="odom",
                transform=Transform(
                    translation=Vector3(x=0.0, y=0.0, z=0.0),
                    rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                ),
            )
        )
        truth: list[tuple[float, float]] = []
        helper.create_subscription(
            Odometry,
            "/ground_truth/odom",
            lambda m: truth.append((m.pose.pose.position.x, m.pose.pose.position.y)),
            10,
        )

        def contacts() -> int:
            n = 0
            for c in sim.data.contact[: sim.data.ncon]:
                b1, b2 = sim.model.geom_bodyid[c.geom1], sim.model.geom_bodyid[c.geom2]
                if (b1 in robot_bodies) == (b2 in robot_bodies):
                    continue
                other = c.geom2 if b1 in robot_bodies else c.geom1
                if sim.model.geom_type[other] != mujoco.mjtGeom.mjGEOM_PLANE:  # not the floor
                    n += 1
            return n

        sim.run(0.5)
        ratios = []
        for gx, gy in ((-6.0, 3.0), (0.0, 5.75)):  # corridor corner, then room N2 via its door
            start = truth[-1]
            k0 = len(truth)
            h = nav.go_to((gx, gy, 0.0))
            hits = 0
            while not h.done and sim.sim_time_s < 200.0:
                sim.run(0.5, until=lambda h=h: h.done)
                hits += contacts()
            assert h.status is GoalStatus.SUCCEEDED, h.text
            assert hits == 0
            path = np.array(truth[k0:])
            travelled = float(np.hypot(*np.diff(path, axis=0).T).sum())
            best = shortest.make_plan(truth_cm, start, (gx, gy, 0.0))
            assert best.ok
            ratios.append(travelled / best.length)
            assert ratios[-1] <= 2.0, (travelled, best.length)  # exploring can cost a detour
            assert math.hypot(path[-1, 0] - gx, path[-1, 1] - gy) < 0.3
        assert float(np.mean(ratios)) <= 1.3, ratios  # the acceptance bound
        sim.close()
