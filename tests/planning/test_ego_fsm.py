"""The replan FSM driven by a fake odometry source (perfect tracking), without a graph."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.mapping.grid_map import GridMap, GridMapParams
from visnav.planning.ego_planner.fsm import FSMError, FSMParams, FSMState, ReplanFSM
from visnav.planning.ego_planner.manager import LocalTrajectory, PlannerManager
from visnav.planning.ego_planner.messages import msg_to_trajectory, trajectory_to_msg
from visnav.planning.ego_planner.traj_server import TrajectoryServer

_NS = 1_000_000_000
TICK = 10_000_000  # 100 Hz


class Flight:
    """An FSM, a traj server and a vehicle that tracks the server's commands exactly."""

    def __init__(
        self, gm: GridMap, params: FSMParams | None = None, start=(-8.0, 0.0, 1.0)
    ) -> None:
        self.manager = PlannerManager(gm, seed=0)
        self.published: list[LocalTrajectory] = []
        self.server = TrajectoryServer()
        self.fsm = ReplanFSM(self.manager, params, on_trajectory=self._on_traj)
        self.now = _NS
        self.pos = np.array(start, dtype=float)
        self.vel = np.zeros(3)
        self.track: list[np.ndarray] = []

    def _on_traj(self, traj: LocalTrajectory) -> None:
        self.published.append(traj)
        start_ns, sampled = msg_to_trajectory(trajectory_to_msg(traj, frame_id="world"))
        self.server.set_trajectory(sampled, start_ns)

    def tick(self) -> None:
        self.now += TICK
        ref = self.server.command(self.now)
        if ref is not None:
            self.pos = np.array(ref.position)
            self.vel = np.array(ref.velocity)
        self.track.append(self.pos.copy())
        self.fsm.set_odometry(self.pos, self.vel, now_ns=self.now)
        self.fsm.step(self.now)
        if (self.now // TICK) % 5 == 0:
            self.fsm.check_collision(self.now)

    def run(self, seconds: float, *, until: FSMState | None = None) -> None:
        for _ in range(round(seconds * 100)):
            self.tick()
            if until is not None and self.fsm.state == until:
                return


def _map(width: float = 12.0, height: float = 3.0) -> GridMap:
    return GridMap(GridMapParams(map_size=(24.0, width, height), virtual_ceil_height=height - 0.5))


def _columns(gm: GridMap, centres: list[tuple[float, float, float]]) -> None:
    for x, y, r in centres:
        zs = np.arange(0.0, 3.0, 0.05)
        th = np.linspace(0, 2 * np.pi, 60, endpoint=False)
        for rr in np.arange(0.0, r + 1e-9, 0.05):
            ring = np.column_stack([x + rr * np.cos(th), y + rr * np.sin(th)])
            gm.mark_occupied(
                np.column_stack([np.repeat(ring, len(zs), axis=0), np.tile(zs, len(th))])
            )


def test_transitions_from_init_to_goal() -> None:
    gm = _map()
    _columns(gm, [(-3.0, 0.2, 0.4), (2.0, -0.3, 0.3)])
    flight = Flight(gm)
    fsm = flight.fsm
    fsm.step(flight.now)
    assert fsm.state == FSMState.INIT  # no odometry yet
    assert not fsm.set_goal([8.0, 0.0], now_ns=flight.now)  # ignored without odometry
    flight.tick()
    assert fsm.state == FSMState.WAIT_TARGET
    flight.tick()
    assert fsm.state == FSMState.WAIT_TARGET  # no goal yet
    assert fsm.set_goal([8.0, 0.0], now_ns=flight.now)
    assert np.allclose(fsm.end_pt, [8.0, 0.0, 1.0])  # flight_height for a 2D goal
    assert fsm.state == FSMState.GEN_NEW_TRAJ
    flight.tick()
    assert fsm.state == FSMState.EXEC_TRAJ
    assert len(flight.published) == 1
    first = flight.published[0]
    assert np.linalg.norm(fsm.local_target_pt - flight.pos) == pytest.approx(7.5, abs=0.3)
    flight.run(60.0, until=FSMState.WAIT_TARGET)
    assert fsm.state == FSMState.WAIT_TARGET
    assert fsm.goals_reached == 1
    assert np.linalg.norm(flight.pos - [8.0, 0.0, 1.0]) < 0.2  # the last fit is least squares
    visited = {(a, b) for a, b, _ in fsm.transitions}
    assert (FSMState.EXEC_TRAJ, FSMState.REPLAN_TRAJ) in visited
    assert (FSMState.REPLAN_TRAJ, FSMState.EXEC_TRAJ) in visited
    assert len(flight.published) > 3
    assert flight.published[-1].traj_id > first.traj_id
    track = np.array(flight.track)
    assert not gm.inflate_occupancy(track).any()
    speeds = np.linalg.norm(np.diff(track, axis=0), axis=1) / (TICK / _NS)
    assert speeds.max() < 2.0 * np.sqrt(3) * 1.05  # per-axis limit 2 m/s
    assert speeds.mean() > 1.0


def test_sudden_wall_triggers_emergency_stop_then_a_new_plan() -> None:
    gm = _map(width=5.0, height=2.0)  # small, so that the failing A* searches end soon
    flight = Flight(gm)
    flight.tick()
    flight.fsm.set_goal([8.0, 0.0], now_ns=flight.now)
    flight.run(2.0)
    assert flight.fsm.state == FSMState.EXEC_TRAJ
    # a wall closing the whole corridor, 0.5 m ahead of the vehicle
    x = flight.pos[0] + 0.5
    ys, zs = np.meshgrid(np.arange(-2.5, 2.5, 0.05), np.arange(0.0, 2.0, 0.05))
    gm.mark_occupied(np.column_stack([np.full(ys.size, x), ys.ravel(), zs.ravel()]))
    flight.run(1.0, until=FSMState.EMERGENCY_STOP)
    assert flight.fsm.state == FSMState.EMERGENCY_STOP
    n = len(flight.published)
    flight.tick()  # the stop trajectory: stand where the odometry is
    assert len(flight.published) == n + 1
    stop = flight.published[-1]
    assert np.allclose(stop.position.control_points, stop.position.control_points[0])
    flight.run(0.3)
    # at rest (this vehicle stops at once) it tries new plans, which the wall defeats
    assert flight.fsm.state == FSMState.GEN_NEW_TRAJ
    assert (FSMState.EMERGENCY_STOP, FSMState.GEN_NEW_TRAJ, "FSM") in flight.fsm.transitions
    assert flight.pos[0] < x - 0.1  # stopped short of the wall
    assert not flight.manager.records[-1].success
    gm.reset()  # the wall goes away
    flight.run(1.0, until=FSMState.EXEC_TRAJ)
    assert flight.fsm.state == FSMState.EXEC_TRAJ


def test_preset_waypoints_start_on_the_first_odometry() -> None:
    gm = _map()
    params = FSMParams(
        flight_type=2, waypoints=((-4.0, 2.0, 1.0), (0.0, -2.0, 1.2), (4.0, 0.0, 1.0))
    )
    flight = Flight(gm, params)
    flight.tick()
    assert flight.fsm.state == FSMState.EXEC_TRAJ
    g = flight.manager.global_traj
    assert g is not None
    pts = g.traj.evaluate(g.traj.boundaries)
    for wp in params.waypoints:
        assert np.min(np.linalg.norm(pts - wp, axis=1)) < 1e-6
    flight.run(40.0, until=FSMState.WAIT_TARGET)
    assert flight.fsm.goals_reached == 1
    assert np.linalg.norm(flight.pos - [4.0, 0.0, 1.0]) < 0.2
    with pytest.raises(FSMError, match="waypoints"):
        FSMParams(flight_type=2)
    with pytest.raises(FSMError, match="flight_type"):
        FSMParams(flight_type=3)
