"""``<gazebo>`` blocks of a URDF -> typed sensor and plugin configurations.

Interprets the blocks the way Gazebo classic and ``gazebo_ros_pkgs`` do and
resolves the exact topic names and frame ids the plugins publish:

* ``<sensor type="camera">`` + ``libgazebo_ros_camera.so``: ``<camera_name>``
  (default: the sensor name) ``/image_raw`` and ``/camera_info`` in the plugin
  node's namespace (``<ros><namespace>``) after ``<ros><remapping>`` rules; the
  frame is ``<frame_name>`` (default: the sensor's link). ROS 1 spellings
  (``robotNamespace``, ``cameraName``, ``imageTopicName``,
  ``cameraInfoTopicName``, ``frameName``, ``distortionK1``..) follow
  ``gazebo_ros_camera_utils``: ``<robotNamespace>/<cameraName>/<imageTopicName>``
  and the frame prefixed like ``tf::resolve(tf_prefix, frameName)``.
  K is ``fx = fy = width / (2 tan(hfov / 2))`` and the principal point
  ``cx, cy = width / 2, height / 2`` (``<cx>``/``<cy>``, ROS 1 ``<Cx>``/``<Cy>``,
  override it; Gazebo publishes ``(width + 1) / 2``, see
  :func:`~visnav.description.gazebo_specs.default_principal_point`); visnav renders exactly this K.
* ``<sensor type="depth">`` + ``libgazebo_ros_camera.so`` (ROS 2) adds
  ``<camera_name>/depth/image_raw``, ``/depth/camera_info`` and ``/points``;
  ``libgazebo_ros_depth_camera.so`` / ``libgazebo_ros_openni_kinect.so``
  (ROS 1) publish ``ir/image_raw``, ``ir/camera_info``, ``depth/image_raw``,
  ``depth/camera_info`` and ``points`` unless renamed.
* ``libgazebo_ros_p3d.so``: ``nav_msgs/Odometry`` on ``odom`` (ROS 2,
  remappable) or ``<topicName>`` (ROS 1), header frame ``frame_name``
  (default ``world``), child frame the body.
* ``libgazebo_ros_diff_drive.so``: ``cmd_vel`` in, ``odom`` out with ROS 2
  defaults (``publish_odom`` and ``publish_odom_tf`` false) or the ROS 1 ones
  (``commandTopic``, ``odometryTopic``, ``publishTf`` true ...).
* ``<sensor type="imu">`` + ``libgazebo_ros_imu_sensor.so``: ``~/out``
  (``<ns>/<plugin name>/out``) in ROS 2, ``<robotNamespace>/<topicName>`` in ROS 1.
* ``libgazebo_ros_joint_state_publisher.so``: ``joint_states``.
* ``libgazebo_ros_imu.so`` (ROS 1 model plugin), ``libgazebo_ros_skid_steer_drive.so`` and
  ``libgazebo_ros_planar_move.so``: see :mod:`visnav.description._gazebo_bases`.
* ``libvisnav_quadrotor.so`` (visnav's own, no Gazebo counterpart): the vehicle
  limits of :class:`~visnav.sim.vehicles.quadrotor.QuadrotorParams` as child
  elements, ``<body_name>`` (default the root link), and the command topics
  ``command/trajectory`` and ``command/pose`` in its ``<ros>`` namespace.

Every element or plugin visnav does not model produces a warning naming it
and the file and line where it is written (returned in :attr:`GazeboExtensions.warnings`;
:func:`~visnav.description.robot.load_robot` logs one grouped summary). Bad values (a
sensor on a link that does not exist, zero image width, an hfov outside
(0, pi), a p3d ``body_name`` that is not a link ...) raise
:class:`~visnav.description.urdf.RobotDescriptionError` naming the file, line, element
and fix.

Where visnav differs from Gazebo: the default camera frame is the sensor's own
link (Gazebo reports the link the sensor ends up on after fixed-joint lumping,
often ``base_link``); depth outside the valid range is NaN for both ROS 1 and
ROS 2 plugins (ROS 2's gazebo_ros_camera writes -inf/+inf); depth noise is
applied (Gazebo ignores ``<noise>`` on depth sensors); p3d also broadcasts
``frame_name -> body`` on TF (by default when the body is the root link and no
diff drive publishes ``odom -> body``; ``<publish_tf>`` decides explicitly).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import cast

from visnav.description._gazebo_bases import parse_imu_model, parse_planar_move, parse_skid_steer
from visnav.description._gazebo_plugins import (
    link_properties,
    parse_diff_drive,
    parse_joint_state_publisher,
    parse_p3d,
    parse_quadrotor,
)
from visnav.description._gazebo_rays import RAY_SENSOR_TYPES, parse_ray
from visnav.description._gazebo_sensors import parse_camera, parse_imu
from visnav.description._ros_control import parse_ros_control
from visnav.description._sdf_reader import SdfReader
from visnav.description.gazebo_specs import (
    CameraSpec,
    DiffDriveSpec,
    GaussianNoise,
    GazeboExtensions,
    ImuModelSpec,
    ImuSpec,
    JointStatePublisherSpec,
    LensDistortion,
    LinkProperties,
    OdometrySpec,
    PlanarMoveSpec,
    QuadrotorSpec,
    RaySpec,
    RosControlSpec,
    RosNodeNames,
    SkidSteerSpec,
    default_principal_point,
    ros1_join,
    tf_resolve,
)
from visnav.description.urdf import RobotDescriptionError, Urdf

__all__ = [
    "CameraSpec",
    "DiffDriveSpec",
    "GaussianNoise",
    "GazeboExtensions",
    "ImuSpec",
    "JointStatePublisherSpec",
    "LensDistortion",
    "LinkProperties",
    "OdometrySpec",
    "QuadrotorSpec",
    "RosNodeNames",
    "default_principal_point",
    "parse_gazebo_extensions",
    "ros1_join",
    "tf_resolve",
]

_JOINT_NOOPS = ("preserveFixedJoint", "disableFixedJointLumping", "provideFeedback")


def parse_gazebo_extensions(urdf: Urdf) -> GazeboExtensions:
    """Interpret the ``<gazebo>`` blocks of a parsed URDF.

    Args:
        urdf: the robot (its :attr:`~visnav.description.urdf.Urdf.gazebo` blocks and links).

    Returns:
        The sensors, plugins, link properties and warnings.

    Raises:
        RobotDescriptionError: a sensor on a missing link, an invalid camera
            (zero width, hfov outside (0, pi), far <= near ...), a p3d body or a
            diff drive joint that does not exist, or malformed values.
    """
    reader = SdfReader(urdf.doc)
    cameras: list[CameraSpec] = []
    imus: list[ImuSpec] = []
    rays: list[RaySpec] = []
    odometry: list[OdometrySpec] = []
    drives: list[DiffDriveSpec] = []
    jsps: list[JointStatePublisherSpec] = []
    quads: list[QuadrotorSpec] = []
    ros_controls: list[RosControlSpec] = []
    bases: dict[type, list[object]] = {ImuModelSpec: [], SkidSteerSpec: [], PlanarMoveSpec: []}
    p3d_elements: list[ET.Element] = []
    props: dict[str, LinkProperties] = {}
    handlers: dict[str, Callable[[SdfReader, ET.Element, Urdf], object]] = {
        "libgazebo_ros_p3d.so": parse_p3d,
        "libgazebo_ros_diff_drive.so": parse_diff_drive,
        "libgazebo_ros_joint_state_publisher.so": parse_joint_state_publisher,
        "libvisnav_quadrotor.so": parse_quadrotor,
        "libgazebo_ros_control.so": parse_ros_control,
        "libgazebo_ros_imu.so": parse_imu_model,
        "libgazebo_ros_skid_steer_drive.so": parse_skid_steer,
        "libgazebo_ros_planar_move.so": parse_planar_move,
    }
    for block in urdf.gazebo:
        element = block.element
        ref = block.reference
        if ref is None:
            for child in element:
                if child.tag == "plugin":
                    filename = child.get("filename") or ""
                    handler = handlers.get(filename)
                    if handler is None:
                        reader.warn(
                            child,
                            f"model plugin {filename!r} (name "
                            f"{child.get('name')!r}) is not supported and is "
                            "ignored",
                        )
                        continue
                    result = handler(reader, child, urdf)
                    if isinstance(result, OdometrySpec):
                        odometry.append(result)
                        p3d_elements.append(child)
                    elif isinstance(result, DiffDriveSpec):
                        drives.append(result)
                    elif isinstance(result, JointStatePublisherSpec):
                        jsps.append(result)
                    elif isinstance(result, QuadrotorSpec):
                        quads.append(result)
                    elif isinstance(result, RosControlSpec):
                        ros_controls.append(result)
                    elif type(result) in bases:
                        bases[type(result)].append(result)
                elif child.tag == "sensor":
                    raise reader.error(
                        child,
                        "a <sensor> needs a link: it is inside a <gazebo> block without reference",
                        'write <gazebo reference="camera_link"><sensor ...>',
                    )
                elif child.tag in ("static", "self_collide", "selfCollide"):
                    reader.warn(
                        child,
                        f"model property <{child.tag}> is not modelled (robots "
                        "are dynamic and do not collide with themselves)",
                    )
                else:
                    reader.warn(
                        child,
                        f"<{child.tag}> in a model-level <gazebo> block is not "
                        "supported and is ignored",
                    )
            continue
        sensors = element.findall("sensor")
        if ref in urdf.joints and ref not in urdf.links:
            if sensors:
                raise reader.error(
                    sensors[0],
                    f"sensor on joint {ref!r}: sensors attach to links",
                    f"use the joint's child link {urdf.joints[ref].child!r} as the reference",
                )
            for child in element:
                if child.tag not in _JOINT_NOOPS:
                    reader.warn(
                        child,
                        f"gazebo reference joint {ref!r}: <{child.tag}> is not "
                        "modelled and is ignored",
                    )
            continue
        if ref not in urdf.links:
            target = sensors[0] if sensors else element
            what = "sensor reference" if sensors else "gazebo reference"
            raise reader.error(
                target,
                f"{what} {ref!r} is not a link of robot {urdf.name!r}",
                f"set reference to one of: {', '.join(urdf.links)}",
            )
        link_props = link_properties(reader, element, ref)
        if link_props is not None:
            props[ref] = link_props
        for sensor in sensors:
            kind = sensor.get("type") or ""
            if kind == "camera":
                cameras.append(parse_camera(reader, sensor, ref, "camera", urdf.name))
            elif kind in ("depth", "depth_camera", "rgbd_camera"):
                cameras.append(parse_camera(reader, sensor, ref, "depth", urdf.name))
            elif kind == "imu":
                imus.append(parse_imu(reader, sensor, ref, urdf.name))
            elif kind in RAY_SENSOR_TYPES:
                rays.append(parse_ray(reader, sensor, ref, urdf.name))
            else:
                reader.warn(
                    sensor,
                    f"sensor {sensor.get('name')!r} of type {kind!r} is not "
                    "supported (camera, depth, imu and ray are) and is ignored",
                )
    _check_unique(urdf, [*cameras, *imus, *rays])
    odometry = _p3d_tf_without_second_parent(reader, odometry, p3d_elements, drives)
    if len(quads) > 1:
        raise RobotDescriptionError(
            f"{urdf.source}: {len(quads)} libvisnav_quadrotor.so plugins: one robot flies with "
            'one controller. Fix: keep one <plugin filename="libvisnav_quadrotor.so">'
        )
    return GazeboExtensions(
        cameras=tuple(cameras), imus=tuple(imus), rays=tuple(rays), odometry=tuple(odometry),
        diff_drives=tuple(drives), joint_state_publishers=tuple(jsps), quadrotors=tuple(quads),
        link_properties=props, warnings=tuple(reader.warnings), ros_control=tuple(ros_controls),
        imu_plugins=tuple(cast("list[ImuModelSpec]", bases[ImuModelSpec])),
        skid_steer_drives=tuple(cast("list[SkidSteerSpec]", bases[SkidSteerSpec])),
        planar_moves=tuple(cast("list[PlanarMoveSpec]", bases[PlanarMoveSpec])),
    )  # fmt: skip


def _p3d_tf_without_second_parent(
    reader: SdfReader,
    odometry: list[OdometrySpec],
    elements: list[ET.Element],
    drives: list[DiffDriveSpec],
) -> list[OdometrySpec]:
    """Turn off p3d's default TF where a diff drive already parents the same frame.

    p3d broadcasts ``frame_name -> body`` by default when the body is the root link;
    a diff drive publishing ``odom -> base_footprint`` makes that a second parent of
    the same frame, which TF rejects. An explicit ``<publish_tf>true`` is kept, with
    a warning.
    """
    out: list[OdometrySpec] = []
    for parsed, element in zip(odometry, elements, strict=True):
        spec = parsed
        owner = next(
            (d for d in drives if d.publish_odom_tf and d.robot_base_frame == spec.child_frame_id),
            None,
        )
        if spec.publish_tf and owner is not None:
            if element.find("publish_tf") is None:
                spec = replace(spec, publish_tf=False)
            else:
                reader.warn(
                    element,
                    f"plugin {spec.plugin_name!r} (libgazebo_ros_p3d.so): publish_tf gives "
                    f"{spec.child_frame_id!r} a second parent ({spec.frame_id!r} besides "
                    f"{owner.odometry_frame!r} from diff drive {owner.plugin_name!r})",
                )
        out.append(spec)
    return out


def _check_unique(urdf: Urdf, specs: Sequence[CameraSpec | ImuSpec | RaySpec]) -> None:
    seen: dict[str, str] = {}
    for spec in specs:
        if spec.name in seen:
            raise RobotDescriptionError(
                f"{urdf.source}: two sensors are named {spec.name!r} (on links {seen[spec.name]!r}"
                f" and {spec.link!r}). Fix: give every <sensor> a unique name"
            )
        seen[spec.name] = spec.link
