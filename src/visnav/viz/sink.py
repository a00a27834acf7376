"""``RerunSink``: ROS messages into a Rerun recording, placed in the fixed frame as RViz does.

Give it ``(topic, message, stamp)``; it converts the message, places it in the fixed
frame through TF at the message's stamp (see :mod:`visnav.viz.placement`) and logs
it on the ``ros_time`` timeline (the header stamp, sim time in simulation; the
``stamp`` argument for messages without one).

Entities (``world`` is the fixed frame, z up):

==================================  ================================================
``world/tf/<frame>``                every TF frame: ``Transform3D`` + axes
``world/cameras/<ns>``              a camera (namespace of its ``camera_info`` or
                                    image topic, one path part: ``a/b`` escaped, for ``/a/b``):
                                    ``Transform3D`` + ``Pinhole``
``world/cameras/<ns>/<name>``       its images (``Image``, ``EncodedImage``,
                                    ``DepthImage`` with ``meter``)
``world/robot_model/<robot>``       ``robot_description`` (RViz's RobotModel): each link's
                                    visuals, placed by TF (:mod:`visnav.viz.robot_model`)
``world/<topic>``                   clouds and scans (``Points3D``), odometry and
                                    poses (``Arrows3D``; odometry keeps a ``path``
                                    child), paths (``LineStrips3D``), occupancy
                                    grids (``GridMap``), markers (``<ns>/<id>``)
==================================  ================================================

Geometry is logged already transformed into the fixed frame (as RViz draws it), so
topics nest freely; only cameras and robot links carry an entity transform, because
Rerun projects images through a pinhole placed by its entity's transform and a link's
visuals are logged once. With ``layout`` the recording gets the default blueprint
(:func:`visnav.viz.layout.default_blueprint`): the 3D view with the cameras beside it.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.description.worldmodel import WorldDescription
from visnav.errors import VisnavError
from visnav.msgs.image import image_to_numpy
from visnav.msgs.time import time_to_ns
from visnav.perception.image_transport import decompress_depth, split_transport_topic
from visnav.tf.transforms import matrix_to_quaternion
from visnav.viz._rerun import rr
from visnav.viz.display import message_to_display
from visnav.viz.errors import VizError
from visnav.viz.geometry import cloud_points, colorize, pose_matrix, scan_points, transform_points32
from visnav.viz.image_archetypes import (
    depth_archetype,
    image_archetype,
    jpeg_archetype,
)
from visnav.viz.layout import default_blueprint
from visnav.viz.markers import DELETE, DELETEALL, MESH_RESOURCE, marker_archetypes
from visnav.viz.placement import FramePlacer
from visnav.viz.robot_model import RobotModel, parse_robot_description
from visnav.viz.rviz_config import RvizConfig
from visnav.viz.world_view import log_world

__all__ = ["SUPPORTED_TYPES", "RerunSink", "shows"]

_LOG = logging.getLogger("visnav.viz")

SUPPORTED_TYPES = (
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/CompressedImage",
    "sensor_msgs/msg/CameraInfo",
    "sensor_msgs/msg/PointCloud2",
    "sensor_msgs/msg/LaserScan",
    "tf2_msgs/msg/TFMessage",
    "nav_msgs/msg/Odometry",
    "nav_msgs/msg/Path",
    "nav_msgs/msg/OccupancyGrid",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseArray",
    "visualization_msgs/msg/Marker",
    "visualization_msgs/msg/MarkerArray",
    "std_msgs/msg/String",
)
"""Message types the sink shows; others are counted and skipped (``String``: only on a
``robot_description`` topic, see :func:`shows`)."""

_STRING = "std_msgs/msg/String"


def shows(topic: str, type_name: str) -> bool:
    """Whether the sink shows ``topic`` of ``type_name`` (a string only as robot_description)."""
    if type_name == _STRING:
        return topic.rstrip("/").rsplit("/", 1)[-1] == "robot_description"
    return type_name in SUPPORTED_TYPES


_KEY_SEP = "\x00"
_PREFERRED_FIXED = ("map", "odom", "world")
_ROOT_AFTER_NS = 1_000_000_000  # TF stamp time seen before the root is taken as fixed frame
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_SCAN_COLOR = (255, 64, 64)
_POSE_COLOR = (255, 40, 40)
_PATH_COLOR = (40, 200, 255)
_GRID_COLORMAPS: dict[str, Any] = {
    "map": rr.components.Colormap.RvizMap,
    "costmap": rr.components.Colormap.RvizCostmap,
    "raw": rr.components.Colormap.Grayscale,
}


def _stamp_ns(msg: Any) -> int:
    """The message's own time: header stamp, else the newest stamp of its transforms/markers."""
    header = getattr(msg, "header", None)
    if header is not None:
        return time_to_ns(header.stamp)
    items = getattr(msg, "transforms", None) or getattr(msg, "markers", None) or ()
    return max((time_to_ns(item.header.stamp) for item in items), default=0)


