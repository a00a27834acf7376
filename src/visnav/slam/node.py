"""The SLAM graph node: synchronised RGB-D in, map -> odom, pose, path and clouds out.

Topics (relative, rtabmap's names):

* in: ``rgb/image`` (rectified mono8 / rgb8 / bgr8), ``depth/image`` (32FC1 m or
  16UC1 mm, registered), ``rgb/camera_info``, paired by ApproximateTime (or exact
  stamps with ``approx_sync: false``); ``slam/dense_cloud_request``
  (``std_msgs/Empty``) asks for a dense cloud;
* out: ``/tf`` ``map -> odom`` (so ``odom -> base_link`` from odometry stays
  continuous, as ROS localisation does), ``slam/pose`` (``PoseStamped`` of the
  base frame in the map), ``slam/path`` (``nav_msgs/Path``, rebuilt after a loop
  closure; the whole path, so at most every ``path_publish_period`` s of stamps (1.0,
  rtabmap's detection rate; 0: every frame) and after each loop), ``slam/map_points``
  (sparse map, every ``map_cloud_period`` s) and
  ``slam/dense_cloud`` (voxelised ``dense_voxel`` m, on request or every
  ``dense_cloud_period`` s when > 0).

The map frame starts equal to ``odom``: the first camera pose in the map is
``T_odom_base(t0) T_base_camera``, both looked up in TF. With ``odom_frame: ""``
the node publishes ``map -> base_frame`` itself. Parameters: ``map_frame``,
``odom_frame``, ``base_frame``, ``publish_tf``, ``transform_tolerance`` (s the
map -> odom stamp is post-dated, as amcl), ``tf_publish_period``, ``queue_size``,
``approx_sync``, ``depth_scale`` (16UC1 units per metre), ``n_features``,
``seed``, ``loop_closure``, ``local_ba``, ``icp_refinement`` (dense ICP refinement of
each pose, :mod:`visnav.slam.dense`), ``depth_noise`` (``sigma_z / z^2`` of the depth;
about 0.002 for a Kinect-like sensor), ``vocabulary`` (a saved ``.npz``),
``max_frame_rate`` (Hz; 0: every frame), ``odometry_prior``, ``odometry_wait`` (s of
clock time a frame waits for ``odom -> base`` at its own stamp, 0.1; after it the newest
transform is used and counted in ``odometry_fallbacks``), ``sensor`` (``rgbd`` or
``mono``) and ``mono_scale`` (``depth``: the depth image scales the monocular map at
initialisation; ``odometry``: TF ``odom -> base`` does, and ``depth/image`` is not
subscribed).

``max_frame_rate`` processes a frame only when its stamp is at least ``1 /
max_frame_rate`` after the last processed one (rtabmap's ``Rtabmap/DetectionRate``
and ORB-SLAM's frame skipping serve the same purpose): the choice depends on the
stamps alone, never on the wall clock, so a run stays deterministic. With
``odometry_prior`` (default) the ``odom -> base_frame`` motion predicts the camera
motion, holds the tracked pose and the local bundle adjustment's keyframes as a
Gaussian prior (standard deviations ``odometry_sigma_t`` m + ``odometry_sigma_t_rel``
per metre moved, ``odometry_sigma_r_deg`` + ``odometry_sigma_r_rel`` per radian
turned + ``odometry_sigma_r_per_m`` rad per metre moved;
:mod:`visnav.slam.odometry_prior`) and restarts tracking after a loss; without it
tracking is purely visual (constant-velocity model) and odometry only anchors the
map frame at the first frame.

SLAM in the loop (``publish_tf``): ``map -> odom`` is refreshed from tracked frames only.
While tracking is lost it is not republished, so its stamp ages and a navigation stack
that checks its robot pose's age (move_base's costmaps, ``transform_tolerance``) stops
the robot until SLAM relocalises (each loss and recovery is logged). ``set_initial_pose``
with ``initial_pose.x`` / ``.y`` / ``.yaw`` (nav2 AMCL's names) puts ``base_frame`` at
that pose of the map at the first frame (default: the map starts equal to ``odom``).
``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``) carries the counters every
``diagnostic_period`` s (1.0; 0: only on loss and recovery). ``database_path`` (rtabmap's
name; '' = none): when the node is destroyed the map is written there (.npz) with its points
beside it (.ply; :mod:`visnav.slam.map_file`); a killed node saves nothing. With
``localization`` (rtabmap's localization mode) the map at ``database_path`` is read
instead, SLAM localises in it (:mod:`visnav.slam.localization_mode`; ``initial_pose.*``
is where it looks first, then bag-of-words relocalisation) and nothing is written; until
the first frame is found in it, ``map -> odom`` is not published.

Where the system runs (:mod:`visnav.slam.worker`): ``worker`` ``inline`` (the node's
thread) or ``process`` (a process of its own, another core). ``result_latency`` (s of
stamp time, default 0) applies the result of the frame stamped ``t`` at clock time ``t +
result_latency`` exactly, waiting for it if the worker is not done: a fixed delay, not
"whatever is finished", so a run gives the same trajectory whatever the wall-clock speed
or the worker (a one-frame latency is what the process worker needs to overlap with a
lock-step simulator). With 0 the result is applied in the frame's callback.
``global_ba_delay`` (frames, default 0) moves the global bundle adjustment after a loop
off the tracking path, into a helper process, merged that many frames later
(:mod:`visnav.slam.background_ba`; deterministic too).

Inputs that cannot be used (a camera_info that changes or disagrees with the
image, an implausible depth scale) are logged (each kind at most once per 5 s, through
the logger's ``throttle_duration_sec``) and the frame dropped; a SLAM scale that
disagrees with wheel odometry by 5x or more is reported as a likely depth unit error.

Services (rtabmap's names, in the node's namespace: ``/slam/reset``, ...;
:mod:`visnav.slam.node_services`): ``~/reset``, ``~/pause``, ``~/resume``
(``std_srvs/srv/Empty``) and ``~/save_map`` (``std_srvs/srv/Trigger``: the map to
``database_path`` now).
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from visnav import message_filters
from visnav.errors import VisnavError
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params
from visnav.msgs.image import image_to_numpy
from visnav.msgs.pointcloud import xyz_to_cloud
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import (
    CameraInfo,
    Header,
    Image,
    Path,
    PointCloud2,
    PoseStamped,
    TransformStamped,
)
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig, TrackResult
from visnav.slam.errors import SlamInputError
from visnav.slam.geometry import inverse, level_pose
from visnav.slam.map_file import check_database_path, check_saved_map_path
from visnav.slam.node_diagnostics import LOCALIZE_FRAMES, SlamDiagnostics
from visnav.slam.node_params import SlamParams
from visnav.slam.node_services import SlamServices
from visnav.slam.system import SlamSystem
from visnav.slam.trajectory import Trajectory
from visnav.slam.worker import (
    WORKERS,
    InlineWorker,
    SlamStats,
    SlamWorker,
    SlamWorkerError,
    make_worker,
    save_at_shutdown,
)
from visnav.tf import (
    Buffer,
    TransformException,
    matrix_to_pose,
    matrix_to_transform,
    transform_to_matrix,
)
from visnav.tf.initial_pose import InitialPoseParams
from visnav.tf.ros import TransformBroadcaster, TransformListener

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["SlamNode", "SlamParams"]

FloatArray = NDArray[np.float64]

_COLOUR = {"rgb8": None, "bgr8": "swap", "rgba8": "drop", "bgra8": "swapdrop"}
_LOG_PERIOD_S = 5.0  # a repeated warning or error is logged at most once per 5 s


def _image_array(msg: Image) -> NDArray[Any]:
    arr = image_to_numpy(msg)
    enc = msg.encoding
    if enc in ("mono8", "8UC1"):
        return arr
    if enc in _COLOUR:
        rgb = arr[:, :, :3]
        return np.ascontiguousarray(rgb[:, :, ::-1] if "swap" in (_COLOUR[enc] or "") else rgb)
    text = (
        f"image encoding {enc!r} unsupported: SLAM takes rectified mono8, rgb8, bgr8, rgba8 "
        "or bgra8 (debayer and rectify with image_proc first)"
    )
    raise SlamInputError(text)


class SlamNode(Node):
    """RGB-D SLAM on a camera stream (see the module docstring for topics and parameters).

    Args:
        name: node name (default ``slam``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace, ...).
    """

    def __init__(self, name: str = "slam", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        prm = declare_params(self, SlamParams)
        self.params = prm
        self.map_frame = prm.map_frame
        self.odom_frame = prm.odom_frame
        self.base_frame = prm.base_frame
        self.publish_tf = prm.publish_tf
        self.transform_tolerance = prm.transform_tolerance
        tf_period = prm.tf_publish_period
        queue = prm.queue_size
        approx = prm.approx_sync
        depth_scale = prm.depth_scale
        map_period = prm.map_cloud_period
        self._path_period_ns = round(1e9 * max(0.0, prm.path_publish_period))
        self._path_sent_ns: int | None = None
        dense_period = prm.dense_cloud_period
        self.dense_voxel = prm.dense_voxel
        self.vocabulary_path = prm.vocabulary
        self.worker_kind = prm.worker
        if self.worker_kind not in WORKERS:
            text = f"worker {self.worker_kind!r}: expected one of {', '.join(WORKERS)}"
            raise SlamInputError(text)
        latency = prm.result_latency
        if not (latency >= 0.0 and np.isfinite(latency)):
            text = f"result_latency {latency}: expected seconds >= 0 (0: apply at once)"
            raise SlamInputError(text)
        self._latency_ns = round(latency * 1e9)
        self._initial_pose: FloatArray | None = None
        if prm.set_initial_pose:  # initial_pose.* are declared only then (as before)
            start = declare_params(self, InitialPoseParams, prefix="initial_pose.")
            self._initial_pose = start.matrix()
        rate = prm.max_frame_rate
        if not (rate >= 0.0 and np.isfinite(rate)):
            text = f"max_frame_rate {rate}: expected a rate in Hz >= 0 (0 processes every frame)"
            raise SlamInputError(text)
        self._min_period_ns = round(1e9 / rate) if rate > 0 else 0
        self.odometry_prior = prm.odometry_prior
        self.database_path = check_database_path(prm.database_path)
        self.localization = prm.localization
        if self.localization:
            check_saved_map_path(self.database_path)
        self._last_stamp: int | None = None
        self.skipped = 0
        self.config = SlamConfig(
            n_features=prm.n_features,
            seed=prm.seed,
            loop_closure=prm.loop_closure,
            global_ba_after_loop=prm.global_ba_after_loop,
            global_ba_delay=prm.global_ba_delay,
            local_ba=prm.local_ba,
            icp_refinement=prm.icp_refinement,
            depth_noise=prm.depth_noise,
            depth_scale=depth_scale,
            sensor=prm.sensor,  # type: ignore[arg-type]
            mono_scale=prm.mono_scale,  # type: ignore[arg-type]
            final_global_ba=False,
            odometry_sigma_t=prm.odometry_sigma_t,
            odometry_sigma_t_rel=prm.odometry_sigma_t_rel,
            odometry_sigma_r_deg=prm.odometry_sigma_r_deg,
            odometry_sigma_r_rel=prm.odometry_sigma_r_rel,
            odometry_sigma_r_per_m=prm.odometry_sigma_r_per_m,
            odometry_model=prm.odometry_model,  # type: ignore[arg-type]
            far_point_limit=None if prm.far_point_limit < 0 else prm.far_point_limit,
            odometry_sigma_t_lateral=prm.odometry_sigma_t_lateral,
        )
        self.worker: SlamWorker | None = None
        self._worker_failure: str | None = None
        self._in_flight: deque[tuple[int, FloatArray]] = deque()  # stamp, T_odom_base
        # frames awaiting their odometry, with their arrival (clock ns); at most queue_size,
        # as tf2's MessageFilter bounds its queue
        self._waiting: deque[tuple[Image, Image | None, int]] = deque()
        self._waiting_limit = max(1, prm.queue_size)
        wait = prm.odometry_wait
        if not (wait >= 0.0 and np.isfinite(wait)):
            text = f"odometry_wait {wait}: expected seconds >= 0 (0: use the newest odometry)"
            raise SlamInputError(text)
        self._odom_wait_ns = round(wait * 1e9)
        self.odometry_fallbacks = 0
        self.force_3dof = prm.force_3dof
        self._level_z: float | None = None  # the base's height in the map at the first frame
        self.tracking = False
        self.unlocalized_frames = 0  # localisation mode: frames before the first fix
        self.cpu_s = 0.0  # the worker's CPU time on frames (its process or this thread)
        self._stats = SlamStats()
        self.stats_stamp_ns = -1  # the stamp of the last frame the counters include
        self._diag = SlamDiagnostics(self)
        diag_period = prm.diagnostic_period
        if diag_period > 0:  # 0: only on loss and recovery
            self.create_timer(diag_period, self._publish_diagnostics)
        self.camera: CameraIntrinsics | None = None
        self._info_key: tuple[float, ...] | None = None
        self.dropped = 0
        self.t_map_odom: FloatArray | None = None
        self._t_base_cam: FloatArray | None = None
        self._odom_start: FloatArray | None = None
        self._slam_start: FloatArray | None = None
        self._scale_checked = False
        self.tf_buffer = Buffer()
        self._listener = TransformListener(self.tf_buffer, self)
        self._broadcaster = TransformBroadcaster(self)
        self._pose_pub = self.create_publisher(PoseStamped, "slam/pose", 10)
        self._path_pub = self.create_publisher(Path, "slam/path", 1)
        self._map_pub = self.create_publisher(PointCloud2, "slam/map_points", 1)
        self._dense_pub = self.create_publisher(PointCloud2, "slam/dense_cloud", 1)
        self._path: list[PoseStamped] = []
        empty = get_message_class("std_msgs/msg/Empty")
        self.create_subscription(empty, "slam/dense_cloud_request", self._on_dense_request, 1)
        image = message_filters.Subscriber(self, Image, "rgb/image", queue)
        self._mono_odom = self.config.sensor == "mono" and self.config.mono_scale == "odometry"
        if self._mono_odom and not self.odom_frame:
            text = "mono_scale 'odometry' needs odom_frame (TF odom -> base scales the map)"
            raise SlamInputError(text)
        inputs = [image]
        if not self._mono_odom:  # monocular with scale from odometry needs no depth
            inputs.append(message_filters.Subscriber(self, Image, "depth/image", queue))
        inputs.append(message_filters.Subscriber(self, CameraInfo, "rgb/camera_info", queue))
        self._sync: message_filters.SimpleFilter = (
            message_filters.ApproximateTime(inputs, queue)
            if approx
            else message_filters.TimeSynchronizer(inputs, queue)
        )
        self._sync.register_callback(self._on_frame)
        if self.publish_tf and tf_period > 0:
            self.create_timer(tf_period, self._publish_tf)
        if self._latency_ns > 0 or self.odom_frame:  # frames wait for odometry, results are
            period = min(0.005, latency / 2) if self._latency_ns > 0 else 0.005  # due on the clock
            self.create_timer(period, self._tick)
        if map_period > 0:
            self.create_timer(map_period, self._publish_map)
        if dense_period > 0:
            self.create_timer(dense_period, self._publish_dense)
        self.slam_services = SlamServices(self)  # reset, pause, resume, save_map

    # ---------------------------------------------------------------- helpers

    def _lookup(self, target: str, source: str, stamp_ns: int) -> FloatArray | None:
        try:
            return self.tf_buffer.lookup_transform_matrix(target, source, stamp_ns)
        except TransformException:
            try:
                return self.tf_buffer.lookup_transform_matrix(target, source, 0)
            except TransformException as exc:
                self.get_logger().warning(
                    f"waiting for TF {target} -> {source} ({exc}); SLAM starts when it exists",
                    throttle_duration_sec=_LOG_PERIOD_S,
                )
                return None

    def _check_camera(self, info: CameraInfo, image: Image) -> CameraIntrinsics:
        key = (float(info.width), float(info.height), *map(float, info.k), *map(float, info.p))
        if self.camera is None:
            cam, warnings = CameraIntrinsics.from_camera_info(
                info, source=self.resolve_topic_name("rgb/camera_info")
            )
            for w in warnings:  # once: the first camera_info only
                self.get_logger().warning(w)
            self.camera, self._info_key = cam, key
        elif key != self._info_key:
            text = (
                f"{self.resolve_topic_name('rgb/camera_info')} changed (size, K or P) after SLAM "
                "started; the map is built with the first calibration: restart SLAM for a new one"
            )
            raise SlamInputError(text)
        if info.header.frame_id and image.header.frame_id != info.header.frame_id:
            self.get_logger().warning(
                f"image frame_id {image.header.frame_id!r} differs from camera_info frame_id "
                f"{info.header.frame_id!r}; using the image's",
                once=True,
            )
        return self.camera

    # -------------------------------------------------------------- callbacks

    def _on_frame(self, image: Image, *rest: Any) -> None:
        if self.slam_services.paused:  # ~/pause: frames are left out until ~/resume
            self.slam_services.paused_frames += 1
            return
        depth, info = (None, rest[0]) if self._mono_odom else (rest[0], rest[1])
        try:
            self._process(image, depth, info)
        except VisnavError as exc:
            self.dropped += 1
            self.get_logger().error(
                f"dropped a frame ({self.dropped} so far): {exc}",
                throttle_duration_sec=_LOG_PERIOD_S,
            )

    def _process(self, image: Image, depth: Image | None, info: CameraInfo) -> None:
        stamp = time_to_ns(image.header.stamp)
        if self._skip(stamp):
            return
        self._check_camera(info, image)
        self._last_stamp = stamp
        if len(self._waiting) >= self._waiting_limit:
            self._waiting.popleft()
            self.dropped += 1
            self.get_logger().warning(
                f"dropped the oldest frame waiting for TF {self.odom_frame} -> "
                f"{self.base_frame} ({self.dropped} so far): {self._waiting_limit} frames "
                "wait already; is the odometry (or /clock) running?",
                throttle_duration_sec=_LOG_PERIOD_S,
            )
        self._waiting.append((image, depth, self.get_clock().now_ns()))
        self._submit_ready()

    def _tick(self) -> None:
        """Clock timer: submit frames whose odometry came, apply results that are due."""
        self._submit_ready()
        self._apply_due()

    def _submit_ready(self) -> None:
        """Submit the waiting frames, oldest first, once TF has odometry at their stamps.

        A frame's ``odom -> base`` is looked up at the frame's own stamp: the odometry of
        that instant often arrives after the image (a 50 Hz diff drive and a 20 Hz camera
        share a stamp only every 100 ms), so the frame waits for it up to
        ``odometry_wait`` s of clock time from its arrival (as tf2's MessageFilter times
        out from arrival, so late images still wait); only then is the newest transform used.
        """
        while self._waiting:
            image, depth, arrival = self._waiting[0]
            stamp = time_to_ns(image.header.stamp)
            t_odom_base, wait = self._odometry_at(stamp, str(image.header.frame_id), arrival)
            if wait:
                return
            self._waiting.popleft()
            if t_odom_base is None:  # no TF yet: the frame is left out (logged)
                continue
            try:
                self._submit(image, depth, stamp, t_odom_base)
            except VisnavError as exc:
                self.dropped += 1
                self.get_logger().error(
                    f"dropped a frame ({self.dropped} so far): {exc}",
                    throttle_duration_sec=_LOG_PERIOD_S,
                )

    def _odometry_at(
        self, stamp: int, camera_frame: str, arrival: int
    ) -> tuple[FloatArray | None, bool]:
        """``(T_odom_base at stamp or None, wait)``; the mounting is looked up first."""
        waiting = self.get_clock().now_ns() - arrival < self._odom_wait_ns
        if self._t_base_cam is None:
            try:
                self._t_base_cam = self.tf_buffer.lookup_transform_matrix(
                    self.base_frame, camera_frame, 0
                )
            except TransformException:
                if waiting:
                    return None, True
                t_base_cam = self._lookup(self.base_frame, camera_frame, stamp)  # logs
                if t_base_cam is None:
                    return None, False
                self._t_base_cam = t_base_cam
        if not self.odom_frame:
            return np.eye(4), False
        try:
            return self.tf_buffer.lookup_transform_matrix(
                self.odom_frame, self.base_frame, stamp
            ), False
        except TransformException:
            pass
        try:
            newest = self.tf_buffer.lookup_transform(self.odom_frame, self.base_frame, 0)
        except TransformException as exc:
            if waiting:
                return None, True
            self.get_logger().warning(
                f"waiting for TF {self.odom_frame} -> {self.base_frame} ({exc}); SLAM starts "
                "when it exists",
                throttle_duration_sec=_LOG_PERIOD_S,
            )
            return None, False
        newest_ns = time_to_ns(newest.header.stamp)
        if newest_ns < stamp and waiting:
            return None, True
        self.odometry_fallbacks += 1
        self.get_logger().warning(
            f"no TF {self.odom_frame} -> {self.base_frame} at the frame's stamp "
            f"{stamp * 1e-9:.3f} s (newest {newest_ns * 1e-9:.3f} s): using the newest "
            f"({self.odometry_fallbacks} frames so far); is the odometry late?",
            throttle_duration_sec=_LOG_PERIOD_S,
        )
        return transform_to_matrix(newest.transform), False

    def _submit(
        self, image: Image, depth: Image | None, stamp: int, t_odom_base: FloatArray
    ) -> None:
        assert self._t_base_cam is not None  # _odometry_at looked it up
        assert self.camera is not None  # _check_camera set it
        if self.worker is None:
            if self._worker_failure is not None:
                raise SlamWorkerError(self._worker_failure)  # not restarted on every frame
            start = self._initial_pose if self._initial_pose is not None else t_odom_base
            try:
                self.worker = make_worker(
                    self.worker_kind,
                    self.camera,
                    self.config,
                    vocabulary_path=self.vocabulary_path,
                    initial_pose=start @ self._t_base_cam,
                    map_path=self.database_path if self.localization else "",
                )
            except VisnavError as exc:
                self._worker_failure = f"the SLAM worker could not start: {exc}; fix and restart"
                raise SlamWorkerError(self._worker_failure) from exc
        depth_arr = None if depth is None else image_to_numpy(depth)
        if depth is not None and depth.encoding not in ("16UC1", "32FC1", "mono16"):
            text = f"depth encoding {depth.encoding!r}: expected 32FC1 (m) or 16UC1 (mm)"
            raise SlamInputError(text)
        odom_pose = (
            t_odom_base @ self._t_base_cam
            if self.odom_frame and (self.odometry_prior or self._mono_odom)
            else None
        )
        self.worker.submit(_image_array(image), depth_arr, stamp, odom_pose)
        self._in_flight.append((stamp, t_odom_base))
        if self._latency_ns == 0:
            self._apply_due()

    def _apply_due(self) -> None:
        """Apply every result whose time (stamp + ``result_latency``) has come, in order."""
        if self.worker is None:
            return
        now = self.get_clock().now_ns()
        while self._in_flight and (
            self._latency_ns == 0 or self._in_flight[0][0] + self._latency_ns <= now
        ):
            stamp, t_odom_base = self._in_flight.popleft()
            out = self.worker.next_result()  # waits for the worker: the barrier
            self.cpu_s += out.cpu_s
            if out.stats is not None:
                self._stats, self.stats_stamp_ns = out.stats, stamp
            if out.result is None:
                self.dropped += 1
                self.get_logger().error(
                    f"dropped a frame ({self.dropped} so far): {out.error}",
                    throttle_duration_sec=_LOG_PERIOD_S,
                )
                continue
            self._apply(out.result, stamp, t_odom_base)

    def _apply(self, result: TrackResult, stamp: int, t_odom_base: FloatArray) -> None:
        assert self._t_base_cam is not None  # set before the first frame was submitted
        for w in result.warnings:
            self.get_logger().warning(w, throttle_duration_sec=_LOG_PERIOD_S)
        if result.t_wc is None:
            if self.localization and self.t_map_odom is None:
                self._not_localized(stamp)
            if self.tracking:
                self.tracking = False
                self.get_logger().warning(
                    f"tracking lost at {stamp * 1e-9:.3f} s: {self.map_frame} -> "
                    f"{self.odom_frame or self.base_frame} is not refreshed until SLAM "
                    "relocalises"
                )
                self._publish_diagnostics()
            return
        if not self.tracking and self.t_map_odom is not None:
            self.get_logger().info(f"tracking again at {stamp * 1e-9:.3f} s")
            self.tracking = True
            self._publish_diagnostics()
        self.tracking = True
        t_map_base = result.t_wc @ inverse(self._t_base_cam)
        t_tf_base = t_map_base
        if self.force_3dof:  # a ground robot: SLAM's z, roll and pitch errors stay out of TF
            if self._level_z is None:
                self._level_z = float(t_map_base[2, 3])
            t_tf_base = level_pose(t_map_base, self._level_z)
        self.t_map_odom = t_tf_base @ inverse(t_odom_base)
        self._check_scale(t_map_base, t_odom_base)
        header = Header(stamp=ns_to_time(stamp), frame_id=self.map_frame)
        pose = PoseStamped(header=header, pose=matrix_to_pose(t_map_base))
        self._pose_pub.publish(pose)
        if result.loop:
            self._rebuild_path(upto_ns=stamp)
        else:
            self._path.append(pose)
        due = self._path_sent_ns is None or stamp - self._path_sent_ns >= self._path_period_ns
        if due or result.loop:  # the whole path each time: at most every path_publish_period
            self._path_sent_ns = stamp
            self._path_pub.publish(Path(header=header, poses=list(self._path)))
        self._publish_tf()

    def _not_localized(self, stamp: int) -> None:
        """Localisation mode before the first fix: say once that it cannot localise."""
        self.unlocalized_frames += 1
        if self.unlocalized_frames == LOCALIZE_FRAMES:
            self.get_logger().error(
                f"cannot localise in the saved SLAM map {self.database_path}: no fix in "
                f"{LOCALIZE_FRAMES} frames (to {stamp * 1e-9:.3f} s), so {self.map_frame} -> "
                f"{self.odom_frame or self.base_frame} is not published and the robot is not "
                "driven; start it where the map was built (initial_pose.*) or map again"
            )
            self._publish_diagnostics()

    def _skip(self, stamp: int) -> bool:
        """True when ``max_frame_rate`` leaves this frame out (1 ms tolerance for jitter)."""
        if self._last_stamp is None or self._min_period_ns <= 0:
            return False
        if stamp - self._last_stamp >= self._min_period_ns - 1_000_000:
            return False
        self.skipped += 1
        return True

    @property
    def system(self) -> SlamSystem | None:
        """The SLAM system when it runs in this process (``worker: inline``), else None."""
        return self.worker.system if isinstance(self.worker, InlineWorker) else None

    def stats(self) -> SlamStats:
        """The system's counters as of the last applied result (zeros before it)."""
        return self._stats

    def _publish_diagnostics(self) -> None:
        self._diag.publish(self._stats, tracking=self.tracking, started=self.worker is not None)

    def trajectory(self) -> Trajectory:
        """Poses of ``base_frame`` in the map for all tracked frames (loop corrections applied).

        Before the camera's mounting is known (no frame processed) the trajectory is empty.
        """
        if self.worker is None or self._t_base_cam is None:
            return Trajectory.empty()
        traj = self.worker.trajectory()
        if len(traj) == 0:
            return traj
        t_cb = inverse(self._t_base_cam)
        return Trajectory.from_matrices(traj.stamps, traj.matrices() @ t_cb)

    def _check_scale(self, t_map_base: FloatArray, t_odom_base: FloatArray) -> None:
        if self._scale_checked or not self.odom_frame:
            return
        if self._odom_start is None or self._slam_start is None:
            self._odom_start, self._slam_start = t_odom_base, t_map_base
            return
        d_odom = float(np.linalg.norm(t_odom_base[:3, 3] - self._odom_start[:3, 3]))
        if d_odom < 0.5:
            return
        d_slam = float(np.linalg.norm(t_map_base[:3, 3] - self._slam_start[:3, 3]))
        self._scale_checked = True
        ratio = d_slam / d_odom
        if ratio > 5.0 or ratio < 0.2:
            self.get_logger().error(  # checked once (_scale_checked)
                f"SLAM moved {d_slam:.3f} m while odometry moved {d_odom:.3f} m (ratio "
                f"{ratio:.3g}): the depth scale is probably wrong (16UC1 must be millimetres "
                "with depth_scale 1000, 32FC1 metres)"
            )

    def _rebuild_path(self, *, upto_ns: int) -> None:
        """The path from the corrected trajectory, up to the frame being applied.

        The worker may already have tracked frames still in flight (``result_latency``):
        those are appended when their own results are applied, not here.
        """
        assert self.worker is not None
        traj = self.worker.trajectory()
        mats = traj.matrices()
        t_cb = inverse(self._t_base_cam) if self._t_base_cam is not None else np.eye(4)
        self._path = [
            PoseStamped(
                header=Header(stamp=ns_to_time(t_ns), frame_id=self.map_frame),
                pose=matrix_to_pose(m @ t_cb),
            )
            for t, m in zip(traj.stamps, mats, strict=True)
            if (t_ns := round(t * 1e9)) <= upto_ns
        ]

    def _publish_tf(self) -> None:
        if not self.publish_tf or self.t_map_odom is None or not self.tracking:
            return
        stamp = self.get_clock().now_ns() + round(self.transform_tolerance * 1e9)
        child = self.odom_frame or self.base_frame
        msg = TransformStamped(
            header=Header(stamp=ns_to_time(stamp), frame_id=self.map_frame),
            child_frame_id=child,
            transform=matrix_to_transform(self.t_map_odom),
        )
        self._broadcaster.send_transform(msg)

    def _publish_map(self) -> None:
        # nobody listening: skip it, as the map fetch waits for every frame in flight
        if self.worker is None or self._map_pub.get_subscription_count() == 0:
            return
        header = Header(stamp=ns_to_time(self.get_clock().now_ns()), frame_id=self.map_frame)
        self._map_pub.publish(xyz_to_cloud(self.worker.map_cloud(), header=header))

    def _publish_dense(self) -> None:
        if self.worker is None:
            return
        pts, rgb = self.worker.dense_cloud(self.dense_voxel)
        header = Header(stamp=ns_to_time(self.get_clock().now_ns()), frame_id=self.map_frame)
        self._dense_pub.publish(xyz_to_cloud(pts, header=header, rgb=rgb))

    def _on_dense_request(self, msg: Any) -> None:
        del msg
        self._publish_dense()

    def reset_map(self) -> None:
        """Drop the map (and frames in flight); the next frame starts a new one, as at start."""
        worker, self.worker = self.worker, None
        self._in_flight.clear()
        if worker is not None:
            worker.close()
        self.t_map_odom = self._level_z = self._odom_start = self._slam_start = None
        self._path, self._path_sent_ns, self._scale_checked = [], None, False
        self._worker_failure, self.tracking, self.unlocalized_frames = None, False, 0

    def destroy_node(self) -> None:
        """Save the map (``database_path``), stop the worker (its process), remove the node."""
        worker = getattr(self, "worker", None)  # None when __init__ refused a parameter
        saving = not getattr(self, "localization", False)  # localisation: the map is read
        level, text = save_at_shutdown(worker, getattr(self, "database_path", "") if saving else "")
        self.database_path = ""  # saved once, even if destroyed again
        if text:  # info (written), warning (no frame) or error (not written)
            getattr(self.get_logger(), level)(text)
        if worker is not None:
            worker.close()
        super().destroy_node()
