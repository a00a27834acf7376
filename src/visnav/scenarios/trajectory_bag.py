"""The tracks of ``trajectory.png`` read from a run's bag (:mod:`visnav.scenarios.trajectory_plot`).

One pass over the bag's topics that the observer reads (ground truth, odometry, goals,
move_base's status, SLAM) plus, when needed, the map topic, ``/tf`` (the localisation:
``map -> base`` at the ground-truth stamps, 10 Hz, as the observer samples it) and the
drone's planned paths.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.msgs.time import time_to_ns
from visnav.scenarios.observer import _goal_index
from visnav.scenarios.observer_metrics import ENDED_STATUSES, SUCCEEDED_STATUS
from visnav.scenarios.trajectory_plot import XY, GoalMark, RunTracks, map_shade
from visnav.tf import pose_to_matrix

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping

    from visnav.bag.reader import RawMessage
    from visnav.scenarios.observer import ObserverParams

__all__ = ["read_bag_tracks"]

_PATH_TYPE = "nav_msgs/msg/Path"
_LOCALISATION_PERIOD_NS = 100_000_000


class _Collected:
    """What the pass over the bag keeps."""

    def __init__(self) -> None:
        self.truth: list[tuple[int, Any]] = []  # (stamp, geometry_msgs/Pose)
        self.base = ""
        self.odom: list[tuple[int, Any]] = []
        self.goals: list[tuple[float, float]] = []
        self.ended: dict[int, tuple[int, bool]] = {}  # goal index -> (bag time, succeeded)
        self.slam_path: list[tuple[int, Any]] = []
        self.slam_poses: list[tuple[int, Any]] = []
        self.grid: Any = None
        self.tf: list[tuple[Any, bool]] = []
        self.plans: list[XY] = []

    def take(self, topic: str, t_ns: int, msg: Any, topics: Mapping[str, str]) -> None:
        if topic == topics["ground_truth_topic"]:
            self.truth.append((time_to_ns(msg.header.stamp), msg.pose.pose))
            self.base = msg.child_frame_id
        elif topic == topics["odom_topic"]:
            self.odom.append((time_to_ns(msg.header.stamp), msg.pose.pose))
        elif topic == topics["goal_topic"]:
            self.goals.append((float(msg.pose.position.x), float(msg.pose.position.y)))
        elif topic == topics["status_topic"]:
            for status in msg.status_list:
                index = _goal_index(str(status.goal_id.id))
                code = int(status.status)
                if index is not None and code in ENDED_STATUSES and index not in self.ended:
                    self.ended[index] = (t_ns, code == SUCCEEDED_STATUS)
        elif topic == topics["slam_path_topic"]:
            self.slam_path = [(time_to_ns(p.header.stamp), p.pose) for p in msg.poses]
        elif topic == topics["slam_pose_topic"]:
            self.slam_poses.append((time_to_ns(msg.header.stamp), msg.pose))
        elif topic == topics["map_topic"]:
            self.grid = msg
        elif topic in ("/tf", "/tf_static"):
            self.tf.extend((tr, topic == "/tf_static") for tr in msg.transforms)
        elif getattr(msg, "poses", None):  # a planned path
            self.plans.append(_xy(p.pose for p in msg.poses))


def _xy(poses: Iterable[Any]) -> XY:
    pts = [(p.position.x, p.position.y) for p in poses]
    return np.asarray(pts, dtype=np.float64).reshape(-1, 2)


def read_bag_tracks(
    bag: Path,
    params: ObserverParams,
    topics: Mapping[str, str],
    *,
    saved_map: Path,
) -> tuple[RunTracks, list[GoalMark]] | None:
    """The tracks and goals of a run's bag (None: no ground truth in it).

    Args:
        bag: the run's bag.
        params: the observer's parameters (scenario, goals, tolerance, frames).
        topics: the observer's topic parameters, resolved to absolute names.
        saved_map: the run's ``map.yaml`` (drawn when it exists, else the bag's last map).

    Raises:
        BagError: the bag does not read.
        MapFileError: ``saved_map`` does not read.
    """
    from visnav.bag.reader import BagReader  # noqa: PLC0415 - heavy

    have_map = saved_map.is_file()
    localise = params.localization_source not in ("", "static")
    with BagReader(bag) as reader:
        available = {name: meta.type_name for name, meta in reader.topics.items()}
        if topics["ground_truth_topic"] not in available:
            return None
        slam = topics["slam_path_topic"] in available or topics["slam_pose_topic"] in available
        localise = localise and not (slam and params.localization_source == "slam")
        wanted = [t for t in topics.values() if t in available and t != topics["map_topic"]]
        if not have_map and topics["map_topic"] in available:
            wanted.append(topics["map_topic"])
        if localise:
            wanted += [t for t in ("/tf", "/tf_static") if t in available]
        if params.scenario == "drone":
            skip = {topics["slam_path_topic"]}
            wanted += [t for t, k in available.items() if k == _PATH_TYPE and t not in skip]
        got = _Collected()
        # only the last SLAM path and map count: decoding each (a growing Path of every
        # pose) was 2/3 of the time on a 134 s car run
        last_only = {topics["slam_path_topic"], topics["map_topic"]}
        last: dict[str, RawMessage] = {}
        for raw in reader.raw_messages(sorted(set(wanted))):
            if raw.topic in last_only:
                last[raw.topic] = raw._replace(data=bytes(raw.data))
            else:
                got.take(raw.topic, raw.t_ns, reader.decode(raw), topics)
        for raw in last.values():
            got.take(raw.topic, raw.t_ns, reader.decode(raw), topics)
    if not got.truth:
        return None
    truth = _xy(p for _, p in got.truth)
    tracks = RunTracks(title="", truth=truth)
    if got.slam_path or got.slam_poses:
        tracks.estimates["SLAM (slam/path)"] = _slam_track(got)
    if localise and got.tf:
        track = _localisation(got, params)
        if len(track):
            tracks.estimates[f"localisation ({params.localization_source})"] = track
    if got.odom:
        tracks.estimates[f"wheel odometry ({topics['odom_topic']})"] = _odometry(got)
    tracks.plans = _spread(got.plans)
    _map(tracks, saved_map if have_map else None, got.grid, topics["map_topic"])
    return tracks, _goals(got, params)


def _slam_track(got: _Collected) -> XY:
    """The last ``slam/path`` plus the poses after it (the observer's SLAM estimate)."""
    last = got.slam_path[-1][0] if got.slam_path else -1
    later = [p for stamp, p in got.slam_poses if stamp > last]
    return _xy([p for _, p in got.slam_path] + later)


def _odometry(got: _Collected) -> XY:
    """Odometry anchored at the ground-truth pose of its first stamp (its drift shows)."""
    stamps = np.array([s for s, _ in got.truth], dtype=np.int64)
    first_stamp, first = got.odom[0]
    k = min(int(np.searchsorted(stamps, first_stamp)), len(stamps) - 1)
    anchor = pose_to_matrix(got.truth[k][1]) @ np.linalg.inv(pose_to_matrix(first))
    pts = np.array([(p.position.x, p.position.y, p.position.z) for _, p in got.odom])
    moved: XY = pts @ anchor[:3, :3].T + anchor[:3, 3]
    return moved[:, :2]


def _localisation(got: _Collected, params: ObserverParams) -> XY:
    """``map -> base`` from the bag's TF at the ground-truth stamps, every 0.1 s."""
    from visnav.tf import Buffer  # noqa: PLC0415
    from visnav.tf.errors import TransformException  # noqa: PLC0415

    parents = {tr.child_frame_id: tr.header.frame_id for tr, _ in got.tf}
    chain, frame = set(), got.base
    while frame in parents and frame not in chain:  # only base's ancestors are needed
        chain.add(frame)
        frame = parents[frame]
    span = (got.truth[-1][0] - got.truth[0][0]) / 1e9
    buffer = Buffer(cache_time=span + 60.0)
    for tr, static in got.tf:
        if tr.child_frame_id in chain:
            insert = buffer.set_transform_static if static else buffer.set_transform
            insert(tr, "bag")
    out: list[tuple[float, float]] = []
    next_ns = -1
    for stamp, _ in got.truth:
        if stamp < next_ns:
            continue
        try:
            m = buffer.lookup_transform_matrix(params.map_frame, got.base, stamp)
        except TransformException:
            continue
        out.append((float(m[0, 3]), float(m[1, 3])))
        next_ns = stamp + _LOCALISATION_PERIOD_NS
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def _spread(plans: list[XY], most: int = 150) -> list[XY]:
    """At most ``most`` plans, evenly chosen (the drone replans a few hundred times)."""
    if len(plans) <= most:
        return plans
    return [plans[int(i)] for i in np.linspace(0, len(plans) - 1, most).round()]


def _map(tracks: RunTracks, saved: Path | None, grid: Any, topic: str) -> None:
    """The run's saved map, else the last map on the map topic (None: the world's, later)."""
    if saved is not None:
        from visnav.mapping.map_io import load_map  # noqa: PLC0415

        loaded = load_map(saved)
        data, res = loaded.data, loaded.metadata.resolution
        x, y, _ = loaded.metadata.origin
        tracks.map_label = f"saved map ({saved.name})"
    elif grid is not None:
        info = grid.info
        data = np.asarray(grid.data, dtype=np.int8).reshape(info.height, info.width)
        res, x, y = float(info.resolution), info.origin.position.x, info.origin.position.y
        tracks.map_label = f"map (the last on {topic})"
    else:
        return
    height, width = data.shape
    tracks.shade = map_shade(data)
    tracks.extent = (float(x), float(x + width * res), float(y), float(y + height * res))


def _goals(got: _Collected, params: ObserverParams) -> list[GoalMark]:
    """The goals sent, reached as the observer counts it (succeeded, within tolerance)."""
    stamps = np.array([s for s, _ in got.truth], dtype=np.int64)
    marks: list[GoalMark] = []
    for index, (x, y) in enumerate(got.goals[: params.goals]):
        end = got.ended.get(index)
        reached = False
        if end is not None and end[1]:
            k = max(int(np.searchsorted(stamps, end[0], side="right")) - 1, 0)
            pos = got.truth[k][1].position
            reached = math.hypot(pos.x - x, pos.y - y) < params.goal_tolerance
        marks.append(GoalMark(x, y, reached, ended=end is not None))
    return marks
