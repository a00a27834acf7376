"""The RGB-D SLAM system: tracking, keyframe mapping, loop closing, relocalisation.

One :class:`SlamSystem` per camera. Feed it synchronised rectified images and
depth with :meth:`SlamSystem.track`; it returns the camera pose in the map frame
(``T_wc``) and keeps a keyframe map. Everything runs in the caller's thread in
a fixed order, so the same inputs and seed give the same trajectory.

Per frame: ORB features with depth; the pose predicted by a constant-velocity
model is refined on map points found by projection (falling back to descriptor
matching against the reference keyframe, then to relocalisation against all
keyframes by bag-of-words); then the local map (keyframes sharing points with
the frame and their neighbours) is searched for more matches and the pose refined
again. A keyframe is inserted when tracking weakens or the camera moved enough:
new points from depth, culling, fusion with neighbours, local bundle adjustment,
then loop detection, verification and pose-graph correction.

Frame poses are stored relative to their reference keyframe, so loop closures
and bundle adjustment move the whole trajectory (:meth:`SlamSystem.trajectory`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.clouds import depth_samples
from visnav.slam.config import SlamConfig, TrackingState, TrackResult
from visnav.slam.dense import DenseTracker
from visnav.slam.features import Frame, OrbExtractor
from visnav.slam.geometry import (
    PoseObservations,
    PosePrior,
    inverse,
    optimize_pose,
    orthonormalize,
    pose_information,
    project,
)
from visnav.slam.global_ba import GlobalAdjuster
from visnav.slam.inputs import STAGES, Stopwatch, prepare_inputs, virtual_baseline
from visnav.slam.keyframe_rule import need_keyframe
from visnav.slam.localization_mode import SavedMapAnchor
from visnav.slam.loop_closing import LoopCloser
from visnav.slam.map_file import SavedSlamMap
from visnav.slam.mapping import create_points, cull_recent_points, fuse_points
from visnav.slam.matching import search_by_projection
from visnav.slam.monocular import (
    MonoInitializer,
    create_initial_map,
    mono_ba_window,
    triangulate_new_points,
)
from visnav.slam.odometry_prior import odometry_edges, odometry_prior
from visnav.slam.optimizer import BaResult, bundle_adjustment
from visnav.slam.place_recognition import Localization, localize_in_map
from visnav.slam.restart import RestartAnchor, follow_depth, predict_from_odometry
from visnav.slam.slam_map import Keyframe, SlamMap
from visnav.slam.system_outputs import FrameRecord as _FrameRecord
from visnav.slam.system_outputs import SystemOutputs
from visnav.slam.vocabulary import Vocabulary

__all__ = ["STAGES", "SlamSystem"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class SlamSystem(SystemOutputs):
    """RGB-D SLAM on one rectified camera.

    Args:
        camera: intrinsics of the rectified images.
        config: parameters (:class:`SlamConfig`).
        vocabulary: a pre-trained vocabulary (default: trained on the first keyframes).
        initial_pose: ``T_map_camera`` of the first frame (default identity); with
            ``saved_map``, where to look for the camera in it first.
        saved_map: localise in this map of an earlier run instead of starting a new one
            (:mod:`visnav.slam.localization_mode`): its keyframes are held, loop closing is
            off, and tracking starts lost until the first frame is relocalised in it.
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        config: SlamConfig | None = None,
        *,
        vocabulary: Vocabulary | None = None,
        initial_pose: FloatArray | None = None,
        saved_map: SavedSlamMap | None = None,
    ) -> None:
        self.config = config or SlamConfig()
        cfg = self.config
        self.camera = CameraIntrinsics(
            camera.fx,
            camera.fy,
            camera.cx,
            camera.cy,
            camera.width,
            camera.height,
            virtual_baseline(cfg.depth_noise, camera.fx),
        )
        self.extractor = OrbExtractor(
            n_features=cfg.n_features,
            scale_factor=cfg.scale_factor,
            n_levels=cfg.n_levels,
            fast_threshold=cfg.fast_threshold,
            grid_cell=cfg.grid_cell,
            min_depth=cfg.min_depth,
            max_depth=cfg.max_depth,
        )
        self.map = SlamMap()
        self.saved = None if saved_map is None else SavedMapAnchor(saved_map)
        if self.saved is not None:
            self.map = self.saved.map
        self.dense = DenseTracker.from_config(self.camera, cfg) if cfg.sensor == "rgbd" else None
        self._pose_info: FloatArray | None = None
        self._dense_ref = -1
        self.global_ba = GlobalAdjuster(
            self.map,
            self.camera,
            cfg,
            self.extractor.inv_level_sigma2,
            mono=cfg.sensor == "mono",
            saved=self.saved,
            note=self._note_ba,
        )
        self.loop_closer = LoopCloser(
            self.map,
            self.camera,
            cfg if self.saved is None else replace(cfg, loop_closure=False),
            vocabulary=vocabulary,
            global_ba=lambda: self.global_ba.after_loop(self.n_frames),
            before_correction=self.global_ba.merge_pending,
        )
        self.state: TrackingState = "uninitialized" if self.saved is None else "lost"
        self.initial_pose = np.eye(4) if initial_pose is None else np.asarray(initial_pose, float)
        self.n_frames = 0
        self.n_lost = 0
        self.n_relocalized = 0
        self.n_reinitialized = 0
        self.timings: list[dict[str, float]] = []
        self.ba_runs = 0
        self.ba_failures = 0
        self.ba_last_error = ""
        self._ba_warnings: list[str] = []
        self._records: list[_FrameRecord] = []
        self._last: Frame | None = None
        self._last_rec: _FrameRecord | None = None
        self._velocity: FloatArray | None = None
        self._ref_kf = -1
        self._local_kfs: list[int] = []
        self._local_points: IntArray = np.zeros(0, dtype=np.int64)
        self._last_kf_frame = 0
        self._just_relocalized = False
        self._lost_frames = 0
        self._anchor = RestartAnchor()
        self._odom_last: FloatArray | None = None
        self._odom_pred: FloatArray | None = None
        self._odom_pose_last: FloatArray | None = None
        self._prior: PosePrior | None = None
        self._odom_now: FloatArray | None = None
        self._mono: MonoInitializer | None = None
        if cfg.sensor == "mono":
            self._mono = MonoInitializer(
                self.camera,
                scale=cfg.mono_scale,
                min_parallax_deg=cfg.init_min_parallax_deg,
                min_points=cfg.init_min_points,
                min_depth=cfg.min_depth,
                max_depth=cfg.max_depth,
            )

    # --------------------------------------------------------------- tracking

    def track(
        self,
        image: NDArray[Any],
        depth: NDArray[Any] | None,
        stamp_ns: int,
        *,
        odom_pose: FloatArray | None = None,
    ) -> TrackResult:
        """Process one synchronised RGB-D frame (or one image with ``sensor="mono"``).

        Args:
            image: (H, W) uint8 mono or (H, W, 3) uint8 RGB, rectified.
            depth: (H, W) float32 metres or uint16 (``config.depth_scale`` units per
                metre, default millimetres), registered to ``image``. Monocular: only
                read (for the scale) until the map is initialised; None otherwise.
            stamp_ns: capture time in nanoseconds.
            odom_pose: optional ``T_odom_camera`` from wheel (or other) odometry at
                ``stamp_ns``: predicts the motion and lets tracking restart after a
                loss that relocalisation cannot recover.

        Returns:
            The frame's pose and what happened.

        Raises:
            SlamInputError: image or depth do not fit the camera or each other, or
                the depth scale is implausible.
        """
        sw = Stopwatch()
        sw.start("loop")
        if self.global_ba.merge_due(self.n_frames + 1):  # a loop's background adjustment
            self._follow_map()  # the last frame's pose, as its keyframe moved
        sw.start("features")
        mono, scale = self._mono is not None, self.config.depth_scale
        gray, colour, depth_m, warnings = prepare_inputs(
            image, depth, self.camera, depth_scale=scale, mono=mono
        )
        cv2.setRNGSeed(int(self.config.seed) + self.n_frames)
        frame = self.extractor.extract(gray, None if mono else depth_m, self.camera, int(stamp_ns))
        self.n_frames += 1
        kf_added = loop = reloc = reinit = False
        inliers = 0
        self._odom_pred = predict_from_odometry(odom_pose, self._odom_last)
        # one private copy per frame: keyframes keep it, so a caller reusing its array is safe
        self._odom_now = None if odom_pose is None else np.array(odom_pose, dtype=np.float64)
        self._prior = odometry_prior(self.config, self._odom_pred, odom_pose, self._odom_pose_last)
        if self.state == "uninitialized" and self._mono is not None:
            sw.start("mapping")
            mono_depth = None if depth is None else depth_m
            if self._initialize_mono(frame, mono_depth, odom_pose, warnings):
                self.state = "ok"
                kf_added = True
                inliers = int((frame.map_points >= 0).sum())
        elif self.state == "uninitialized":
            if self._initialize(frame, depth_m, colour):
                self.state = "ok"
                kf_added = True
                inliers = int((frame.map_points >= 0).sum())
            else:
                n_depth = int(np.isfinite(frame.depth).sum())
                warnings.append(
                    f"frame {stamp_ns}: {n_depth} keypoints with depth; need 50 to start the "
                    "map (point the camera at textured surfaces within the depth range)"
                )
        else:
            ok = False
            if self.state == "ok":
                sw.start("matching")
                ok = self._track_motion(frame, sw) or self._track_reference(frame)
            if not ok:
                sw.start("matching")
                self._prior = None  # a relocalised pose owes nothing to the odometry
                ok = self._relocalize(frame, sw)
                reloc = ok and self.state == "lost"
                if ok:
                    self.n_relocalized += int(reloc)
            if ok:
                sw.start("matching")
                inliers = self._track_local_map(frame, sw)
                need = (
                    self.config.reloc_min_inliers
                    if (reloc or self._just_relocalized)
                    else self.config.min_inliers
                )
                ok = inliers >= need
            if ok:
                self.state = "ok"
                self._just_relocalized = reloc
                sw.start("pose")
                self._refine_dense(frame, depth_m)
                since = self.n_frames - self._last_kf_frame
                if need_keyframe(self.config, self.map, frame, inliers, self._ref_kf, since):
                    sw.start("mapping")
                    loop = self._insert_keyframe(frame, depth_m, colour, sw)
                    kf_added = True
            else:
                if self.state != "lost":
                    warnings.append(
                        f"frame {stamp_ns}: tracking lost ({inliers} inliers); relocalising"
                    )
                elif not self.localized:  # localisation mode, not found in the saved map yet
                    warnings.append(
                        f"frame {stamp_ns}: not localised in the saved map after "
                        f"{self._lost_frames + 1} frames ({inliers} inliers); is the camera "
                        "where the map was built?"
                    )
                self.state = "lost"
                self.n_lost += 1
                self._lost_frames += 1
                self._velocity = None
                self._last = None
                followed = follow_depth(
                    self.dense, self.map, self._ref_kf, depth_m, self._odom_pred, odom_pose
                )
                if followed is not None:  # the odometry's prediction corrected on the depth
                    self._odom_pred, self._odom_last = followed
                if (
                    self._odom_pred is not None
                    and self._lost_frames >= self.config.reinit_after_lost
                    and self._reinitialize(frame, depth_m, colour, self._odom_pred)
                ):
                    reinit = True
                    n = self._lost_frames - 1
                    warnings.append(f"frame {stamp_ns}: tracking restarted after {n} lost frames")
                    self.n_reinitialized += 1
        t_wc: FloatArray | None = None
        if self.state == "ok" and frame.t_cw is not None:
            self._record(frame)
            t_wc = inverse(frame.t_cw)
            self._lost_frames = 0
            self._odom_last = None if self._odom_now is None else self._odom_now @ frame.t_cw
            self._odom_pose_last = self._odom_now
        timings = sw.stop()
        self.timings.append(timings)
        if self._ba_warnings:
            warnings.extend(f"frame {stamp_ns}: {w}" for w in self._ba_warnings)
            self._ba_warnings.clear()
        return TrackResult(
            stamp_ns=int(stamp_ns),
            state=self.state,
            t_wc=t_wc,
            inliers=inliers,
            keyframe=kf_added,
            loop=loop,
            relocalized=reloc,
            reinitialized=reinit,
            warnings=tuple(warnings),
            timings=timings,
            cpu_timings=dict(sw.cpu),
        )

    def _initialize(
        self, frame: Frame, depth_m: NDArray[np.float32], colour: NDArray[np.uint8] | None
    ) -> bool:
        if int(np.isfinite(frame.depth).sum()) < 50:
            return False
        frame.t_cw = inverse(self.initial_pose)
        kf = self.map.add_keyframe(frame, frame.t_cw, parent=-1)
        kf.odom_pose = self._odom_now
        create_points(self.map, kf)
        self._store_cloud(kf, depth_m, colour)
        self._ref_kf = kf.id
        self._local_kfs = [kf.id]
        self._local_points = self.map.local_points([kf.id])
        self._last_kf_frame = self.n_frames
        self.loop_closer.add_keyframe(kf)
        return True

    def _initialize_mono(
        self,
        frame: Frame,
        depth_m: NDArray[np.float32] | None,
        odom_pose: FloatArray | None,
        warnings: list[str],
    ) -> bool:
        """Two-view initialisation (monocular); on failure say why in ``warnings``."""
        assert self._mono is not None
        ref = self._mono.ref
        view, why = self._mono.step(frame, depth_m=depth_m, odom_pose=odom_pose)
        if view is None or ref is None:
            warnings.append(f"frame {frame.stamp_ns}: {why}")
            return False
        kf0, kf1 = create_initial_map(
            self.map,
            self.camera,
            ref,
            frame,
            view,
            self._mono.origin(self.initial_pose),
            inv_sigma2_levels=self.extractor.inv_level_sigma2,
            depth_m=self._mono.ref_depth if self.config.mono_scale == "depth" else None,
            min_depth=self.config.min_depth,
            max_depth=self.config.max_depth,
            on_ba=self._note_ba,
        )
        self._records.append(_FrameRecord(ref.stamp_ns, kf0.id, np.eye(4)))
        self._ref_kf = kf1.id
        self._local_kfs = [kf1.id, kf0.id]
        self._local_points = self.map.local_points(self._local_kfs)
        self._last_kf_frame = self.n_frames
        self.loop_closer.add_keyframe(kf0)
        self.loop_closer.add_keyframe(kf1)
        return True

    def _reinitialize(
        self,
        frame: Frame,
        depth_m: NDArray[np.float32],
        colour: NDArray[np.uint8] | None,
        t_cw: FloatArray,
    ) -> bool:
        """Start tracking again from a new keyframe (held: :mod:`visnav.slam.restart`)."""
        if int(np.isfinite(frame.depth).sum()) < 50 or not self.map.keyframes:
            return False
        frame.t_cw = t_cw.copy()
        frame.map_points[:] = -1
        parent = self.map.keyframes[-1].id
        kf = self.map.add_keyframe(frame, frame.t_cw, parent=parent)
        kf.odom_pose = self._odom_now
        create_points(self.map, kf)
        self._store_cloud(kf, depth_m, colour)
        self._ref_kf = kf.id
        self._local_kfs = [kf.id]
        self._local_points = self.map.local_points([kf.id])
        self._last_kf_frame = self.n_frames
        self.state = "ok"
        self._anchor.hold(kf.id)
        self.loop_closer.add_keyframe(kf)
        return True

    def _observations(self, frame: Frame, kp: IntArray, pts: IntArray) -> PoseObservations:
        return PoseObservations(
            self.map.positions[pts], frame.uv[kp], frame.u_right[kp], frame.inv_sigma2[kp]
        )

    def _track_motion(self, frame: Frame, sw: Stopwatch) -> bool:
        """Track on the local map from a predicted pose: odometry's, then constant velocity.

        Wheel odometry slips in tight turns (its heading rate off by several degrees per
        second on the car), so when its prediction finds too few matches the visual
        constant-velocity model is tried before falling back to the reference keyframe.
        """
        if self._last is None or self._last.t_cw is None:
            return False
        velocity = self._velocity if self._velocity is not None else np.eye(4)
        preds = [velocity @ self._last.t_cw]
        if self._odom_pred is not None:
            preds.insert(0, self._odom_pred)
        return any(self._track_from(frame, pred, sw) for pred in preds)

    def _track_from(self, frame: Frame, pred: FloatArray, sw: Stopwatch) -> bool:
        pts = self._local_points[~self.map.bad[self._local_points]]
        xyz, desc, r = self.map.positions[pts], self.map.descriptors[pts], self.config.search_radius
        for radius in (r, 2 * r):  # a wider window when the prediction is off
            mi, ki = search_by_projection(frame, self.camera, pred, xyz, desc, radius=radius)
            if len(mi) >= 20:
                break
        else:
            return False
        sw.start("pose")
        obs = self._observations(frame, ki, pts[mi])
        t_cw, mask = optimize_pose(self.camera, pred, obs, prior=self._prior)
        if int(mask.sum()) < 10:
            return False
        frame.t_cw = t_cw
        frame.map_points[ki[mask]] = pts[mi[mask]]
        return True

    def _apply(self, frame: Frame, loc: Localization) -> None:
        frame.t_cw = loc.t_cw
        frame.map_points[:] = -1
        frame.map_points[loc.keypoints] = loc.points

    def _track_reference(self, frame: Frame) -> bool:
        if self._ref_kf < 0:
            return False
        ref = self.map.keyframes[self._ref_kf]
        loc = localize_in_map(
            frame, self.camera, self.map, [ref.id, *ref.best_covisibles(5)], min_inliers=15
        )
        if loc is None:
            return False
        self._apply(frame, loc)
        return True

    def _relocalize(self, frame: Frame, sw: Stopwatch) -> bool:
        kfs = [kf.id for kf in self.map.keyframes if not kf.bad]
        if not kfs:
            return False
        if self.saved is not None and not self.localized:  # first, where we were told
            near = self.saved.nearby(self.initial_pose)
            self._local_points = self.map.local_points(near)
            if near and self._track_from(frame, inverse(self.initial_pose), sw):
                self._velocity = None
                return True
        if self.saved is not None:  # the saved map's place memory, built when first needed
            self.loop_closer.index_map()
        candidates = self.loop_closer.place_candidates(frame.descriptors, 5) or kfs[::-1][:5]
        for k in candidates:
            group = [k, *self.map.keyframes[k].best_covisibles(5)]
            loc = localize_in_map(
                frame, self.camera, self.map, group, min_inliers=self.config.reloc_min_inliers
            )
            if loc is not None:
                self._apply(frame, loc)
                self._velocity = None
                return True
        return False

    def _update_local_map(self, frame: Frame) -> None:
        votes: dict[int, int] = {}
        obs = self.map.observations
        for p in frame.map_points[frame.map_points >= 0].tolist():
            for k in obs[p]:
                votes[k] = votes.get(k, 0) + 1
        if not votes:
            return
        ranked = sorted(votes.items(), key=lambda kv: (-kv[1], kv[0]))
        cap = self.config.local_keyframes
        local = [k for k, _ in ranked[:cap]]
        chosen = set(local)
        for k in list(local):
            if len(local) >= cap + 8:
                break
            kf = self.map.keyframes[k]
            for n in [*kf.best_covisibles(4), kf.parent]:
                if n >= 0 and n not in chosen:
                    chosen.add(n)
                    local.append(n)
        if self.saved is not None and frame.t_cw is not None:  # the saved map in view
            local += [k for k in self.saved.nearby(inverse(frame.t_cw)) if k not in chosen]
        self._ref_kf = ranked[0][0]
        self._local_kfs = local
        self._local_points = self.map.local_points(local)

    def _track_local_map(self, frame: Frame, sw: Stopwatch) -> int:
        assert frame.t_cw is not None
        self._update_local_map(frame)
        pts = self._local_points
        uv, z = project(self.camera, frame.t_cw, self.map.positions[pts])
        cam = self.camera
        inside = (
            (z > 0.05)
            & (uv[:, 0] >= 0)
            & (uv[:, 0] < cam.width)
            & (uv[:, 1] >= 0)
            & (uv[:, 1] < cam.height)
        )
        self.map.visible[pts[inside]] += 1
        matched = frame.map_points >= 0
        cand = pts[inside & ~np.isin(pts, frame.map_points[matched])]
        mi, ki = search_by_projection(
            frame,
            cam,
            frame.t_cw,
            self.map.positions[cand],
            self.map.descriptors[cand],
            radius=self.config.local_radius,
            available=~matched,
        )
        frame.map_points[ki] = cand[mi]
        sw.start("pose")
        kp = np.flatnonzero(frame.map_points >= 0)
        mp = frame.map_points[kp]
        obs = self._observations(frame, kp, mp)
        t_cw, mask = optimize_pose(cam, frame.t_cw, obs, prior=self._prior)
        frame.t_cw = t_cw
        if self.dense is not None:
            self._pose_info = pose_information(cam, t_cw, obs, mask)
            if self._prior is not None:
                self._pose_info = self._pose_info + self._prior.information
        frame.map_points[kp[~mask]] = -1
        self.map.found[mp[mask]] += 1
        return int(mask.sum())

    def _refine_dense(self, frame: Frame, depth_m: NDArray[np.float32]) -> None:
        """ICP refinement of the tracked pose on the depth (:mod:`visnav.slam.dense`)."""
        self._dense_ref = -1
        if self.dense is None or frame.t_cw is None:
            return
        ref = self._ref_kf if self.dense.has(self._ref_kf) else self.map.keyframes[-1].id
        t_rw, prior = self.map.keyframes[ref].t_cw, self._pose_info
        res = self.dense.refine(ref, t_rw, depth_m, frame.t_cw, prior)
        if res.ok:
            frame.t_cw, self._dense_ref = res.t_cw, ref

    # -------------------------------------------------------------- keyframes

    def _store_cloud(
        self, kf: Keyframe, depth_m: NDArray[np.float32], colour: NDArray[np.uint8] | None
    ) -> None:
        if self.dense is not None:
            self.dense.add_keyframe(kf.id, depth_m)
        if self._mono is not None:  # monocular: no dense cloud (depth is for the scale only)
            return
        kf.cloud = depth_samples(
            depth_m,
            colour,
            self.camera,
            stride=self.config.dense_stride,
            max_depth=self.config.max_depth,
        )

    def _insert_keyframe(
        self,
        frame: Frame,
        depth_m: NDArray[np.float32],
        colour: NDArray[np.uint8] | None,
        sw: Stopwatch,
    ) -> bool:
        assert frame.t_cw is not None
        cfg = self.config
        m = self.map
        kf = m.add_keyframe(frame, frame.t_cw, parent=self._ref_kf)
        kf.odom_pose = self._odom_now
        kp, pts = np.flatnonzero(frame.map_points >= 0), frame.map_points[frame.map_points >= 0]
        for p, k in zip(pts.tolist(), kp.tolist(), strict=True):
            m.observations[p][kf.id] = k
        if cfg.far_point_limit is None:
            create_points(m, kf)
        else:
            create_points(m, kf, close_depth=cfg.close_depth, min_points=cfg.far_point_limit)
        self._store_cloud(kf, depth_m, colour)
        m.update_connections(kf)
        if self._mono is not None:
            triangulate_new_points(
                m,
                self.camera,
                kf,
                kf.best_covisibles(cfg.triangulation_neighbours),
                scale_factor=cfg.scale_factor,
                scales=self.extractor.scales,
            )
            m.update_connections(kf)
        cull_recent_points(m, kf.id)
        neighbours = kf.best_covisibles(cfg.fuse_neighbours)
        _, cur_pts = m.keyframe_points(kf)
        for n in neighbours:
            fuse_points(m, self.camera, m.keyframes[n], cur_pts)
        fuse_points(m, self.camera, kf, m.local_points(neighbours))
        _, cur_pts = m.keyframe_points(kf)
        m.update_point_descriptors(cur_pts)
        m.update_point_normals(cur_pts)
        m.update_connections(kf)
        for n in neighbours:
            m.update_connections(m.keyframes[n])
        if cfg.local_ba and len(m.keyframes) >= 2:
            window = [kf.id, *kf.best_covisibles(cfg.local_window - 1)]
            window = self._anchor.window(m, kf, window)
            if self.saved is not None:  # the saved keyframes are held
                window = self.saved.new_only(window)
            if self._mono is not None:
                window = mono_ba_window(window)
            self._note_ba(
                bundle_adjustment(
                    m,
                    self.camera,
                    window,
                    inv_sigma2_levels=self.extractor.inv_level_sigma2,
                    iterations=cfg.ba_iterations,
                    odometry=odometry_edges(cfg, m, window),
                )
            )
        self._last_kf_frame = self.n_frames
        self._ref_kf = kf.id
        self._local_kfs = [kf.id, *kf.best_covisibles(cfg.local_keyframes)]
        self._local_points = m.local_points(self._local_kfs)
        sw.start("loop")
        closed = self.loop_closer.add_keyframe(kf)
        if closed:  # the loop region joined the local map
            self._local_kfs = [kf.id, *kf.best_covisibles(cfg.local_keyframes)]
            self._local_points = m.local_points(self._local_kfs)
        frame.t_cw = kf.t_cw.copy()  # bundle adjustment / loop correction moved the keyframe
        return closed

    def _note_ba(self, result: BaResult) -> None:
        """Count a bundle adjustment; a solver failure becomes a warning of this frame."""
        self.ba_runs += 1
        if not result.ok:
            self.ba_failures += 1
            self.ba_last_error = result.error
            self._ba_warnings.append(f"{result.error} (the map keeps its previous poses)")

    def global_bundle_adjustment(self, iterations: int | None = None) -> BaResult | None:
        """Optimise every keyframe pose (but the first) and map point together, now.

        Returns:
            The adjustment's result (also counted in ``ba_runs`` / ``ba_failures``), or
            None with fewer than two keyframes.
        """
        return self.global_ba.run(iterations)

    def _follow_map(self) -> None:
        if self._last is not None and self._last_rec is not None:
            self._last.t_cw = (
                self._last_rec.t_c_ref @ self.map.keyframes[self._last_rec.ref_kf].t_cw
            )
            if self._odom_pose_last is not None:
                self._odom_last = self._odom_pose_last @ self._last.t_cw

    # ----------------------------------------------------------------- output

    def _record(self, frame: Frame) -> None:
        assert frame.t_cw is not None
        ref = self.map.keyframes[self._dense_ref if self._dense_ref >= 0 else self._ref_kf]
        rec = _FrameRecord(frame.stamp_ns, ref.id, frame.t_cw @ ref.t_wc)
        if self._last is not None and self._last.t_cw is not None and self._last_rec is not None:
            last_t_cw = self._last_rec.t_c_ref @ self.map.keyframes[self._last_rec.ref_kf].t_cw
            self._velocity = orthonormalize(frame.t_cw @ inverse(last_t_cw))
        self._records.append(rec)
        self._last = frame
        self._last_rec = rec

    def finish(self) -> None:
        """End of a run: the final global bundle adjustment if configured; helper stopped."""
        if self.config.final_global_ba:
            self.global_bundle_adjustment()
        self.global_ba.close()
