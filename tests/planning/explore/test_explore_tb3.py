"""explore_lite with the real simulator: ROBOTIS' TurtleBot3 burger explores turtlebot3_world.

The chain is the tutorial's with known poses: the simulated burger's ``/scan`` -> visnav's
``mapper`` (``map``; ``map -> odom`` is the identity, the diff drive plugin's odometry is
the world pose) -> ``explore_lite`` -> ``move_base`` (DWA with the burger's speed limits)
-> ``/cmd_vel``; explore_lite reads the mapper's ``map`` or move_base's global costmap, as
its documentation offers. Exploring must end by itself with the arena mapped from wall to
wall, without touching a wall or a pillar (the simulator's contact sensor).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import ndimage

from visnav.graph import Context, Node
from visnav.mapping.nodes import MapperNode
from visnav.msgs import (
    Header,
    OccupancyGrid,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    get_message_class,
    ns_to_time,
)
from visnav.planning.explore import ExploreCostmap
from visnav.planning.explore.frontier_search import FREE_SPACE
from visnav.planning.explore.node import ExploreNode
from visnav.planning.nodes import NavigatorNode
from visnav.sim.simulator import RobotSpawn, Simulator
from visnav.tf.ros import StaticTransformBroadcaster

DATA = Path(__file__).resolve().parents[2] / "data" / "turtlebot3"
DESCRIPTION = DATA / "turtlebot3_description"
WORLD = DATA / "turtlebot3_gazebo" / "worlds" / "turtlebot3_world.world"
# turtlebot3_navigation's costmap_common_params_burger.yaml footprint
FOOTPRINT = "[[-0.105, -0.105], [-0.105, 0.105], [0.041, 0.105], [0.041, -0.105]]"
# dwa_local_planner_params_burger.yaml's limits
BURGER_DWA = {
    "DWAPlannerROS.max_vel_x": 0.22,
    "DWAPlannerROS.max_vel_trans": 0.22,
    "DWAPlannerROS.min_vel_trans": 0.11,
    "DWAPlannerROS.max_vel_theta": 2.75,
    "DWAPlannerROS.min_vel_theta": 1.37,
    "DWAPlannerROS.vx_samples": 20,
    "DWAPlannerROS.vth_samples": 40,
    "DWAPlannerROS.sim_time": 1.5,
    "DWAPlannerROS.controller_frequency": 10.0,
    "controller_frequency": 10.0,
}


def _identity_map_to_odom(ctx: Context) -> Node:
    node = Node("map_to_odom", context=ctx)
    StaticTransformBroadcaster(node).send_transform(
        TransformStamped(
            header=Header(stamp=ns_to_time(0), frame_id="map"),
            child_frame_id="odom",
            transform=Transform(
                translation=Vector3(x=0.0, y=0.0, z=0.0),
                rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
    )
    return node


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("costmap_topic", ["map", "move_base/global_costmap/costmap"])
def test_burger_explores_turtlebot3_world(
    caplog: pytest.LogCaptureFixture, costmap_topic: str
) -> None:
    with Context(transport="local") as ctx:
        _identity_map_to_odom(ctx)
        maps: list[OccupancyGrid] = []
        probe = Node("probe", context=ctx)
        probe.create_subscription(OccupancyGrid, "/map", maps.append, 1)
        touches: list[str] = []
        samples: list[int] = []

        def on_contacts(msg: Any) -> None:
            samples.append(len(msg.status))
            touches.extend(
                f"{c.name} - {c.hardware_id}" for c in msg.status if c.message != "plane"
            )

        probe.create_subscription(
            get_message_class("diagnostic_msgs/msg/DiagnosticArray"),
            "/bumper_states",
            on_contacts,
            100,
        )
        MapperNode(
            context=ctx,
            use_sim_time=True,
            parameter_overrides={"width": 8.0, "height": 8.0, "origin_x": -4.0, "origin_y": -4.0},
        )
        NavigatorNode(
            context=ctx,
            use_sim_time=True,
            parameter_overrides={
                "global_costmap.footprint": FOOTPRINT,
                "local_costmap.footprint": FOOTPRINT,
                "global_costmap.track_unknown_space": True,
                "global_costmap.inflation_layer.inflation_radius": 0.3,
                "local_costmap.inflation_layer.inflation_radius": 0.3,
                "global_costmap.inflation_layer.cost_scaling_factor": 5.0,
                "local_costmap.inflation_layer.cost_scaling_factor": 5.0,
                "local_costmap.width": 3.0,
                "local_costmap.height": 3.0,
                **BURGER_DWA,
            },
        )
        # explore_lite's own explore.launch values
        explore = ExploreNode(
            context=ctx,
            use_sim_time=True,
            parameter_overrides={
                "costmap_topic": costmap_topic,
                "robot_base_frame": "base_footprint",
                "potential_scale": 3.0,
                "min_frontier_size": 0.75,
                "planner_frequency": 0.33,
            },
        )
        spawn = RobotSpawn(
            source=DESCRIPTION / "urdf" / "turtlebot3_burger.urdf.xacro",
            packages={"turtlebot3_description": DESCRIPTION},
            spawn=(-2.0, -0.5, 0.0, 0.0),
        )
        with (
            caplog.at_level(logging.INFO),
            Simulator(WORLD, [spawn], context=ctx, contact_rate=20.0) as sim,
        ):
            stats = sim.run(150.0, until=lambda: explore.stopped)
        assert explore.stopped, f"still exploring after {stats.sim_time_s:.0f} s of sim time"
        assert "[/explore] Exploration stopped." in [r.getMessage() for r in caplog.records]
        assert explore.costmap is not None
        assert maps
        grid = ExploreCostmap.from_msg(maps[-1])
        free = grid.costs == FREE_SPACE
        labels, _ = ndimage.label(free)
        here = labels == 1 + int(np.argmax(np.bincount(labels.reshape(-1))[1:]))
        # the arena (a hexagon of about 20 m^2 less nine pillars) is mapped wall to wall
        area = here.sum() * grid.resolution**2
        assert area > 18.0, f"{area:.1f} m^2 free"
        rows, cols = np.nonzero(here)
        xs = grid.origin[0] + (cols + 0.5) * grid.resolution
        ys = grid.origin[1] + (rows + 0.5) * grid.resolution
        # its walls: x -2.9 .. 2.6, y -2.5 .. 2.5
        assert xs.min() < -2.7
        assert xs.max() > 2.4
        assert ys.min() < -2.3
        assert ys.max() > 2.3
        assert 2 <= explore.goals_sent < 60
        assert len(samples) > 20 * 20  # 20 Hz for more than 20 s
        assert max(samples) > 0  # the wheels on the floor: the sensor sees contacts
        assert not touches, f"the burger touched the world: {sorted(set(touches))}"
