"""An earlier loop that later verified loops keep contradicting is dropped (loop_closing.py)."""

from __future__ import annotations

import numpy as np

from visnav.slam import SlamConfig, SlamSystem
from visnav.slam.geometry import inverse, se3_exp
from visnav.slam.loop_closing import LOOP_CONTRADICTION_VOTES, LoopCloser
from visnav.slam.optimizer import LoopConstraint, optimize_pose_graph

from .conftest import Sequence

CONFIG = SlamConfig(n_features=400, vocabulary_keyframes=6, loop_min_inliers=30)
TIGHT = np.eye(6) * 1e-6  # 1 mm, 1 mrad


def _true_loop(slam: SlamSystem, i: int, j: int) -> LoopConstraint:
    """A loop that measures what the chain already says (a consistent one)."""
    kfs = slam.map.keyframes
    return LoopConstraint(i, j, kfs[i].t_cw @ kfs[j].t_wc, TIGHT)


def test_a_contradicted_loop_is_dropped_after_enough_votes(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
    for i in range(40):
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
    kfs = slam.map.keyframes
    assert len(kfs) >= 3 + LOOP_CONTRADICTION_VOTES
    closer = LoopCloser(slam.map, slam.camera, CONFIG)
    # an earlier loop measured 20 cm off, with a tight covariance (weak geometry, closed anyway)
    bad = _true_loop(slam, 0, 2)
    bad = LoopConstraint(0, 2, bad.t_ij @ se3_exp(np.array([0.2, 0, 0, 0, 0, 0])), TIGHT)
    closer.loops = [bad]
    # the pose graph cannot take it (refused: the poses stay)
    assert optimize_pose_graph(slam.map, [bad], max_error_ratio=CONFIG.loop_max_error_ratio) is None
    poses = [kf.t_cw.copy() for kf in kfs]
    new_ids = [len(kfs) - 1 - k for k in range(LOOP_CONTRADICTION_VOTES)]
    for n, j in enumerate(new_ids, start=1):
        loop = _true_loop(slam, 1, j)
        corrections = closer._without_contradicted_loop(loop)
        if n < LOOP_CONTRADICTION_VOTES:
            # not enough keyframes contradict it yet: nothing changes
            assert corrections is None
            assert closer.loops == [bad]
            for kf, pose in zip(kfs, poses, strict=True):
                np.testing.assert_array_equal(kf.t_cw, pose)
    assert corrections is not None
    assert closer.loops == []
    assert closer.rejected == [bad]
    # the chain, which the new loops agree with, hardly moves
    for kf, pose in zip(kfs, poses, strict=True):
        assert np.linalg.norm((kf.t_cw @ inverse(pose))[:3, 3]) < 0.002


def test_the_same_keyframe_votes_once(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
    for i in range(40):
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
    kfs = slam.map.keyframes
    closer = LoopCloser(slam.map, slam.camera, CONFIG)
    bad = _true_loop(slam, 0, 2)
    bad = LoopConstraint(0, 2, bad.t_ij @ se3_exp(np.array([0.2, 0, 0, 0, 0, 0])), TIGHT)
    closer.loops = [bad]
    j = len(kfs) - 1
    for _ in range(LOOP_CONTRADICTION_VOTES + 1):  # one keyframe, several candidates
        assert closer._without_contradicted_loop(_true_loop(slam, 1, j)) is None
    assert closer.loops == [bad]
