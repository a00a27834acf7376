"""Loop closing: the bag-of-words database, loop detection, verification and correction.

Each new keyframe gets a bag-of-words vector (the vocabulary is trained on the
first ``vocabulary_keyframes`` keyframes unless one is given). Loop candidates
from :class:`~visnav.slam.place_recognition.LoopDetector` are verified by
localising the keyframe in the candidate's map region; a loop is accepted only
when the pose found there is well determined (its standard deviations below
``loop_max_sigma_t`` / ``loop_max_sigma_r``: matches on one distant wall can
leave a rotation-translation ambiguity of a degree), and only when the pose graph
with the new constraint stays consistent (no edge off by more than
``loop_max_error_ratio`` standard deviations after optimisation, RTAB-Map's
``RGBD/OptimizeMaxError``): look-alike places (rooms furnished alike) pass the
geometric check but not this one. An earlier loop that such refused loops from
``LOOP_CONTRADICTION_VOTES`` keyframes all contradict (each consistent without it)
is dropped instead, and the new loop closes. The correction then:

1. adds the relative pose (weighted by its covariance) to the loop constraints
   and optimises the pose graph (gtsam), keyframe 0 fixed;
2. moves every map point with the correction of its reference keyframe;
3. merges the keyframe's matched points into the old ones and fuses the old
   region's points into the keyframe's neighbourhood, so tracking continues on
   the old map;
4. optionally runs a global bundle adjustment.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig
from visnav.slam.features import DescArray
from visnav.slam.geometry import inverse
from visnav.slam.mapping import fuse_points
from visnav.slam.optimizer import LoopConstraint, apply_point_corrections, optimize_pose_graph
from visnav.slam.place_recognition import Localization, LoopDetector, localize_in_map
from visnav.slam.slam_map import Keyframe, SlamMap
from visnav.slam.vocabulary import BowDatabase, Vocabulary

__all__ = ["LOOP_CONTRADICTION_VOTES", "LoopCloser"]

FloatArray = NDArray[np.float64]

LOOP_CONTRADICTION_VOTES = 3
"""Keyframes whose verified loops must contradict an earlier loop before it is dropped."""


class LoopCloser:
    """Bag-of-words place memory and loop closure over one map.

    Args:
        slam_map: the map (corrected in place).
        camera: intrinsics.
        config: the SLAM parameters (loop and vocabulary settings).
        vocabulary: a pre-trained vocabulary (default: trained on the fly).
        global_ba: called after a correction when ``config.global_ba_after_loop``.
        before_correction: called when a verified loop is about to be checked against
            and applied to the pose graph (a background adjustment still pending is merged
            first: it was due earlier, and merged later it would undo the correction).
    """

    def __init__(
        self,
        slam_map: SlamMap,
        camera: CameraIntrinsics,
        config: SlamConfig,
        *,
        vocabulary: Vocabulary | None = None,
        global_ba: Callable[[], object] | None = None,
        before_correction: Callable[[], object] | None = None,
    ) -> None:
        self.map = slam_map
        self.camera = camera
        self.config = config
        self.vocabulary = vocabulary
        self.database = BowDatabase(vocabulary) if vocabulary is not None else None
        self.detector = LoopDetector(
            exclude_recent=config.loop_exclude_recent, consistency=config.loop_consistency
        )
        self.loops: list[LoopConstraint] = []
        self.rejected: list[LoopConstraint] = []
        self.last_loop_kf = -(10**9)
        self._contradictions: dict[tuple[int, int], set[int]] = {}
        self._global_ba = global_ba
        self._before_correction = before_correction

    def place_candidates(self, descriptors: DescArray, n: int) -> list[int]:
        """Keyframes most similar to an image by bag of words (empty before the vocabulary)."""
        if self.vocabulary is None or self.database is None or not len(self.database):
            return []
        ids, scores = self.database.query(self.vocabulary.transform(descriptors))
        order = np.lexsort((ids, -scores))[:n]
        return [int(ids[i]) for i in order]

    def index_map(self) -> None:
        """Describe the keyframes of the map not described yet (a loaded map's) by words.

        Without a vocabulary one is trained first, on ``vocabulary_keyframes`` keyframes
        spread evenly over the map (in mapping it is the first ones: there are no others).
        """
        kfs = [k for k in self.map.keyframes if not k.bad]
        if not kfs:
            return
        if self.vocabulary is None:
            step = max(1, len(kfs) // max(1, self.config.vocabulary_keyframes))
            docs = [k.frame.descriptors for k in kfs[::step]]
            cfg = self.config
            self.vocabulary = Vocabulary.train(docs, k=cfg.vocabulary_size, seed=cfg.seed)
            self.database = BowDatabase(self.vocabulary)
        assert self.database is not None  # made with the vocabulary
        for k in kfs:
            if k.bow is None:  # not yet in the database
                k.bow = self.vocabulary.transform(k.frame.descriptors)
                self.database.add(k.id, k.bow)

    def add_keyframe(self, kf: Keyframe) -> bool:
        """Describe a new keyframe, look for a loop and close it; return whether one closed."""
        cfg = self.config
        if self.vocabulary is None:
            if not cfg.loop_closure or len(self.map.keyframes) < cfg.vocabulary_keyframes:
                return False
            docs = [k.frame.descriptors for k in self.map.keyframes]
            self.vocabulary = Vocabulary.train(docs, k=cfg.vocabulary_size, seed=cfg.seed)
            self.database = BowDatabase(self.vocabulary)
            for k in self.map.keyframes[:-1]:
                k.bow = self.vocabulary.transform(k.frame.descriptors)
                self.database.add(k.id, k.bow)
        assert self.database is not None  # created with the vocabulary
        kf.bow = self.vocabulary.transform(kf.frame.descriptors)
        closed = False
        if cfg.loop_closure and kf.id - self.last_loop_kf >= cfg.loop_min_gap:
            closed = self._detect_and_close(kf)
        self.database.add(kf.id, kf.bow)
        return closed

    def _detect_and_close(self, kf: Keyframe) -> bool:
        assert self.vocabulary is not None  # add_keyframe made it
        assert self.database is not None
        cfg = self.config
        for c in self.detector.candidates(kf, self.map, self.database, self.vocabulary):
            group = [c, *self.map.keyframes[c].best_covisibles(8)]
            loc = localize_in_map(
                kf.frame, self.camera, self.map, group, min_inliers=cfg.loop_min_inliers
            )
            if loc is None:
                continue
            sigma_t, sigma_r = loc.sigmas()
            if sigma_t > cfg.loop_max_sigma_t or sigma_r > cfg.loop_max_sigma_r:
                continue
            if self._close(kf, c, loc):
                return True
        return False

    def _without_contradicted_loop(self, loop: LoopConstraint) -> dict[int, FloatArray] | None:
        """Drop an earlier loop that verified loops from several keyframes contradict.

        A loop closed on weak geometry (seed 8 of the car: the restart keyframe, facing a
        wall closer than the depth range, closed one with a 3.75 cm standard deviation)
        can make every later true loop in its region inconsistent (there: 50 verified
        loops refused in 62-96 s, the old loop off by 4.9 standard deviations in each),
        and the map stays off. When the pose graph with
        ``loop`` is consistent without one earlier loop, that loop gets a vote from
        ``loop``'s keyframe; with votes from ``LOOP_CONTRADICTION_VOTES`` keyframes it is
        dropped and ``loop`` closes instead (a robust back end's switchable constraint,
        decided by votes).

        Returns:
            The pose graph's corrections (poses already moved) when ``loop`` replaced an
            earlier loop, else None with the poses unchanged.
        """
        m = self.map
        for old in reversed(self.loops):
            rest = [c for c in self.loops if c is not old]
            saved = {kf.id: kf.t_cw.copy() for kf in m.keyframes}
            ratio = self.config.loop_max_error_ratio
            corrections = optimize_pose_graph(m, [*rest, loop], max_error_ratio=ratio)
            if corrections is None:
                continue
            votes = self._contradictions.setdefault((old.i, old.j), set())
            votes.add(loop.j)
            if len(votes) >= LOOP_CONTRADICTION_VOTES:
                self.loops = rest
                self.rejected.append(old)
                m.keyframes[old.i].loop_edges.discard(old.j)
                m.keyframes[old.j].loop_edges.discard(old.i)
                return corrections
            for kf in m.keyframes:  # not yet: the graph as it was
                kf.t_cw = saved[kf.id]
            return None
        return None

    def _close(self, kf: Keyframe, loop_id: int, loc: Localization) -> bool:
        m = self.map
        if self._before_correction is not None:
            self._before_correction()
        loop_kf = m.keyframes[loop_id]
        t_ij = loop_kf.t_cw @ inverse(loc.t_cw)
        loop = LoopConstraint(loop_id, kf.id, t_ij, loc.covariance)
        corrections = optimize_pose_graph(
            m, [*self.loops, loop], max_error_ratio=self.config.loop_max_error_ratio
        )
        if corrections is None:
            corrections = self._without_contradicted_loop(loop)
        if corrections is None:  # inconsistent with the keyframe chain: a look-alike place
            self.rejected.append(loop)
            return False
        self.loops.append(loop)
        kf.loop_edges.add(loop_id)
        loop_kf.loop_edges.add(kf.id)
        apply_point_corrections(m, corrections)
        for kp, p in zip(loc.keypoints.tolist(), loc.points.tolist(), strict=True):
            existing = int(kf.frame.map_points[kp])
            if m.bad[p]:
                continue
            if existing >= 0 and not m.bad[existing]:
                if existing != p and kf.id not in m.observations[p]:
                    m.replace_point(existing, p)
            elif kf.id not in m.observations[p]:
                m.add_observation(p, kf, kp)
        group_pts = m.local_points([loop_id, *loop_kf.best_covisibles(10)])
        targets = [kf.id, *kf.best_covisibles(10)]
        for t in targets:
            fuse_points(m, self.camera, m.keyframes[t], group_pts, radius=4.0)
        for t in targets:
            m.update_connections(m.keyframes[t])
        if self.config.global_ba_after_loop and self._global_ba is not None:
            self._global_ba()
        self.last_loop_kf = kf.id
        self.detector.reset()
        return True
