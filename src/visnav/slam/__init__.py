"""Visual SLAM (RGB-D) and trajectory evaluation.

* :class:`SlamSystem`: ORB features, tracking by projection + robust pose
  optimisation against a local map, keyframes, local bundle adjustment (gtsam),
  bag-of-words loop detection with geometric verification, pose-graph
  optimisation (gtsam), relocalisation. Numpy in, poses out; deterministic.
* :class:`SlamNode` (:mod:`visnav.slam.node`): the graph node (``map -> odom``,
  ``slam/pose``, ``slam/path``, map clouds).
* :func:`slam_tum`, :func:`slam_bag`: offline runs writing TUM trajectories.
* :func:`ate`, :func:`rpe`: trajectory metrics agreeing with evo.
* :mod:`visnav.slam.synthetic`: textured-room RGB-D sequences with ground truth.

The node lives in :mod:`visnav.slam.node` and is not imported here (it pulls in
the graph); import it from there.
"""

from __future__ import annotations

from visnav.slam.camera import CameraIntrinsics, check_depth_scale, depth_to_metres
from visnav.slam.config import SlamConfig, TrackingState, TrackResult
from visnav.slam.errors import (
    AssociationError,
    EvaluationError,
    SlamError,
    SlamInputError,
    TrajectoryFormatError,
)
from visnav.slam.evaluation import Alignment, ErrorStats, associate, ate, rpe, umeyama
from visnav.slam.offline import SlamRun, slam_bag, slam_tum
from visnav.slam.system import SlamSystem
from visnav.slam.trajectory import Trajectory, read_tum, write_tum
from visnav.slam.tum import TumSequence, associate_stamps
from visnav.slam.vocabulary import BowDatabase, Vocabulary

__all__ = [
    "Alignment",
    "AssociationError",
    "BowDatabase",
    "CameraIntrinsics",
    "ErrorStats",
    "EvaluationError",
    "SlamConfig",
    "SlamError",
    "SlamInputError",
    "SlamRun",
    "SlamSystem",
    "TrackResult",
    "TrackingState",
    "Trajectory",
    "TrajectoryFormatError",
    "TumSequence",
    "Vocabulary",
    "associate",
    "associate_stamps",
    "ate",
    "check_depth_scale",
    "depth_to_metres",
    "read_tum",
    "rpe",
    "slam_bag",
    "slam_tum",
    "umeyama",
    "write_tum",
]
