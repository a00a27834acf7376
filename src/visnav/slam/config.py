"""Settings and per-frame results of the SLAM system."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from visnav.slam.errors import SlamInputError

__all__ = ["SlamConfig", "TrackResult", "TrackingState", "check_mono_settings"]

TrackingState = Literal["uninitialized", "ok", "lost"]


@dataclass(frozen=True)
class SlamConfig:
    """Parameters of :class:`~visnav.slam.SlamSystem` (defaults suit 640x480 RGB-D).

    Features: ``n_features``, ``scale_factor``, ``n_levels``, ``fast_threshold``;
    depth is used between ``min_depth`` and ``max_depth`` metres; uint16 depth is
    divided by ``depth_scale`` (None: 1000, ROS millimetres).

    Depth weighting: ``depth_noise`` k models the depth standard deviation as
    ``k * z^2`` metres (structured-light sensors ~0.0015, simulated depth less);
    it sets the virtual stereo baseline ``bf = 1 / k`` used by the optimisers.
    ``close_depth`` (m) is the limit of "close" points in the keyframe rule, and with
    ``far_point_limit`` N of the points a new keyframe makes: nearest first, and past
    ``close_depth`` only until N keypoints (with a map point or a new one) are counted
    (ORB-SLAM2's ``Tracking::CreateNewKeyFrame``, N = 100); None (the default): every
    keypoint with depth makes a point (visnav makes far points from no other source: it
    does not triangulate between RGB-D keyframes as ORB-SLAM2 does).

    Tracking: ``search_radius`` (px) for the motion-model search, ``local_radius``
    for the local-map search, ``min_inliers`` to count a frame as tracked
    (``reloc_min_inliers`` right after relocalisation), ``local_keyframes`` in the
    local map.

    Keyframes: a new one when ``kf_max_frames`` frames passed, tracked points fall
    below ``kf_ratio`` of the reference keyframe's, close tracked points run low
    (RGB-D rule of ORB-SLAM2), or the camera moved ``kf_translation`` m /
    ``kf_rotation_deg`` since the last keyframe.

    Mapping: ``local_ba`` (window ``local_window`` keyframes, ``ba_iterations``),
    ``fuse_neighbours``.

    Loops: ``loop_closure``, vocabulary of ``vocabulary_size`` words trained once
    ``vocabulary_keyframes`` keyframes exist (unless a vocabulary is given),
    ``loop_min_inliers``, ``loop_max_sigma_t`` (m) / ``loop_max_sigma_r`` (rad)
    (largest standard deviation of the verified pose: weak geometry is refused),
    ``loop_max_error_ratio`` (a loop is refused when, after the pose-graph
    optimisation with it, an edge is off by more than this many standard
    deviations; 0: no check), ``loop_consistency``, ``loop_exclude_recent``,
    ``global_ba_after_loop`` (as ORB-SLAM2: without it a loop pose a centimetre or two
    off stays in the merged map), solved inline or, with ``global_ba_delay`` frames > 0,
    in a helper process and merged that many frames after the loop
    (:mod:`visnav.slam.global_ba`); ``final_global_ba`` runs on :meth:`finish`.

    Odometry (optional ``odom_pose`` per frame): predicts the motion instead of
    the constant-velocity model, and after ``reinit_after_lost`` lost frames
    without relocalisation restarts tracking at the odometry-predicted pose,
    corrected while lost by ICP on the depth (:mod:`visnav.slam.restart`; the
    new part of the map joins the old one when a loop or relocalisation links
    them, its first keyframe held in local bundle adjustment until then). With
    ``odom_prior`` the odometry's motion since the last tracked
    frame is also a Gaussian prior in the tracked pose's optimisation, with standard
    deviations ``odometry_sigma_t`` m + ``odometry_sigma_t_rel`` of the distance moved (each
    translation axis) and ``odometry_sigma_r_deg`` + ``odometry_sigma_r_rel`` of the angle
    turned + ``odometry_sigma_r_per_m`` rad per metre moved (each rotation axis; amcl's
    ``odom_alpha1`` / ``odom_alpha2`` in spirit: unequal wheel radii turn the odometry's
    heading while it drives straight): it holds the pose where the matched points do not
    (all of them far down a corridor: a sideways shift and a turn then look alike), and
    links consecutive keyframes in local bundle adjustment. ``odometry_model`` ``"diff"``
    (amcl's ``odom_model_type``) is a base that cannot move sideways: its sideways error
    (horizontal, across the motion) is only ``odometry_sigma_t_lateral`` m + the distance
    moved times the heading's standard deviation, where ``"omni"`` (the default) takes the
    same standard deviation on every axis.

    Monocular (``sensor="mono"``, :mod:`visnav.slam.monocular`): keypoints get no
    depth; the map starts from two views (median parallax ``init_min_parallax_deg``,
    ``init_min_points`` points) with the metric scale from the depth image at
    initialisation (``mono_scale="depth"``) or the odometry translation between
    the two views (``"odometry"``); new points are triangulated with the
    ``triangulation_neighbours`` best covisible keyframes. The scale drifts.

    Dense refinement (RGB-D, :mod:`visnav.slam.dense`): with ``icp_refinement`` each
    tracked pose is refined by point-to-plane ICP of its depth (every ``icp_stride``-th
    pixel) against the reference keyframe's, the feature pose's information as a
    prior; the ``icp_keyframes`` most recent keyframes keep their depth for it.

    ``seed`` seeds every random choice (RANSAC, vocabulary); ``dense_stride`` is the
    pixel stride of the points kept per keyframe for the dense cloud.
    """

    n_features: int = 1000
    scale_factor: float = 1.2
    n_levels: int = 8
    fast_threshold: int = 20
    grid_cell: int = 40
    min_depth: float = 0.1
    max_depth: float = 8.0
    depth_scale: float | None = None
    depth_noise: float = 0.0004
    close_depth: float = 3.0
    far_point_limit: int | None = None
    search_radius: float = 15.0
    local_radius: float = 4.0
    min_inliers: int = 30
    reloc_min_inliers: int = 40
    local_keyframes: int = 12
    kf_max_frames: int = 20
    kf_min_frames: int = 0
    kf_ratio: float = 0.75
    kf_translation: float = 0.25
    kf_rotation_deg: float = 15.0
    local_ba: bool = True
    local_window: int = 8
    ba_iterations: int = 4
    fuse_neighbours: int = 8
    loop_closure: bool = True
    vocabulary_size: int = 500
    vocabulary_keyframes: int = 12
    loop_min_inliers: int = 50
    loop_max_sigma_t: float = 0.05
    loop_max_sigma_r: float = 0.01
    loop_max_error_ratio: float = 3.0
    loop_consistency: int = 1
    loop_exclude_recent: int = 20
    loop_min_gap: int = 10
    global_ba_after_loop: bool = True
    final_global_ba: bool = True
    global_ba_iterations: int = 15
    global_ba_delay: int = 0
    seed: int = 0
    dense_stride: int = 8
    icp_refinement: bool = True
    icp_stride: int = 6
    icp_keyframes: int = 8
    reinit_after_lost: int = 5
    odom_prior: bool = True
    odometry_sigma_t: float = 0.005
    odometry_sigma_t_rel: float = 0.05
    odometry_sigma_r_deg: float = 0.1
    odometry_sigma_r_rel: float = 0.2
    odometry_sigma_r_per_m: float = 0.02
    odometry_model: Literal["omni", "diff"] = "omni"
    odometry_sigma_t_lateral: float = 0.001
    sensor: Literal["rgbd", "mono"] = "rgbd"
    mono_scale: Literal["depth", "odometry"] = "depth"
    init_min_parallax_deg: float = 1.0
    init_min_points: int = 50
    triangulation_neighbours: int = 10

    def __post_init__(self) -> None:
        check_mono_settings(self.sensor, self.mono_scale)
        ints = ("n_features", "n_levels", "grid_cell", "ba_iterations", "dense_stride")
        for name in (*ints, "icp_stride", "icp_keyframes"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                flag = " (--features)" if name == "n_features" else ""
                default = getattr(SlamConfig, name)
                text = f"{name}{flag} is {value!r}: expected a positive integer (default {default})"
                raise SlamInputError(text)
        limit = self.far_point_limit
        bad_limit = not isinstance(limit, int) or isinstance(limit, bool) or limit < 0
        if limit is not None and bad_limit:
            text = (
                f"far_point_limit is {limit!r}: expected None (every depth makes a point) or "
                "keypoints >= 0 (ORB-SLAM2: 100)"
            )
            raise SlamInputError(text)
        delay = self.global_ba_delay
        if not isinstance(delay, int) or isinstance(delay, bool) or delay < 0:
            text = f"global_ba_delay is {delay!r}: expected frames >= 0 (0: inline, the default)"
            raise SlamInputError(text)
        if not self.scale_factor > 1.0:
            text = f"scale_factor is {self.scale_factor!r}: expected a number > 1 (ORB: 1.2)"
            raise SlamInputError(text)
        if self.odometry_model not in ("omni", "diff"):
            text = (
                f"odometry_model is {self.odometry_model!r}: expected 'diff' (a wheeled base that "
                "cannot move sideways, amcl's odom_model_type diff) or 'omni' (any direction; "
                "the default)"
            )
            raise SlamInputError(text)
        for name in ("odometry_sigma_t", "odometry_sigma_r_deg", "odometry_sigma_t_lateral"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0.0 and value < float("inf")):
                default = getattr(SlamConfig, name)
                text = f"{name} is {value!r}: expected a number > 0 (default {default})"
                raise SlamInputError(text)
        for name in ("odometry_sigma_t_rel", "odometry_sigma_r_rel", "odometry_sigma_r_per_m"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value >= 0.0 and value < float("inf")):
                default = getattr(SlamConfig, name)
                text = f"{name} is {value!r}: expected a number >= 0 (default {default})"
                raise SlamInputError(text)


def check_mono_settings(sensor: str, mono_scale: str) -> None:
    """Refuse unknown ``sensor`` / ``mono_scale`` values.

    Raises:
        SlamInputError: naming the value and the accepted ones.
    """
    if sensor not in ("rgbd", "mono"):
        text = f"sensor {sensor!r}: expected 'rgbd' or 'mono'"
        raise SlamInputError(text)
    if mono_scale not in ("depth", "odometry"):
        text = (
            f"mono_scale {mono_scale!r}: expected 'depth' (depth image at initialisation) or "
            "'odometry' (odometry translation between the initial frames)"
        )
        raise SlamInputError(text)


@dataclass(frozen=True)
class TrackResult:
    """The outcome of one frame.

    Attributes:
        stamp_ns: the frame's stamp.
        state: tracking state after the frame.
        t_wc: camera pose in the map frame (None when not tracked).
        inliers: inlier map point matches.
        keyframe: a keyframe was created.
        loop: a loop was closed (past poses moved).
        relocalized: tracking was recovered from loss on this frame.
        reinitialized: tracking restarted from the odometry prior after a loss.
        warnings: problems noticed with this frame's inputs.
        timings: seconds per stage (features, matching, pose, mapping, loop).
        cpu_timings: CPU seconds per stage (the tracking thread's).
    """

    stamp_ns: int
    state: TrackingState
    t_wc: NDArray[np.float64] | None
    inliers: int = 0
    keyframe: bool = False
    loop: bool = False
    relocalized: bool = False
    reinitialized: bool = False
    warnings: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)
