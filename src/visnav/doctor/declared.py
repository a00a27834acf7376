"""What the system declares about its topics: ``--expect`` merged with ``robot_description``.

A URDF published on ``robot_description`` with Gazebo ``<sensor>`` blocks declares,
per topic, the update rate, image size, horizontal field of view, clip range, frame
and encoding (parsed with :func:`visnav.description.gazebo.parse_gazebo_extensions`, which
resolves the exact topic names the ``gazebo_ros`` plugins publish). It also says
which joints are fixed (their transforms belong on ``/tf_static``). ``--expect``
values win over the URDF's.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from visnav.doctor.expect import Expectations
from visnav.errors import VisnavError

__all__ = ["Declared", "DeclaredJoint", "DeclaredTopic", "declared_from"]

_LOG = logging.getLogger("visnav.doctor")


@dataclass(frozen=True)
class DeclaredTopic:
    """Declared properties of one topic (None: not declared).

    Attributes:
        topic: topic name.
        rate: Hz.
        width: image width in pixels.
        height: image height in pixels.
        hfov: horizontal field of view, radians.
        clip_far: sensor range, metres.
        frame_id: header frame_id.
        encoding: image encoding.
        source: where the declaration comes from (for evidence).
    """

    topic: str
    rate: float | None = None
    width: int | None = None
    height: int | None = None
    hfov: float | None = None
    clip_far: float | None = None
    frame_id: str | None = None
    encoding: str | None = None
    source: str = ""


@dataclass(frozen=True)
class DeclaredJoint:
    """A joint of the robot description: what places ``child`` on ``parent``.

    Attributes:
        name: the joint's name.
        parent: parent link.
        child: child link.
        moves: False for a fixed joint (its transform belongs on ``/tf_static``).
        xyz: the joint origin's translation, metres.
        rpy: the joint origin's roll, pitch, yaw, radians.
    """

    name: str
    parent: str
    child: str
    moves: bool
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Declared:
    """Declarations by topic, and the robot's joints.

    Attributes:
        topics: declared topic properties.
        fixed_joints: child link -> parent link of every fixed joint.
        moving_joints: child link -> parent link of every joint that moves.
        joints: child link -> the joint placing it (name, parent, origin).
    """

    topics: Mapping[str, DeclaredTopic] = field(default_factory=dict)
    fixed_joints: Mapping[str, str] = field(default_factory=dict)
    moving_joints: Mapping[str, str] = field(default_factory=dict)
    joints: Mapping[str, DeclaredJoint] = field(default_factory=dict)

    def get(self, topic: str) -> DeclaredTopic | None:
        """The declaration of ``topic``, if any."""
        return self.topics.get(topic)


def _prefix(namespace: str, topic: str) -> str:
    ns = namespace.rstrip("/")
    return f"{ns}{topic}" if ns else topic


def _from_urdf(text: str, topic: str) -> Declared:
    # Parsing the URDF is the simulator's job; imported here so doctor runs without it.
    from visnav.description.gazebo import parse_gazebo_extensions  # noqa: PLC0415
    from visnav.description.urdf import parse_urdf  # noqa: PLC0415

    urdf = parse_urdf(text, source=topic)
    ext = parse_gazebo_extensions(urdf)
    namespace = topic.rsplit("/", 1)[0]
    out: dict[str, DeclaredTopic] = {}
    for cam in ext.cameras:
        src = f"robot_description sensor '{cam.name}'"
        for name, encoding, far in (
            (cam.image_topic, cam.encoding, None),
            (cam.camera_info_topic, None, None),
            (cam.depth_topic, cam.depth_encoding, cam.depth_range[1]),
            (cam.depth_info_topic, None, cam.depth_range[1]),
            (cam.points_topic, None, cam.depth_range[1]),
        ):
            if name:
                full = _prefix(namespace, name)
                out[full] = DeclaredTopic(
                    full,
                    rate=cam.update_rate or None,
                    width=cam.width,
                    height=cam.height,
                    hfov=cam.hfov,
                    clip_far=far,
                    frame_id=cam.frame_id,
                    encoding=encoding,
                    source=src,
                )
    for odo in ext.odometry:
        full = _prefix(namespace, odo.topic)
        out[full] = DeclaredTopic(
            full,
            rate=odo.update_rate or None,
            frame_id=odo.frame_id,
            source=f"robot_description plugin '{odo.plugin_name}'",
        )
    for dd in ext.diff_drives:
        if dd.publish_odom:
            full = _prefix(namespace, dd.odometry_topic)
            out[full] = DeclaredTopic(
                full,
                rate=dd.update_rate or None,
                frame_id=dd.odometry_frame,
                source=f"robot_description plugin '{dd.plugin_name}'",
            )
    fixed = {j.child: j.parent for j in urdf.joints.values() if not j.moves}
    moving = {j.child: j.parent for j in urdf.joints.values() if j.moves}
    joints = {
        j.child: DeclaredJoint(j.name, j.parent, j.child, j.moves, j.origin.xyz, j.origin.rpy)
        for j in urdf.joints.values()
    }
    return Declared(out, fixed, moving, joints)


def declared_from(
    robot_description: str | None,
    robot_description_topic: str,
    expect: Expectations | None,
) -> Declared:
    """Merge the URDF's declarations with ``--expect`` (expect wins).

    A URDF that does not parse is ignored (logged at debug level): doctor checks the
    data, the simulator reports URDF errors.
    """
    declared = Declared()
    if robot_description:
        try:
            declared = _from_urdf(
                robot_description, robot_description_topic or "/robot_description"
            )
        except (VisnavError, ValueError, KeyError, TypeError) as exc:
            _LOG.debug("robot_description not used: %s", exc)
    if expect is None:
        return declared
    topics = dict(declared.topics)
    for name, exp in expect.topics.items():
        base = topics.get(name, DeclaredTopic(name))
        fields = (exp.rate, exp.hfov, exp.clip_far, exp.frame_id, exp.encoding)
        if all(v is None for v in fields):
            continue
        src = f"--expect {expect.source}"
        topics[name] = replace(
            base,
            rate=base.rate if exp.rate is None else exp.rate,
            hfov=base.hfov if exp.hfov is None else exp.hfov,
            clip_far=base.clip_far if exp.clip_far is None else exp.clip_far,
            frame_id=base.frame_id if exp.frame_id is None else exp.frame_id,
            encoding=base.encoding if exp.encoding is None else exp.encoding,
            source=f"{base.source}; {src}" if base.source else src,
        )
    return Declared(topics, declared.fixed_joints, declared.moving_joints, declared.joints)