class RerunSink:
    """Logs ROS messages to a Rerun recording, placed in the fixed frame through TF.

    Args:
        recording: the ``rerun.RecordingStream`` to log to (see
            :func:`visnav.viz.open_viewer` for one with file / web sinks).
        fixed_frame: the frame everything is shown in (RViz's *Fixed Frame*); None picks
            ``map``, else ``odom``, else ``world`` once TF has it, else the root of the
            TF tree of the first message placed.
        max_points: clouds are decimated to at most this many points (None: all).
        root: the entity of the fixed frame.
        timeline: the timeline of the message stamps.
        queue_size: messages per topic held while waiting for TF (RViz's queue).
        tf_axis_length: length of the axes drawn for every TF frame (m).
        tf_period_s: the TF frames are re-logged at most this often in stamp time.
        arrow_length: length of odometry / pose arrows (m).
        path_keep: odometry path points kept (a point is added per 1 cm moved).
        strict: raise on a message that cannot be shown (default: warn once per topic
            and count it in :meth:`stats`).
        layout: send the default blueprint (3D view, cameras beside it) and update it as
            cameras appear.
        tf_prefix: the robot model's TF prefix (RViz's RobotModel *TF Prefix*).
        packages: package name -> directory for the robot model's ``package://`` meshes.
        jpeg_quality: colour images are sent JPEG-compressed at this quality (1-100), as
            ``EncodedImage`` (a 640x480 frame is ~30 KB instead of 900 KB); None sends
            them raw. Depth images are sent as 16-bit millimetres.
        rviz: an RViz config (:func:`visnav.viz.rviz_config.load_rviz_config`): its fixed
            frame (unless ``fixed_frame``), its displays' colours and map colour schemes,
            and TF axes only with an enabled TF display. Which topics are fed is the
            feed's choice (``topics=rviz.topics``).
    """

    def __init__(
        self,
        recording: rr.RecordingStream,
        *,
        fixed_frame: str | None = None,
        max_points: int | None = 50_000,
        root: str = "world",
        timeline: str = "ros_time",
        queue_size: int = 10,
        tf_axis_length: float = 0.25,
        tf_period_s: float = 0.2,
        arrow_length: float = 0.5,
        path_keep: int = 2000,
        strict: bool = False,
        layout: bool = True,
        tf_prefix: str = "",
        packages: Mapping[str, str] | None = None,
        jpeg_quality: int | None = 80,
        rviz: RvizConfig | None = None,
    ) -> None:
        if jpeg_quality is not None and not 1 <= jpeg_quality <= 100:
            text = f"jpeg_quality is {jpeg_quality}: expected 1..100 (or None for raw images)"
            raise VizError(text)
        self._jpeg_quality = jpeg_quality
        if max_points is not None and max_points < 1:
            text = f"max_points is {max_points}: expected at least 1 (or None for every point)"
            raise VizError(text)
        self.recording = recording
        self._packages = dict(packages or {})  # package:// meshes of robot_description
        if rviz is not None and fixed_frame is None:
            fixed_frame = rviz.fixed_frame
        self._colors = rviz.colors if rviz is not None else {}
        self._schemes = {
            d.topic: d.color_scheme for d in (rviz.enabled if rviz else []) if d.color_scheme
        }
        self._show_tf_axes = rviz.show_tf if rviz is not None else True
        # no fixed frame given: chosen from TF (see _tf), not from the first data message
        self.placer = FramePlacer(fixed_frame, queue_size=queue_size, auto_root=False)
        self._first_tf_ns: int | None = None
        self._max_points = max_points
        self._root = root.strip("/") or "world"
        self._timeline = timeline
        self._axis = tf_axis_length
        self._tf_period_ns = int(tf_period_s * 1e9)
        self._arrow_length = arrow_length
        self._path_keep = path_keep
        self._strict = strict
        self._lock = threading.RLock()
        self._last_ns = 0
        self._tf_logged_ns: int | None = None
        self._tf_frames: dict[str, None] = {}
        self._tf_axes: set[str] = set()
        self._entities: dict[str, str] = {}
        self._cameras_with_info: set[str] = set()
        self._pinholes: dict[str, tuple[bytes, int, int]] = {}
        self._tracks: dict[str, list[NDArray[np.float64]]] = {}
        self._marker_kinds: dict[str, int] = {}
        self._warned: set[tuple[str, str]] = set()
        self._layout = layout
        self._tf_prefix = tf_prefix
        self._cameras: list[str] = []
        self.world_paths: list[str] = []
        """Entities of the world's geometry (:meth:`log_world`)."""
        self.robot_models: dict[str, RobotModel] = {}
        """The robot model of each robot_description topic."""
        self.counts: dict[str, int] = {}
        """Messages logged, per topic."""
        self.errors: dict[str, int] = {}
        """Messages that could not be shown, per topic."""
        self.types: dict[str, str] = {}
        """Message type, per topic seen."""
        self._handlers: dict[str, Callable[[str, Any, int], None]] = {
            "sensor_msgs/msg/Image": self._image,
            "sensor_msgs/msg/CompressedImage": self._compressed,
            "sensor_msgs/msg/CameraInfo": self._camera_info,
            "sensor_msgs/msg/PointCloud2": self._cloud,
            "sensor_msgs/msg/LaserScan": self._scan,
            "tf2_msgs/msg/TFMessage": self._tf,
            "nav_msgs/msg/Odometry": self._odometry,
            "nav_msgs/msg/Path": self._path,
            "nav_msgs/msg/OccupancyGrid": self._grid,
            "geometry_msgs/msg/PoseStamped": self._pose,
            "geometry_msgs/msg/PoseArray": self._pose_array,
            "visualization_msgs/msg/Marker": self._marker_msg,
            "visualization_msgs/msg/MarkerArray": self._marker_array,
            _STRING: self._robot_description,
        }
        recording.log(self._root, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        if layout:
            recording.send_blueprint(default_blueprint(self._root, [], timeline=timeline))

    # ------------------------------------------------------------------ public

    @property
    def fixed_frame(self) -> str | None:
        """The fixed frame (None until chosen automatically)."""
        return self.placer.fixed_frame

    @staticmethod
    def supports(type_name: str) -> bool:
        """Whether messages of ``type_name`` (``"sensor_msgs/msg/Image"``) are shown."""
        return type_name in SUPPORTED_TYPES

    def log(self, topic: str, msg: Any, stamp_ns: int | None = None) -> bool:
        """Show one message.

        Args:
            topic: the topic it came on (names the entity).
            msg: the message (a ``visnav.msgs`` / rosbags message object).
            stamp_ns: receive or record time (ns), the timeline time of messages
                without a header stamp; None: the latest time seen.

        Returns:
            True if the message was shown or queued for TF; False if its type is not
            supported or it could not be converted (see :meth:`stats`).

        Raises:
            VisnavError: only with ``strict=True``, for a message that cannot be shown.
        """
        type_name = getattr(msg, "__msgtype__", type(msg).__name__)
        with self._lock:
            self.types.setdefault(topic, type_name)
            handler = self._handlers.get(type_name) if shows(topic, type_name) else None
            if handler is None:
                if (topic, "type") not in self._warned:  # listed in stats(): no warning
                    self._warned.add((topic, "type"))
                    _LOG.debug("%s: type %s is not shown", topic, type_name)
                return False
            t = _stamp_ns(msg) or (stamp_ns if stamp_ns is not None else self._last_ns)
            self._last_ns = max(self._last_ns, t)
            try:
                handler(topic, msg, t)
            except (VisnavError, ValueError, TypeError) as exc:
                if self._strict:
                    raise
                self.errors[topic] = self.errors.get(topic, 0) + 1
                self._warn_once(topic, "error", f"{topic} ({type_name}) cannot be shown: {exc}")
                return False
            self.counts[topic] = self.counts.get(topic, 0) + 1
            return True

    def log_world(self, world: WorldDescription) -> list[str]:
        """Show the world's geometry (static, in the fixed frame = the simulator's world).

        Returns:
            The entity paths logged (``world/scene/...``).
        """
        with self._lock:
            self.world_paths = log_world(self.recording, world, root=self._root)
        return self.world_paths

    def log_error(self, topic: str, type_name: str, reason: str) -> None:
        """Count a message of ``topic`` that could not even be decoded (warned once per topic).

        A bag message whose bytes do not decode is skipped like a message that cannot be
        shown: it is counted under ``errors`` in :meth:`stats`, the rest is still shown.

        Raises:
            VisnavError: only with ``strict=True``.
        """
        if self._strict:
            msg = f"{topic} ({type_name}): {reason}"
            raise VisnavError(msg)
        with self._lock:
            self.types.setdefault(topic, type_name)
            self.errors[topic] = self.errors.get(topic, 0) + 1
            self._warn_once(topic, "error", f"{topic} ({type_name}) skipped: {reason}")

    def poll(self) -> None:
        """Give up on data that waited too long for TF (call now and then when live)."""
        with self._lock:
            self.placer.expire()

    def close(self) -> None:
        """Place or drop everything still waiting for TF, and flush the recording."""
        with self._lock:
            if self.placer.fixed_frame is None and self._tf_frames:
                self.placer.choose_fixed(next(iter(self._tf_frames)))
                self.placer.expire()
            self.placer.expire(force=True)
        self.recording.flush()

    def stats(self) -> dict[str, dict[str, Any]]:
        """Per topic: type, messages logged, errors, items dropped for TF and the last reason."""
        dropped: dict[str, int] = {}
        reasons: dict[str, str] = {}
        for key, count in self.placer.dropped.items():
            topic = key.split(_KEY_SEP, 1)[0]
            dropped[topic] = dropped.get(topic, 0) + count
            reasons[topic] = self.placer.drop_reasons.get(key, "")
        out: dict[str, dict[str, Any]] = {}
        for topic, type_name in self.types.items():
            out[topic] = {
                "type": type_name,
                "logged": self.counts.get(topic, 0),
                "errors": self.errors.get(topic, 0),
                "dropped": dropped.get(topic, 0),
                "reason": reasons.get(topic, ""),
                "supported": shows(topic, type_name),
            }
        return out

    # ------------------------------------------------------------------ helpers

    def _warn_once(self, topic: str, kind: str, text: str) -> None:
        if (topic, kind) not in self._warned:
            self._warned.add((topic, kind))
            _LOG.warning(text)

    def _at(self, t_ns: int) -> None:
        self.recording.set_time(self._timeline, timestamp=np.datetime64(t_ns, "ns"))

    def _entity(self, topic: str) -> str:
        path = self._entities.get(topic)
        if path is None:
            parts = [rr.escape_entity_path_part(p) for p in topic.split("/") if p]
            path = "/".join([self._root, *parts])
            self._entities[topic] = path
        return path

    def _place(self, topic: str, header: Any, apply: Callable[[NDArray[np.float64]], None]) -> None:
        self.placer.place(topic, header.frame_id, time_to_ns(header.stamp), apply)

    @staticmethod
    def _transform3d(matrix: NDArray[np.float64]) -> Any:
        quat = matrix_to_quaternion(matrix[:3, :3])
        return rr.Transform3D(translation=matrix[:3, 3], quaternion=rr.Quaternion(xyzw=quat))

    # ------------------------------------------------------------------ TF

    def _tf(self, topic: str, msg: Any, t: int) -> None:
        static = topic.rstrip("/").endswith("tf_static")
        self.placer.add_transforms(msg, static=static)
        for tr in msg.transforms:
            self._tf_frames.setdefault(tr.header.frame_id.lstrip("/"), None)
            self._tf_frames.setdefault(tr.child_frame_id.lstrip("/"), None)
        if self.placer.fixed_frame is None:
            # RViz's usual fixed frames first; else the TF root once data need placing
            preferred = [f for f in _PREFERRED_FIXED if f in self._tf_frames]
            if self._first_tf_ns is None:
                self._first_tf_ns = t
            if preferred:
                self.placer.choose_fixed(preferred[0])
            elif t - self._first_tf_ns >= _ROOT_AFTER_NS and self._tf_frames:
                self.placer.choose_fixed(next(iter(self._tf_frames)))
        if static or self._tf_logged_ns is None or t - self._tf_logged_ns >= self._tf_period_ns:
            self._tf_logged_ns = t
            self._log_tf_frames(t)

    def _log_tf_frames(self, t: int) -> None:
        self._at(t)
        for frame in self._tf_frames if self._show_tf_axes else ():
            if not frame:
                continue
            matrix = self.placer.lookup(frame, 0)
            if matrix is None:
                continue
            entity = f"{self._root}/tf/{rr.escape_entity_path_part(frame)}"
            if frame not in self._tf_axes:
                self._tf_axes.add(frame)
                self.recording.log(entity, rr.TransformAxes3D(self._axis), static=True)
            self.recording.log(entity, self._transform3d(matrix))
        for model in self.robot_models.values():
            model.log_links(self.recording, lambda frame: self.placer.lookup(frame, 0))

    # ------------------------------------------------------------------ robot model

    def _robot_description(self, topic: str, msg: Any, t: int) -> None:
        urdf = parse_robot_description(str(msg.data), source=topic, packages=self._packages)
        parts = [rr.escape_entity_path_part(p) for p in topic.split("/")[:-1] if p]
        name = "/".join([*parts, rr.escape_entity_path_part(str(urdf.name))])
        model = RobotModel(urdf, f"{self._root}/robot_model/{name}", tf_prefix=self._tf_prefix)
        model.log_geometry(self.recording)
        self.robot_models[topic] = model
        self._at(t)
        model.log_links(self.recording, lambda frame: self.placer.lookup(frame, 0))

    # ------------------------------------------------------------------ cameras

    def _camera_paths(self, topic: str, *, image: bool) -> tuple[str, str]:
        """(camera entity, image entity) for an image or camera_info topic."""
        base = split_transport_topic(topic)[0] if image else topic
        ns, _, _ = base.rstrip("/").rpartition("/")
        # One path part per camera: cameras never nest (Rerun refuses nested pinholes,
        # and /depth_camera and /depth_camera/depth are two cameras).
        camera = f"{self._root}/cameras/{rr.escape_entity_path_part(ns.strip('/') or 'camera')}"
        leaf = topic[len(ns) :] if topic.startswith(ns) else topic
        leaf_parts = [rr.escape_entity_path_part(p) for p in leaf.split("/") if p]
        if image and camera not in self._cameras:  # a pane once it has an image to show
            self._cameras.append(camera)
            if self._layout:
                self.recording.send_blueprint(
                    default_blueprint(self._root, self._cameras, timeline=self._timeline)
                )
        return camera, "/".join([camera, *leaf_parts])

    def _place_camera(self, topic: str, camera: str, header: Any, t: int) -> None:
        def apply(matrix: NDArray[np.float64]) -> None:
            self._at(t)
            self.recording.log(camera, self._transform3d(matrix))

        self._place(topic, header, apply)

    def _image(self, topic: str, msg: Any, t: int) -> None:
        camera, entity = self._camera_paths(topic, image=True)
        self._at(t)
        self.recording.log(entity, image_archetype(msg, self._jpeg_quality))
        if camera not in self._cameras_with_info:
            self._place_camera(topic, camera, msg.header, t)

    def _compressed(self, topic: str, msg: Any, t: int) -> None:
        camera, entity = self._camera_paths(topic, image=True)
        if "compressedDepth" in msg.format:
            depth = decompress_depth(msg)
            archetype: Any = depth_archetype(image_to_numpy(depth), depth.encoding)
        else:
            data = np.asarray(msg.data, dtype=np.uint8).tobytes()
            if data[:2] == b"\xff\xd8":
                archetype = rr.EncodedImage(contents=data, media_type="image/jpeg")
            elif data[:8] == _PNG_MAGIC:
                archetype = rr.EncodedImage(contents=data, media_type="image/png")
            elif self._jpeg_quality is not None:
                archetype = jpeg_archetype(message_to_display(msg), self._jpeg_quality)
            else:
                archetype = rr.Image(message_to_display(msg), color_model="RGB")
        self._at(t)
        self.recording.log(entity, archetype)
        if camera not in self._cameras_with_info:
            self._place_camera(topic, camera, msg.header, t)

    def _camera_info(self, topic: str, msg: Any, t: int) -> None:
        camera, _ = self._camera_paths(topic, image=False)
        self._cameras_with_info.add(camera)
        k = np.asarray(msg.k, dtype=np.float64).reshape(3, 3).copy()
        width, height = int(msg.width), int(msg.height)
        roi = msg.roi
        if roi.width > 0 and roi.height > 0:
            k[0, 2] -= roi.x_offset
            k[1, 2] -= roi.y_offset
            width, height = int(roi.width), int(roi.height)
        bx, by = max(1, int(msg.binning_x)), max(1, int(msg.binning_y))
        k[0, :] /= bx
        k[1, :] /= by
        width, height = width // bx, height // by
        if k[0, 0] > 0 and k[1, 1] > 0 and width > 0 and height > 0:
            key = (k.tobytes(), width, height)
            if self._pinholes.get(camera) != key:
                self._pinholes[camera] = key
                self._at(t)
                self.recording.log(
                    camera, rr.Pinhole(image_from_camera=k, resolution=[width, height])
                )
        else:
            self._warn_once(
                topic, "uncalibrated", f"{topic}: uncalibrated camera (K = 0), no pinhole shown"
            )
        self._place_camera(topic, camera, msg.header, t)

    # ------------------------------------------------------------------ geometry

    def _cloud(self, topic: str, msg: Any, t: int) -> None:
        xyz, colors = cloud_points(msg, max_points=self._max_points)
        entity = self._entity(topic)

        def apply(matrix: NDArray[np.float64]) -> None:
            points = transform_points32(matrix, xyz)
            rgb: Any = self._colors.get(topic)
            if rgb is None:
                rgb = colors if colors is not None else colorize(points[:, 2])
            self._at(t)
            self.recording.log(entity, rr.Points3D(points, colors=rgb))

        self._place(topic, msg.header, apply)

    def _scan(self, topic: str, msg: Any, t: int) -> None:
        xyz, intensity = scan_points(msg)
        entity = self._entity(topic)

        def apply(matrix: NDArray[np.float64]) -> None:
            points = transform_points32(matrix, xyz)
            rgb: Any = self._colors.get(topic)
            if rgb is None:
                rgb = colorize(intensity) if intensity is not None else _SCAN_COLOR
            self._at(t)
            self.recording.log(entity, rr.Points3D(points, colors=rgb, radii=0.02))

        self._place(topic, msg.header, apply)

    def _arrow(self, world: NDArray[np.float64], topic: str = "") -> Any:
        return rr.Arrows3D(
            origins=world[:3, 3].reshape(1, 3),
            vectors=(world[:3, 0] * self._arrow_length).reshape(1, 3),
            colors=self._colors.get(topic, _POSE_COLOR),
        )

    def _odometry(self, topic: str, msg: Any, t: int) -> None:
        entity = self._entity(topic)
        pose = pose_matrix(msg.pose.pose)

        def apply(matrix: NDArray[np.float64]) -> None:
            world = matrix @ pose
            track = self._tracks.setdefault(topic, [])
            position = world[:3, 3].copy()
            grew = not track or float(np.linalg.norm(position - track[-1])) >= 0.01
            if grew:
                track.append(position)
                del track[: max(0, len(track) - self._path_keep)]
            self._at(t)
            self.recording.log(entity, self._arrow(world, topic))
            if grew and len(track) >= 2:
                strip = np.asarray(track, dtype=np.float32)
                self.recording.log(f"{entity}/path", rr.LineStrips3D([strip], colors=_PATH_COLOR))

        self._place(topic, msg.header, apply)

    def _pose(self, topic: str, msg: Any, t: int) -> None:
        entity = self._entity(topic)
        pose = pose_matrix(msg.pose)

        def apply(matrix: NDArray[np.float64]) -> None:
            self._at(t)
            self.recording.log(entity, self._arrow(matrix @ pose, topic))

        self._place(topic, msg.header, apply)

    def _pose_array(self, topic: str, msg: Any, t: int) -> None:
        entity = self._entity(topic)
        poses = [pose_matrix(p) for p in msg.poses]

        def apply(matrix: NDArray[np.float64]) -> None:
            self._at(t)
            if not poses:
                self.recording.log(entity, rr.Clear(recursive=False))
                return
            world = np.stack([matrix @ p for p in poses])
            length = self._arrow_length * 0.5  # RViz's PoseArray arrows are shorter
            self.recording.log(
                entity,
                rr.Arrows3D(
                    origins=world[:, :3, 3],
                    vectors=world[:, :3, 0] * length,
                    colors=self._colors.get(topic, _POSE_COLOR),
                ),
            )

        self._place(topic, msg.header, apply)

    def _path(self, topic: str, msg: Any, t: int) -> None:
        entity = self._entity(topic)
        local = np.array(
            [(p.pose.position.x, p.pose.position.y, p.pose.position.z) for p in msg.poses],
            dtype=np.float32,
        ).reshape(-1, 3)

        def apply(matrix: NDArray[np.float64]) -> None:
            self._at(t)
            if len(local) < 2:
                self.recording.log(entity, rr.Clear(recursive=False))
                return
            strip = transform_points32(matrix, local)
            color = self._colors.get(topic, (60, 255, 60))
            self.recording.log(entity, rr.LineStrips3D([strip], colors=color))

        self._place(topic, msg.header, apply)

    def _grid(self, topic: str, msg: Any, t: int) -> None:
        info = msg.info
        width, height = int(info.width), int(info.height)
        data = np.asarray(msg.data, dtype=np.int8).reshape(-1)
        if data.size != width * height:
            text = (
                f"OccupancyGrid.data has {data.size} cells: expected info.width * info.height "
                f"= {width} * {height} = {width * height}"
            )
            raise VizError(text)
        entity = self._entity(topic)
        origin = pose_matrix(info.origin)
        # ROS: row 0 is at the origin (lowest y); Rerun's GridMap draws row 0 at the top.
        blob = np.ascontiguousarray(data.reshape(height, width)[::-1]).tobytes()

        def apply(matrix: NDArray[np.float64]) -> None:
            world = matrix @ origin
            grid = rr.GridMap(
                data=blob,
                format=rr.components.ImageFormat(
                    width=width, height=height, color_model="L", channel_datatype="U8"
                ),
                cell_size=float(info.resolution),
                translation=world[:3, 3],
                quaternion=rr.Quaternion(xyzw=matrix_to_quaternion(world[:3, :3])),
                colormap=_GRID_COLORMAPS[self._schemes.get(topic, "map")],
            )
            self._at(t)
            self.recording.log(entity, grid)

        self._place(topic, msg.header, apply)

    # ------------------------------------------------------------------ markers

    def _marker_msg(self, topic: str, msg: Any, t: int) -> None:
        self._marker(topic, msg, t)

    def _marker_array(self, topic: str, msg: Any, t: int) -> None:
        for marker in msg.markers:
            self._marker(topic, marker, time_to_ns(marker.header.stamp) or t)

    def _marker(self, topic: str, marker: Any, t: int) -> None:
        root = self._entity(topic)
        action = int(marker.action)
        if action == DELETEALL:
            self._at(t)
            self.recording.log(root, rr.Clear(recursive=True))
            prefix = root + "/"
            for key in [k for k in self._marker_kinds if k.startswith(prefix)]:
                del self._marker_kinds[key]
            return
        ns = rr.escape_entity_path_part(marker.ns) if marker.ns else "_"
        entity = f"{root}/{ns}/{int(marker.id)}"
        if action == DELETE:
            self._at(t)
            self.recording.log(entity, rr.Clear(recursive=False))
            self._marker_kinds.pop(entity, None)
            return
        kind = int(marker.type)
        if kind == MESH_RESOURCE:
            self._warn_once(topic, "mesh", f"{topic}: MESH_RESOURCE markers are not shown")
            return

        def apply(matrix: NDArray[np.float64]) -> None:
            archetypes = marker_archetypes(marker, matrix)
            self._at(t)
            if self._marker_kinds.get(entity, kind) != kind:
                self.recording.log(entity, rr.Clear(recursive=False))
            self._marker_kinds[entity] = kind
            if archetypes:
                self.recording.log(entity, *archetypes)

        key = f"{topic}{_KEY_SEP}{ns}/{int(marker.id)}"  # one TF queue per marker
        self.placer.place(key, marker.header.frame_id, time_to_ns(marker.header.stamp), apply)
