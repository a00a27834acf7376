"""The observer's bookkeeping without a graph: contact events, errors, id parsing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.scenarios.observer import _goal_index, parse_planner_status
from visnav.scenarios.observer_metrics import ContactEvents, PoseErrors, path_length, pose_error


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
