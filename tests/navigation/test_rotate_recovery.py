"""rotate_recovery with a circular footprint: no full turn with an obstacle inside the circle."""

from __future__ import annotations

import math

import pytest

from visnav.mapping.costmap_2d import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE
from visnav.mapping.footprint import Footprint
from visnav.mapping.inflation_layer import InflationLayer
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.planning.recovery import RecoveryContext, RotateRecovery, nearest_lethal


def _context(cells_behind: int) -> RecoveryContext:
    """The car (radius 0.33 m) at a cell centre, one lethal cell ``cells_behind`` x 5 cm behind."""
    obstacles = ObstacleLayer(footprint_clearing_enabled=False)
    lc = LayeredCostmap(
        "odom",
        width=3.0,
        height=3.0,
        origin_x=-1.5,
        origin_y=-1.5,
        footprint=Footprint.from_params(robot_radius=0.33),
        layers=[obstacles, InflationLayer()],
    )
    x = y = 0.025
    cell = lc.costmap.world_to_map(x, y)
    assert cell is not None
    obstacles.grid.set_cost(cell[0] - cells_behind, cell[1], LETHAL_OBSTACLE)
    lc.request_full_update()
    lc.update_map(x, y, 0.0)
    pose = (x, y, 0.0)
    return RecoveryContext(0, pose, pose, (0.0, 0.0), lc, lc)


@pytest.mark.parametrize("cells", [2, 4, 5])
def test_no_turn_with_an_obstacle_inside_the_circle(cells: int) -> None:
    # seed 5: the wall corner 0.25 m from the car's centre, the chassis' rear corner 0.30 m
    ctx = _context(cells)
    rec = RotateRecovery()
    rec.start(ctx)
    step = rec.step(ctx)
    assert step.done
    assert step.w == 0.0
    assert "inside its 0.34 m radius" in step.failed


@pytest.mark.parametrize(
    ("cells", "inscribed"),
    [
        (9, False),  # 0.45 m: inflated (cost > 0) but outside the 0.34 m circle
        # 0.30 m, the centre cell inscribed: the edge of the inscribed band where DWA
        # leaves a robot (seed 5's second visit of the corner with the map in the local
        # costmap: 0.37 m by ground truth); one cell of quantisation is given, so the
        # turn may free the robot
        (6, True),
    ],
)
def test_turns_when_no_obstacle_is_well_inside_the_circle(cells: int, inscribed: bool) -> None:
    ctx = _context(cells)
    cm = ctx.local_costmap.costmap
    centre = cm.world_to_map(*ctx.pose_local[:2])
    assert centre is not None
    cost = cm.get_cost(*centre)
    assert 0 < cost < LETHAL_OBSTACLE
    assert (cost == INSCRIBED_INFLATED_OBSTACLE) is inscribed
    rec = RotateRecovery()
    rec.start(ctx)
    step = rec.step(ctx)
    assert not step.done
    assert step.w == pytest.approx(1.0)


def test_nearest_lethal() -> None:
    ctx = _context(5)
    cm = ctx.local_costmap.costmap
    assert nearest_lethal(cm, 0.025, 0.025, 0.5) == pytest.approx(0.25)
    assert nearest_lethal(cm, 0.025, 0.025, 0.2) == math.inf
