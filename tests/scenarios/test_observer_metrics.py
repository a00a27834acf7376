"""The observer's bookkeeping without a graph: contact events, errors, id parsing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.scenarios.observer import _goal_index, parse_planner_status
from visnav.scenarios.observer_metrics import (
    ContactEvents,
    PoseErrors,
    interpolate_poses,
    path_length,
    pose_error,
    slam_metrics,
)
from visnav.slam import Trajectory


def _pose(x: float, y: float, yaw: float) -> np.ndarray:
    m = np.eye(4)
    m[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    m[:2, 3] = x, y
    return m


def test_a_run_of_touching_samples_is_one_event() -> None:
    events = ContactEvents(gap_s=0.0)
    for k, touching in enumerate([False, True, True, False, True, False]):
        events.sample(k * 0.005, touching=touching)
    assert events.events == 2


def test_contacts_within_the_gap_are_one_event() -> None:
    events = ContactEvents(gap_s=0.2)
    samples = [(0.0, True), (0.05, False), (0.1, True), (0.15, False), (0.5, True)]
    for t, touching in samples:
        events.sample(t, touching=touching)
    assert events.events == 2  # 0.1 s after the first touch: the same event; 0.5 s: a new one


def test_path_length_and_pose_error() -> None:
    assert path_length(np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 5.0]])) == pytest.approx(6.0)
    assert path_length(np.zeros((1, 2))) == 0.0
    dist, heading = pose_error(_pose(1.0, 1.0, 0.1), _pose(1.0, 2.0, -0.1))
    assert dist == pytest.approx(1.0)
    assert heading == pytest.approx(0.2)
    # heading errors wrap at +-pi
    assert pose_error(_pose(0, 0, 3.1), _pose(0, 0, -3.1))[1] == pytest.approx(6.2 - 2 * math.pi)


def test_interpolate_poses_exact_at_samples_and_between() -> None:
    stamps = np.array([0, 100, 200], dtype=np.int64)
    mats = np.stack([_pose(0, 0, 0), _pose(1, 0, 0.2), _pose(1, 2, 0.4)])
    idx, out = interpolate_poses(stamps, mats, np.array([-5, 0, 50, 150, 200, 201]))
    assert idx.tolist() == [1, 2, 3, 4]  # outside the known span: left out
    np.testing.assert_allclose(out[0], mats[0], atol=1e-12)
    np.testing.assert_allclose(out[3], mats[2], atol=1e-12)
    np.testing.assert_allclose(out[1], _pose(0.5, 0, 0.1), atol=1e-12)
    np.testing.assert_allclose(out[2], _pose(1, 1, 0.3), atol=1e-12)
    none, empty = interpolate_poses(stamps[:1], mats[:1], np.array([0]))
    assert len(none) == 0
    assert empty.shape == (0, 4, 4)
    outside, nothing = interpolate_poses(stamps, mats, np.array([300, 400]))
    assert len(outside) == 0
    assert nothing.shape == (0, 4, 4)


def test_slam_metrics_aligned_and_unaligned() -> None:
    stamps = np.arange(20) * 0.1
    ref = Trajectory.from_matrices(
        stamps, np.stack([_pose(0.1 * i, 0.02 * i**1.5, 0.05 * i) for i in range(20)])
    )
    shifted = ref.matrices()
    shifted[:, :3, 3] += [0.03, -0.04, 0.0]  # a constant 5 cm offset: alignment removes it
    est = Trajectory.from_matrices(stamps, shifted)
    m = slam_metrics(est, ref)
    assert m["ate_unaligned_rmse_m"] == pytest.approx(0.05, abs=1e-5)
    assert m["ate_rmse_m"] == pytest.approx(0.0, abs=1e-5)
    assert m["rpe_trans_rmse_m"] == pytest.approx(0.0, abs=1e-5)
    assert m["rpe_rot_rmse_deg"] == pytest.approx(0.0, abs=1e-4)
    assert set(slam_metrics(est.subset([0, 1]), ref.subset([0, 1])).values()) == {None}


def test_slam_metrics_of_a_car_that_did_not_move() -> None:
    stamps = np.arange(5) * 0.1
    still = Trajectory.from_matrices(stamps, np.stack([_pose(1.0, 2.0, 0.3)] * 5))
    m = slam_metrics(still, still)
    assert m["ate_rmse_m"] is None  # alignment of a single point is undefined
    assert m["ate_unaligned_rmse_m"] == 0.0


def test_pose_errors_summary() -> None:
    errors = PoseErrors()
    assert errors.summary("slam")["rmse_m"] is None
    errors.add(_pose(3.0, 0.0, 0.0), _pose(0.0, 0.0, 0.0))
    errors.add(_pose(0.0, 4.0, 0.0), _pose(0.0, 0.0, 0.0))
    out = errors.summary("static")
    assert out["source"] == "static"
    assert out["samples"] == 2
    assert out["rmse_m"] == pytest.approx(math.sqrt(12.5), abs=1e-4)
    assert out["max_m"] == 4.0
    assert out["heading_rmse_deg"] == 0.0


def test_goal_ids_and_planner_status() -> None:
    assert _goal_index("goal_3") == 2
    assert _goal_index("goal_0") is None
    assert _goal_index("other") is None
    assert parse_planner_status({"goals_reached": "1", "planning_time_ms": "1.5,2"}) == (
        1,
        [1.5, 2.0],
    )
    assert parse_planner_status({"goals_reached": "0", "planning_time_ms": ""}) == (0, [])
    assert parse_planner_status({"goals_reached": "x", "planning_time_ms": "1"}) is None
    assert parse_planner_status({"goals_reached": "1", "planning_time_ms": "nan"}) is None


@given(st.text(max_size=40), st.text(max_size=80))
def test_fuzz_planner_status_never_raises(reached: str, times: str) -> None:
    out = parse_planner_status({"goals_reached": reached, "planning_time_ms": times})
    assert out is None or (out[0] >= 0 and all(math.isfinite(t) for t in out[1]))


@given(st.text(max_size=40))
def test_fuzz_goal_index_never_raises(goal_id: str) -> None:
    index = _goal_index(goal_id)
    assert index is None or index >= 0
