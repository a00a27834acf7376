"""Offline SLAM runs on a TUM RGB-D folder or a bag, writing TUM trajectories.

* :func:`slam_tum`: every associated colour/depth pair of a TUM folder, in stamp
  order; the estimate is written as a TUM file and, when the folder has a
  ``groundtruth.txt``, evaluated (ATE with alignment, RPE per frame).
* :func:`slam_bag`: colour, depth and camera_info topics of a bag (any format
  :mod:`visnav.bag` reads), paired with roscpp's ApproximateTime policy; with a
  ground-truth odometry topic the map frame is anchored at the ground truth's
  first camera pose and the result evaluated. With ``/tf_static`` holding the
  camera's mounting, the written trajectory is of the base frame (as
  ``ground_truth/odom``), else of the camera.

Both run every frame in order in the calling thread: the same input and seed
give the same trajectory.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.bag import BagReader
from visnav.bag.image_compression import decode_image, image_topics
from visnav.message_filters import ApproximateTime
from visnav.msgs.image import image_to_numpy
from visnav.msgs.time import time_to_ns
from visnav.outpaths import check_output_file
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig
from visnav.slam.errors import SlamError, SlamInputError
from visnav.slam.evaluation import ErrorStats, ate, rpe
from visnav.slam.system import STAGES, SlamSystem
from visnav.slam.trajectory import Trajectory, read_tum, write_tum
from visnav.slam.tum import TUM_DEPTH_SCALE, TumSequence
from visnav.slam.vocabulary import Vocabulary
from visnav.tf import Buffer, TransformException, pose_to_matrix

__all__ = ["SlamRun", "slam_bag", "slam_tum"]

FloatArray = NDArray[np.float64]
_LOG = logging.getLogger(__name__)


@dataclass
class SlamRun:
    """The result of an offline run.

    Attributes:
        trajectory: estimated poses of all tracked frames.
        keyframes: keyframe poses.
        frames: frames given to SLAM.
        tracked: frames with a pose.
        lost: frames where tracking failed.
        relocalized: recoveries from loss by relocalisation.
        reinitialized: restarts at the odometry pose after a loss.
        loops: loops closed.
        output: the TUM file written (if any).
        groundtruth: the reference trajectory (if any).
        ate: absolute trajectory error (Umeyama-aligned) against it.
        rpe: relative pose error (1 frame) against it.
        timings: median seconds per stage over all frames.
        warnings: distinct warnings raised by the inputs.
        system: the SLAM system (map, clouds).
    """

    trajectory: Trajectory
    keyframes: Trajectory
    frames: int
    tracked: int
    lost: int
    relocalized: int
    loops: int
    reinitialized: int = 0
    output: Path | None = None
    groundtruth: Trajectory | None = None
    ate: ErrorStats | None = None
    rpe: ErrorStats | None = None
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    system: SlamSystem | None = None

    def summary(self) -> str:
        """Human-readable report."""
        lines = [
            f"frames {self.frames}, tracked {self.tracked}, lost {self.lost}, "
            f"relocalised {self.relocalized}, restarted {self.reinitialized}, "
            f"keyframes {len(self.keyframes)}, loops {self.loops}",
        ]
        if self.timings:
            per = ", ".join(f"{k} {v * 1e3:.1f}" for k, v in self.timings.items())
            lines.append(f"median ms per frame: {per}")
        if self.ate is not None:
            lines.append(f"ATE (aligned) rmse {self.ate.rmse:.4f} m, max {self.ate.max:.4f} m")
        if self.rpe is not None:
            lines.append(f"RPE (1 frame) rmse {self.rpe.rmse:.4f} m")
        if self.output is not None:
            lines.append(f"trajectory written to {self.output}")
        return "\n".join(lines)


class _Collector:
    def __init__(self, system: SlamSystem, log: logging.Logger) -> None:
        self.system = system
        self.log = log
        self.seen: set[str] = set()
        self.warnings: list[str] = []
        self.frames = 0

    def track(
        self,
        image: NDArray[Any],
        depth: NDArray[Any] | None,
        stamp_ns: int,
        *,
        odom_pose: FloatArray | None = None,
    ) -> None:
        self.frames += 1
        result = self.system.track(image, depth, stamp_ns, odom_pose=odom_pose)
        for w in result.warnings:
            key = w.split(":", 1)[-1] if w.startswith("frame ") else w
            if key not in self.seen:
                self.seen.add(key)
                self.warnings.append(w)
                self.log.warning("%s", w)

    def finish(
        self,
        output: Path | None,
        groundtruth: Trajectory | None,
        *,
        body_from_camera: FloatArray | None = None,
        anchor: bool = False,
    ) -> SlamRun:
        s = self.system
        s.finish()
        traj = s.trajectory()
        kfs = s.keyframe_trajectory()
        if body_from_camera is not None and len(traj):
            t_cb = np.linalg.inv(body_from_camera)
            traj = Trajectory.from_matrices(traj.stamps, traj.matrices() @ t_cb)
            kfs = Trajectory.from_matrices(kfs.stamps, kfs.matrices() @ t_cb)
        if anchor and groundtruth is not None and len(traj):
            # the map frame was not started at the ground truth: move it there now
            start = _initial_pose(groundtruth, float(traj.stamps[0]), 0.05)
            if start is not None:
                fix = start @ np.linalg.inv(traj.matrices()[0])
                traj = Trajectory.from_matrices(traj.stamps, fix @ traj.matrices())
                kfs = Trajectory.from_matrices(kfs.stamps, fix @ kfs.matrices())
        written = None
        if output is not None:
            written = write_tum(output, traj, header="visnav slam: timestamp tx ty tz qx qy qz qw")
        run = SlamRun(
            trajectory=traj,
            keyframes=kfs,
            frames=self.frames,
            tracked=len(traj),
            lost=s.n_lost,
            relocalized=s.n_relocalized,
            loops=len(s.loops),
            reinitialized=s.n_reinitialized,
            output=written,
            groundtruth=groundtruth,
            timings={k: float(np.median([t[k] for t in s.timings])) for k in STAGES}
            if s.timings
            else {},
            warnings=self.warnings,
            system=s,
        )
        if groundtruth is not None and len(traj) >= 3:
            try:
                run.ate = ate(traj, groundtruth, align=True)
                run.rpe = rpe(traj, groundtruth)
            except SlamError as exc:
                run.warnings.append(f"evaluation skipped: {exc}")
                self.log.warning("evaluation skipped: %s", exc)
        return run


def _vocabulary(vocabulary: Vocabulary | str | Path | None) -> Vocabulary | None:
    if vocabulary is None or isinstance(vocabulary, Vocabulary):
        return vocabulary
    return Vocabulary.load(vocabulary)


def slam_tum(
    folder: str | Path,
    *,
    output: str | Path | None = None,
    camera: CameraIntrinsics | None = None,
    config: SlamConfig | None = None,
    vocabulary: Vocabulary | str | Path | None = None,
    depth_scale: float = TUM_DEPTH_SCALE,
    max_difference: float = 0.02,
    max_frames: int | None = None,
    logger: logging.Logger | None = None,
) -> SlamRun:
    """Run RGB-D SLAM on a TUM RGB-D folder.

    Args:
        folder: the sequence (``rgb.txt``, ``depth.txt``, images, optional
            ``groundtruth.txt`` and ``camera_info.yaml``).
        output: TUM file for the estimate (default ``<folder>/visnav_slam.txt``;
            ``""`` writes nothing).
        camera: intrinsics (default: the folder's ``camera_info.yaml``).
        config: SLAM parameters; its ``depth_scale`` is replaced by ``depth_scale``.
        vocabulary: a :class:`Vocabulary` or a saved ``.npz`` (default: trained on the fly).
        depth_scale: depth PNG units per metre (TUM: 5000).
        max_difference: colour/depth association tolerance (s).
        max_frames: stop after this many frames.
        logger: receives warnings (default this module's logger).

    Returns:
        The run: trajectory, counts, evaluation against ground truth if present.

    Raises:
        SlamInputError: empty or malformed folder, no intrinsics, bad images.
        AssociationError: colour and depth stamps do not pair.
    """
    log = logger or _LOG
    seq = TumSequence(folder, max_difference=max_difference, logger=log)
    out = seq.folder / "visnav_slam.txt" if output is None else (Path(output) if output else None)
    if out is not None:
        check_output_file(out, what="the trajectory", error=SlamInputError)
    cam = camera or seq.find_intrinsics()
    if cam is None:
        text = (
            f"TUM folder {seq.folder} has no camera_info.yaml: pass the intrinsics "
            "(visnav slam --intrinsics FX,FY,CX,CY, or --camera-info FILE); the TUM "
            "freiburg1 camera is 517.3,516.5,318.6,255.3 (its images are not rectified)"
        )
        raise SlamInputError(text)
    cfg = config or SlamConfig()
    cfg = dataclasses.replace(cfg, depth_scale=depth_scale)
    gt_path = seq.groundtruth_path
    groundtruth = read_tum(gt_path) if gt_path is not None else None
    mono_odom = cfg.sensor == "mono" and cfg.mono_scale == "odometry"
    if mono_odom and groundtruth is None:
        text = (
            f"monocular SLAM with scale from odometry needs poses: TUM folder {seq.folder} has "
            "no groundtruth.txt (used as the odometry of the initial frames); use "
            "--scale depth (depth.txt) instead"
        )
        raise SlamInputError(text)
    initial = (
        _initial_pose(groundtruth, seq.frames[0].stamp, max_difference) if groundtruth else None
    )
    system = SlamSystem(cam, cfg, vocabulary=_vocabulary(vocabulary), initial_pose=initial)
    collector = _Collector(system, log)
    for n, (frame, rgb, depth) in enumerate(seq.images()):
        if max_frames is not None and n >= max_frames:
            break
        odom = None
        if mono_odom and groundtruth is not None and system.state == "uninitialized":
            # ground truth stands in for odometry at initialisation only (scale); tracking
            # stays visual so the evaluation against it stays honest
            odom = _initial_pose(groundtruth, frame.stamp, max_difference)
            if odom is None:
                continue
        image_depth = None if mono_odom else depth
        collector.track(rgb, image_depth, round(frame.stamp * 1e9), odom_pose=odom)
    return collector.finish(out, groundtruth)


def _initial_pose(gt: Trajectory, stamp: float, max_difference: float) -> FloatArray | None:
    """The ground-truth pose at ``stamp`` (nearest within ``max_difference``), if any."""
    i = int(np.argmin(np.abs(gt.stamps - stamp)))
    if abs(gt.stamps[i] - stamp) > max_difference:
        return None
    pose: FloatArray = gt.matrices()[i]
    return pose


def slam_bag(
    path: str | Path,
    *,
    image_topic: str = "/depth_camera/image_raw",
    depth_topic: str = "/depth_camera/depth/image_raw",
    info_topic: str = "/depth_camera/camera_info",
    groundtruth_topic: str | None = "/ground_truth/odom",
    base_frame: str | None = None,
    odom_frame: str | None = "odom",
    output: str | Path | None = None,
    config: SlamConfig | None = None,
    vocabulary: Vocabulary | str | Path | None = None,
    max_frames: int | None = None,
    logger: logging.Logger | None = None,
) -> SlamRun:
    """Run RGB-D SLAM on the image, depth and camera_info topics of a bag.

    Images recorded through image_transport's compressed transports are read as an
    image_transport subscriber does: when ``image_topic`` (``depth_topic``) is not in the
    bag but ``<topic>/compressed`` (``<topic>/compressedDepth``) is, that topic is read
    and decoded (what ``visnav run --record-images`` stores); a transport topic may also
    be named directly.

    Args:
        path: the bag.
        image_topic: rectified colour or mono images.
        depth_topic: depth registered to the images (32FC1 m or 16UC1 mm).
        info_topic: the images' camera_info (the newest one is used per frame).
        groundtruth_topic: ``nav_msgs/Odometry`` ground truth (None or missing: no
            evaluation).
        base_frame: the robot frame the trajectory is written for (default: the
            ground truth's ``child_frame_id``, else ``base_link``), when
            ``/tf_static`` gives the camera's pose in it.
        odom_frame: the odometry frame in ``/tf``; its motion predicts the camera
            motion and restarts tracking after a loss (None: not used).
        output: TUM file for the estimate (default ``<bag>.slam.txt``; ``""`` none).
        config: SLAM parameters.
        vocabulary: a :class:`Vocabulary` or a saved ``.npz``.
        max_frames: stop after this many frames.
        logger: receives warnings.

    Raises:
        SlamInputError: a topic is missing or no frame could be formed.
    """
    log = logger or _LOG
    bag = Path(path)
    out = (
        bag.with_name(bag.name + ".slam.txt")
        if output is None
        else (Path(output) if output else None)
    )
    if out is not None:
        check_output_file(out, what="the trajectory", error=SlamInputError)
    cfg = config or SlamConfig()
    mono_odom = cfg.sensor == "mono" and cfg.mono_scale == "odometry"
    with BagReader(bag) as reader:
        topics = reader.topics
        if mono_odom and (not odom_frame or "/tf" not in topics):
            text = (
                f"monocular SLAM with scale from odometry needs the {odom_frame or 'odom'} -> "
                f"camera transform in /tf; bag {bag} has no /tf (or no odom_frame was given): "
                "use scale from depth"
            )
            raise SlamInputError(text)
        stored = image_topics((n, m.type_name) for n, m in topics.items())
        image_topic = stored.get(image_topic, image_topic)
        depth_topic = stored.get(depth_topic, depth_topic)
        for name, what in (
            (image_topic, "image"),
            (depth_topic, "depth"),
            (info_topic, "camera_info"),
        ):
            if name not in topics:
                text = (
                    f"bag {bag} has no {what} topic {name!r}; its topics: "
                    f"{', '.join(sorted(topics)) or 'none'}"
                )
                raise SlamInputError(text)
        gt_topic = groundtruth_topic if groundtruth_topic in topics else None
        wanted = [image_topic, depth_topic, info_topic]
        wanted += [t for t in ("/tf_static", "/tf") if t in topics]
        wanted += [gt_topic] if gt_topic else []
        state: dict[str, Any] = {
            "anchored": False,
            "info": None,
            "system": None,
            "collector": None,
            "camera_frame": "",
        }
        tf = Buffer(cache_time=1e9)
        gt_rows: list[tuple[float, FloatArray]] = []
        pending: list[tuple[Any, Any]] = []

        sync = ApproximateTime(None, 10, num_inputs=2)
        sync.register_callback(lambda img, dep: pending.append((img, dep)))
        for message in reader.messages(wanted):
            topic, msg = message.topic, message.msg
            if topic == "/tf_static":
                for t in msg.transforms:
                    tf.set_transform_static(t, "bag")
            elif topic == "/tf":
                for t in msg.transforms:
                    tf.set_transform(t, "bag")
            elif topic == gt_topic:
                gt_rows.append((time_to_ns(msg.header.stamp) * 1e-9, _odom_matrix(msg)))
                if base_frame is None:
                    base_frame = str(msg.child_frame_id) or "base_link"
            elif topic == info_topic:
                state["info"] = msg
            elif topic in (image_topic, depth_topic):
                try:
                    frame = decode_image(msg)
                except ValueError as exc:  # one undecodable compressed frame: skip it
                    log.warning("%s: skipped a frame: %s", topic, exc)
                    continue
                sync.add(0 if topic == image_topic else 1, frame)
            while pending:
                img, dep = pending.pop(0)
                if state["info"] is None:
                    continue
                if state["system"] is None:
                    cam, warns = CameraIntrinsics.from_camera_info(state["info"], source=info_topic)
                    for w in warns:
                        log.warning("%s", w)
                    state["camera_frame"] = str(img.header.frame_id)
                    initial = None
                    base_frame = base_frame or "base_link"
                    if gt_rows:
                        initial = _camera_start(
                            tf, gt_rows[-1][1], base_frame, state["camera_frame"]
                        )
                    system = SlamSystem(
                        cam,
                        cfg,
                        vocabulary=_vocabulary(vocabulary),
                        initial_pose=initial,
                    )
                    state["system"] = system
                    state["anchored"] = initial is not None
                    state["collector"] = _Collector(system, log)
                collector: _Collector = state["collector"]
                if max_frames is not None and collector.frames >= max_frames:
                    continue
                stamp = time_to_ns(img.header.stamp)
                odom = _odom_pose(tf, odom_frame, state["camera_frame"], stamp)
                if mono_odom and odom is None and collector.system.state == "uninitialized":
                    continue  # the odometry TF is not there yet: it scales the initial map
                depth_arr = None if mono_odom else image_to_numpy(dep)
                collector.track(image_to_numpy(img), depth_arr, stamp, odom_pose=odom)
    collector_final: _Collector | None = state["collector"]
    if collector_final is None:
        text = (
            f"bag {bag}: no synchronised frame of {image_topic} + {depth_topic} with a "
            f"camera_info on {info_topic}"
        )
        raise SlamInputError(text)
    body_from_camera = None
    base_frame = base_frame or "base_link"
    try:
        body_from_camera = tf.lookup_transform_matrix(base_frame, state["camera_frame"])
    except TransformException:
        log.warning(
            "no /tf_static from %s to %s in the bag: the trajectory is of the camera",
            base_frame,
            state["camera_frame"],
        )
    groundtruth = None
    if gt_rows:
        groundtruth = Trajectory.from_matrices(
            [r[0] for r in gt_rows], np.stack([r[1] for r in gt_rows])
        )
    return collector_final.finish(
        out, groundtruth, body_from_camera=body_from_camera, anchor=not state["anchored"]
    )


def _odom_pose(tf: Buffer, odom: str | None, camera: str, stamp_ns: int) -> FloatArray | None:
    """``T_odom_camera`` at ``stamp_ns`` (or the newest), None without odometry in TF."""
    if not odom:
        return None
    for t in (stamp_ns, 0):
        try:
            return tf.lookup_transform_matrix(odom, camera, t)
        except TransformException:
            continue
    return None


def _odom_matrix(msg: Any) -> FloatArray:
    return pose_to_matrix(msg.pose.pose)


def _camera_start(tf: Any, t_world_base: FloatArray, base: str, camera: str) -> FloatArray | None:
    try:
        t_base_cam = tf.lookup_transform_matrix(base, camera)
    except TransformException:
        return None
    out: FloatArray = t_world_base @ t_base_cam
    return out
