"""DWA and regulated pure pursuit: sampling, critics, goal handling, curvature, collisions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from visnav.mapping import (
    Footprint,
    InflationLayer,
    LayeredCostmap,
    ObservationSource,
    ObstacleLayer,
)
from visnav.planning import (
    DWAParams,
    DWAPlanner,
    PlanningError,
    RegulatedPurePursuit,
    RotationShim,
    RPPParams,
    carrot_curvature,
    circle_segment_intersection,
    transform_global_plan,
    velocity_samples,
)

ID = (0.0, 0.0, 0.0)


def _costmap(points: list[tuple[float, float]] = (), radius: float = 0.2) -> LayeredCostmap:  # type: ignore[assignment]
    lc = LayeredCostmap(
        "odom",
        width=5.0,
        height=5.0,
        resolution=0.05,
        rolling_window=True,
        footprint=Footprint.from_params(robot_radius=radius),
    )
    layer = ObstacleLayer(sources=[ObservationSource("scan")], footprint_clearing_enabled=False)
    lc.add_layer(layer)
    lc.add_layer(InflationLayer())
    if points:
        pts = np.array([[x, y, 0.2] for x, y in points])
        layer.add_points("scan", pts, np.eye(4), stamp_ns=0, now_ns=0)
    lc.update_map(0.0, 0.0, 0.0)
    return lc


def _straight_plan(length: float = 4.0, y: float = 0.0) -> np.ndarray:
    xs = np.arange(0.0, length, 0.025)
    return np.stack([xs, np.full_like(xs, y), np.zeros_like(xs)], axis=1)


def test_velocity_iterator_semantics() -> None:
    np.testing.assert_allclose(velocity_samples(0.0, 0.5, 3), [0.0, 0.25, 0.5])
    np.testing.assert_allclose(velocity_samples(-0.3, 0.5, 3), [-0.3, 0.0, 0.1, 0.5])
    np.testing.assert_allclose(velocity_samples(0.2, 0.2, 5), [0.2])
    assert len(velocity_samples(-1.0, 1.0, 20)) == 21  # zero inserted


def test_dwa_samples_stay_in_the_dynamic_window() -> None:
    p = DWAParams()
    dwa = DWAPlanner(p)
    v, w = dwa._samples((0.3, 0.2))
    assert v.min() >= 0.3 - p.acc_lim_x * p.sim_period - 1e-9
    assert v.max() <= 0.3 + p.acc_lim_x * p.sim_period + 1e-9
    assert np.abs(w - 0.2).max() <= p.acc_lim_theta * p.sim_period + 1e-9
    # from rest: samples slower than both min_vel_trans and min_vel_theta are dropped
    v0, w0 = dwa._samples((0.0, 0.0))
    slow = (np.abs(v0) < p.min_vel_trans) & (np.abs(w0) < p.min_vel_theta)
    assert not slow.any()
    assert len(v0) > 0


def test_dwa_goes_straight_along_a_free_plan() -> None:
    lc = _costmap()
    dwa = DWAPlanner()
    dwa.set_plan(_straight_plan())
    r = dwa.compute_velocity(ID, (0.5, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    assert r.v == pytest.approx(0.55)
    assert abs(r.w) < 1e-9
    assert len(r.trajectory) > 10


def test_dwa_picks_the_collision_free_sample() -> None:
    # a wall crossing the straight line 0.6 m ahead; the plan bends left around it
    wall = [(0.6, y) for y in np.arange(-1.0, 0.25, 0.05)]
    lc = _costmap(wall)
    dwa = DWAPlanner()
    bend = np.array(
        [[x, 0.0 if x < 0.2 else min(0.8, (x - 0.2) * 2), 0.0] for x in np.arange(0.0, 2.0, 0.025)]
    )
    dwa.set_plan(bend)
    r = dwa.compute_velocity(ID, (0.3, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    assert r.v < 0.3 + 2.5 * 0.05 - 1e-6  # the fastest sample (0.425 m/s) would reach the wall
    costs = lc.costmap.costs_at(r.trajectory[:, :2])
    assert (costs < 253).all()
    # the straight sample would have hit the wall
    xs, ys, ths, mask, _ = dwa._rollout(ID, np.array([0.4]), np.array([0.0]))
    ok, _ = dwa._obstacle_costs(
        xs, ys, ths, mask, np.array([0.4]), lc.costmap, lc.footprint, robot=ID[:2]
    )
    assert not ok[0]


def test_dwa_fails_when_boxed_in() -> None:
    ring = [(0.45 * math.cos(a), 0.45 * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 90)]
    lc = _costmap(ring, radius=0.1)
    dwa = DWAPlanner(DWAParams(min_vel_theta=10.0))  # no rotation in place
    dwa.set_plan(_straight_plan())
    r = dwa.compute_velocity(ID, (0.0, 0.0), lc.costmap, lc.footprint, ID)
    assert not r.ok
    assert "trajectories collide" in r.reason


def test_dwa_stops_and_rotates_at_the_goal() -> None:
    lc = _costmap()
    dwa = DWAPlanner()
    plan = _straight_plan(1.0)
    plan[-1, 2] = math.pi / 2
    dwa.set_plan(plan)
    pose = (float(plan[-1, 0]) - 0.05, 0.0, 0.0)
    r = dwa.compute_velocity(pose, (0.4, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    assert 0 < r.v < 0.4  # braking within acc_lim_x
    assert r.v == pytest.approx(0.4 - 2.5 * 0.05)
    r = dwa.compute_velocity(pose, (0.0, 0.0), lc.costmap, lc.footprint, ID)
    assert r.v == 0.0
    assert r.w > 0  # turns toward +pi/2
    assert not dwa.is_goal_reached(pose, (0.0, 0.0))
    done = (pose[0], 0.0, math.pi / 2 - 0.05)
    assert dwa.is_goal_reached(done, (0.0, 0.0))
    assert not dwa.is_goal_reached(done, (0.3, 0.0))  # not stopped


def test_dwa_keeps_the_xy_latch_across_replans_to_the_same_goal() -> None:
    lc = _costmap()
    dwa = DWAPlanner(DWAParams(latch_xy_goal_tolerance=True, xy_goal_tolerance=0.15))
    plan = _straight_plan(1.0)
    plan[-1, 2] = math.pi
    dwa.set_plan(plan)
    inside = (float(plan[-1, 0]) - 0.14, 0.0, 0.0)
    r = dwa.compute_velocity(inside, (0.0, 0.0), lc.costmap, lc.footprint, ID)
    assert r.v == 0.0
    assert r.w != 0.0  # latched: turning in place to the goal's yaw
    drifted = (float(plan[-1, 0]) - 0.16, 0.0, 1.0)  # turning moved the base 2 cm
    replan = _straight_plan(1.0)
    replan[-1, 2] = math.pi
    dwa.set_plan(replan[3:])  # move_base replans from the robot: same goal
    r = dwa.compute_velocity(drifted, (0.0, 0.5), lc.costmap, lc.footprint, ID)
    assert r.v == 0.0  # still turning in place, not driving back
    assert r.w > 0.0
    assert dwa.is_goal_reached((drifted[0], 0.0, math.pi - 0.05), (0.0, 0.0))
    other = _straight_plan(2.0)
    dwa.set_plan(other)  # a new goal clears the latch
    assert not dwa.is_goal_reached((drifted[0], 0.0, 0.0), (0.0, 0.0))


def test_dwa_oscillation_flags_forbid_flipping_rotation() -> None:
    dwa = DWAPlanner()
    p = dwa.params
    osc = dwa._osc
    osc.update((0.0, 0.0, 0.0), 0.0, 0.5, p.min_vel_trans, p)
    osc.update((0.0, 0.0, 0.01), 0.0, -0.5, p.min_vel_trans, p)  # flip: only negative allowed now
    allowed = osc.allowed(np.array([0.0, 0.0]), np.array([0.5, -0.5]))
    assert allowed.tolist() == [False, True]
    osc.update((0.0, 0.0, 0.5), 0.0, -0.5, p.min_vel_trans, p)  # turned 0.49 rad > 0.2: reset
    assert osc.allowed(np.array([0.0]), np.array([0.5])).tolist() == [True]


def test_transform_global_plan_keeps_the_part_near_the_robot() -> None:
    lc = _costmap()
    plan = _straight_plan(10.0)
    local = transform_global_plan(plan, (1.0, 0.0, 0.0), (2.0, 0.0, 0.0), lc.costmap)
    assert local[0, 0] == pytest.approx(1.0)  # the plan starts inside the window
    assert local[-1, 0] == pytest.approx(2.0 + 2.5, abs=0.03)
    pruned = transform_global_plan(plan, (1.0, 0.0, 0.0), (2.0, 0.0, 0.0), lc.costmap, prune=True)
    assert pruned[0, 0] == pytest.approx(2.0, abs=0.03)


def test_dwa_param_checks() -> None:
    with pytest.raises(PlanningError, match="sim_time is 0"):
        DWAParams(sim_time=0.0)


# ---------------------------------------------------------------------- pure pursuit
def test_curvature_and_carrot_geometry() -> None:
    assert carrot_curvature(1.0, 0.0) == 0.0
    assert carrot_curvature(1.0, 1.0) == pytest.approx(1.0)  # 2y / L^2
    assert carrot_curvature(0.6, -0.3) == pytest.approx(-0.6 / 0.45)
    p = circle_segment_intersection(np.array([0.1, 0.0]), np.array([2.0, 0.0]), 0.6)
    np.testing.assert_allclose(p, [0.6, 0.0])
    p = circle_segment_intersection(np.array([0.0, 0.5]), np.array([1.0, 0.5]), 1.0)
    assert np.hypot(*p) == pytest.approx(1.0)


def test_pure_pursuit_follows_the_arc_through_the_carrot() -> None:
    lc = _costmap()
    rpp = RegulatedPurePursuit(RPPParams(use_cost_regulated_linear_velocity_scaling=False))
    plan = _straight_plan(4.0, y=0.2)
    rpp.set_plan(plan)
    r = rpp.compute_velocity(ID, (0.5, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    carrot = rpp.carrot
    assert np.hypot(*carrot) == pytest.approx(0.6, abs=1e-6)
    assert carrot[1] == pytest.approx(0.2)
    k = 2 * carrot[1] / 0.36
    assert rpp.curvature == pytest.approx(k)
    assert r.v == pytest.approx(0.5)  # radius 1/k = 0.9 is not below min_radius 0.9
    assert r.w == pytest.approx(0.5 * k)


def test_pure_pursuit_regulates_speed_on_tight_curves_and_near_the_goal() -> None:
    lc = _costmap()
    rpp = RegulatedPurePursuit(RPPParams(use_cost_regulated_linear_velocity_scaling=False))
    rpp.set_plan(_straight_plan(4.0, y=0.4))
    r = rpp.compute_velocity(ID, (0.5, 0.0), lc.costmap, lc.footprint, ID)
    radius = 1.0 / abs(rpp.curvature)
    assert radius < 0.9
    expected = max(0.5 * (1 - abs(radius - 0.9) / 0.9), 0.25)
    assert r.v == pytest.approx(expected)
    rpp.set_plan(_straight_plan(0.3))
    r = rpp.compute_velocity(ID, (0.5, 0.0), lc.costmap, lc.footprint, ID)
    assert r.v == pytest.approx(0.5 * 0.275 / 0.6)  # approach scaling by the remaining 0.275 m


def test_pure_pursuit_rotates_to_a_path_behind() -> None:
    lc = _costmap()
    rpp = RegulatedPurePursuit()
    plan = _straight_plan(3.0)
    plan[:, 0] *= -1
    rpp.set_plan(plan)
    r = rpp.compute_velocity(ID, (0.0, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    assert r.v == 0.0
    assert abs(r.w) == pytest.approx(3.2 * 0.05)  # limited by max_angular_accel per cycle


def test_pure_pursuit_refuses_a_collision() -> None:
    lc = _costmap([(0.45, y) for y in np.arange(-0.5, 0.55, 0.05)])
    rpp = RegulatedPurePursuit()
    rpp.set_plan(_straight_plan(3.0))
    r = rpp.compute_velocity(ID, (0.5, 0.0), lc.costmap, lc.footprint, ID)
    assert not r.ok
    assert "collision ahead" in r.reason


def test_pure_pursuit_goal_checker_is_stateful() -> None:
    rpp = RegulatedPurePursuit()
    plan = _straight_plan(1.0)
    rpp.set_plan(plan)
    gx = float(plan[-1, 0])
    assert not rpp.is_goal_reached((gx - 0.2, 0.0, 1.0), (0.0, 0.0))  # yaw off
    assert rpp.is_goal_reached((gx + 0.5, 0.0, 0.1), (0.0, 0.0))  # xy latched, yaw ok


# ---------------------------------------------------------------------- rotation shim
def test_rotation_shim_turns_toward_a_plan_behind_then_hands_over() -> None:
    lc = _costmap()
    shim = RotationShim(DWAPlanner())
    plan = _straight_plan(3.0)
    plan[:, 0] *= -1  # the plan leaves backwards
    shim.set_plan(plan)
    r = shim.compute_velocity(ID, (0.0, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    assert r.v == 0.0
    assert abs(r.w) == pytest.approx(3.2 * 0.05)  # accelerating toward 1.8 rad/s
    facing = (0.0, 0.0, math.pi - 0.3)  # within 0.785 rad of the plan: DWA drives
    r = shim.compute_velocity(facing, (0.0, 0.0), lc.costmap, lc.footprint, ID)
    assert r.ok
    assert r.v > 0.0
    # near the goal (no plan pose 0.5 m away) the shim hands over at once
    shim.set_plan(plan[:10])
    assert shim.heading_error(ID, ID) is None
