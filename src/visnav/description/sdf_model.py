"""One SDF ``<model>`` (what ``/gazebo/spawn_sdf_model`` receives) as URDF text.

visnav's robots are URDF; an SDF model is rewritten into the URDF Gazebo itself would
read the same way, then loaded like any robot:

* each ``<link>`` becomes a link: its ``<pose>`` (relative to the model, SDF's default)
  turns into the joint origins, its ``<inertial>``, ``<collision>`` and ``<visual>``
  geometry (box, sphere, cylinder, mesh) are kept, a visual's diffuse colour becomes its
  material;
* each ``<joint>`` (revolute, continuous, prismatic, fixed, ball -> fixed) becomes a URDF
  joint whose frame is the child link's, with the axis (``<xyz>``, in the joint frame)
  and ``<limit>``;
* ``<sensor>`` elements of a link go into ``<gazebo reference="link">`` and the model's
  ``<plugin>`` elements into ``<gazebo>``, untouched, so gazebo_ros plugins and sensors
  are read as from a URDF;
* a ``<static>`` model is fixed to the world.

Not converted (an error says so): several links without joints between them (URDF is
one tree), nested ``<model>`` and ``<include>``. A ``<plane>`` geometry is dropped.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import numpy.typing as npt

from visnav.description.errors import RobotDescriptionError
from visnav.description.rigid import make_transform

__all__ = ["is_sdf", "sdf_model_to_urdf"]

_Mat = npt.NDArray[np.float64]
_JOINT_TYPES = {
    "revolute": "revolute",
    "continuous": "continuous",
    "prismatic": "prismatic",
    "fixed": "fixed",
    "ball": "fixed",
    "revolute2": "fixed",
    "universal": "fixed",
}


def is_sdf(text: str) -> bool:
    """Whether ``text`` is SDF (an ``<sdf>`` or bare ``<model>`` root) rather than URDF."""
    try:
        root = ET.fromstring(text)  # noqa: S314  (a model description, not network input)
    except ET.ParseError:
        return False
    return root.tag in ("sdf", "model")


def _floats(text: str | None, n: int, what: str) -> list[float]:
    values = (text or "").split()
    try:
        out = [float(v) for v in values]
    except ValueError:
        out = []
    if len(out) != n or not all(math.isfinite(v) for v in out):
        msg = f"SDF {what} is {text!r}: expected {n} finite numbers"
        raise RobotDescriptionError(msg)
    return out


def _pose(element: ET.Element) -> _Mat:
    pose = element.find("pose")
    if pose is None or not (pose.text or "").strip():
        return np.eye(4)
    v = _floats(pose.text, 6, f"<pose> of <{element.tag} name={element.get('name')!r}>")
    return make_transform(v[:3], v[3:])


def _rpy(rot: _Mat) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a rotation (``R = Rz(yaw) Ry(pitch) Rx(roll)``)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(rot[2, 0]))))
    if abs(float(rot[2, 0])) < 1.0 - 1e-12:
        roll = math.atan2(float(rot[2, 1]), float(rot[2, 2]))
        yaw = math.atan2(float(rot[1, 0]), float(rot[0, 0]))
    else:  # gimbal lock: all of the rotation about z in yaw
        roll, yaw = 0.0, math.atan2(-float(rot[0, 1]), float(rot[1, 1]))
    return roll, pitch, yaw


def _origin(parent: ET.Element, matrix: _Mat) -> None:
    xyz = " ".join(f"{v:.9g}" for v in matrix[:3, 3])
    rpy = " ".join(f"{v:.9g}" for v in _rpy(matrix[:3, :3]))
    ET.SubElement(parent, "origin", xyz=xyz, rpy=rpy)


def _geometry(out: ET.Element, geometry: ET.Element | None, where: str) -> bool:
    if geometry is None:
        return False
    g = ET.SubElement(out, "geometry")
    if (box := geometry.find("box")) is not None:
        size = _floats(box.findtext("size", "1 1 1"), 3, f"box size of {where}")
        ET.SubElement(g, "box", size=" ".join(f"{v:.9g}" for v in size))
    elif (sphere := geometry.find("sphere")) is not None:
        ET.SubElement(g, "sphere", radius=sphere.findtext("radius", "1"))
    elif (cylinder := geometry.find("cylinder")) is not None:
        ET.SubElement(
            g,
            "cylinder",
            radius=cylinder.findtext("radius", "1"),
            length=cylinder.findtext("length", "1"),
        )
    elif (mesh := geometry.find("mesh")) is not None:
        attrs = {"filename": (mesh.findtext("uri") or "").strip()}
        if (scale := mesh.findtext("scale")) is not None:
            attrs["scale"] = scale.strip()
        ET.SubElement(g, "mesh", attrs)
    else:
        return False  # plane, heightmap, ...: nothing URDF can hold
    return True


def _link(robot: ET.Element, link: ET.Element, name: str) -> None:
    out = ET.SubElement(robot, "link", name=name)
    inertial = link.find("inertial")
    if inertial is not None:
        i_out = ET.SubElement(out, "inertial")
        _origin(i_out, _pose(inertial))
        ET.SubElement(i_out, "mass", value=inertial.findtext("mass", "1"))
        inertia = inertial.find("inertia")
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        defaults = {"ixx": "1", "iyy": "1", "izz": "1"}
        values = {
            k: (inertia.findtext(k) if inertia is not None else None) or defaults.get(k, "0")
            for k in keys
        }
        ET.SubElement(i_out, "inertia", {k: v.strip() for k, v in values.items()})
    for kind in ("collision", "visual"):
        for k, element in enumerate(link.findall(kind)):
            part = ET.Element(kind, name=element.get("name") or f"{name}_{kind}_{k}")
            _origin(part, _pose(element))
            if not _geometry(part, element.find("geometry"), f"link {name!r}"):
                continue
            diffuse = element.findtext("material/diffuse")
            if kind == "visual" and diffuse:
                rgba = diffuse.split()
                rgba = [*rgba, "1"] if len(rgba) == 3 else rgba
                material = ET.SubElement(part, "material", name=f"{name}_material_{k}")
                ET.SubElement(material, "color", rgba=" ".join(rgba))
            out.append(part)


def sdf_model_to_urdf(text: str, *, name: str | None = None) -> str:
    """URDF text of the one ``<model>`` in ``text`` (see the module docstring).

    Args:
        text: SDF XML: ``<sdf><model>...</model></sdf>`` or a bare ``<model>``.
        name: the robot's name (default: the model's).

    Raises:
        RobotDescriptionError: not SDF, no or several models, or a model URDF cannot hold.
    """
    try:
        root = ET.fromstring(text)  # noqa: S314
    except ET.ParseError as exc:
        msg = f"SDF is not well-formed XML: {exc}"
        raise RobotDescriptionError(msg) from exc
    models = [root] if root.tag == "model" else root.findall("model")
    if root.tag not in ("sdf", "model") or len(models) != 1:
        msg = (
            f"expected SDF with exactly one <model> (root <{root.tag}> holds {len(models)}); "
            "a world or several models cannot be spawned as one model"
        )
        raise RobotDescriptionError(msg)
    model = models[0]
    if model.find("model") is not None or model.find("include") is not None:
        msg = "SDF nested <model> and <include> are not supported by visnav's spawn_sdf_model"
        raise RobotDescriptionError(msg)
    robot_name = name or model.get("name") or "model"
    robot = ET.Element("robot", name=robot_name)
    links = {link.get("name") or f"link_{k}": link for k, link in enumerate(model.findall("link"))}
    if not links:
        msg = f"SDF model {robot_name!r} has no <link>"
        raise RobotDescriptionError(msg)
    poses = {n: _pose(link) for n, link in links.items()}
    children: set[str] = set()
    joints = []
    for joint in model.findall("joint"):
        parent = (joint.findtext("parent") or "").strip()
        child = (joint.findtext("child") or "").strip()
        jtype = _JOINT_TYPES.get(joint.get("type", ""))
        if child not in links or jtype is None:
            msg = (
                f"SDF joint {joint.get('name')!r}: type {joint.get('type')!r}, child "
                f"{child!r} (links: {sorted(links)})"
            )
            raise RobotDescriptionError(msg)
        children.add(child)
        joints.append((joint, parent, child, jtype))
    roots = [n for n in links if n not in children]
    static = (model.findtext("static") or "").strip().lower() in ("1", "true")
    if len(roots) != 1:
        msg = (
            f"SDF model {robot_name!r} has {len(roots)} links that are no joint's child "
            f"({roots}); visnav spawns a model as one tree: join them with fixed joints"
        )
        raise RobotDescriptionError(msg)
    if static:
        ET.SubElement(robot, "link", name="world")
        fixed = ET.SubElement(robot, "joint", name=f"{robot_name}_static", type="fixed")
        ET.SubElement(fixed, "parent", link="world")
        ET.SubElement(fixed, "child", link=roots[0])
        _origin(fixed, poses[roots[0]])
    for n, link in links.items():
        _link(robot, link, n)
    for joint, parent, child, jtype in joints:
        out = ET.SubElement(robot, "joint", name=joint.get("name") or child, type=jtype)
        if parent in ("world", ""):
            msg = f"SDF joint {joint.get('name')!r} to the world: make the model <static>"
            raise RobotDescriptionError(msg)
        if parent not in links:
            msg = f"SDF joint {joint.get('name')!r}: parent {parent!r} is not a link"
            raise RobotDescriptionError(msg)
        ET.SubElement(out, "parent", link=parent)
        ET.SubElement(out, "child", link=child)
        _origin(out, np.linalg.inv(poses[parent]) @ poses[child])
        if jtype == "fixed":
            continue
        axis = np.array(_floats(joint.findtext("axis/xyz", "0 0 1"), 3, "joint axis"))
        axis = _pose(joint)[:3, :3] @ axis
        ET.SubElement(out, "axis", xyz=" ".join(f"{v:.9g}" for v in axis))
        limit = joint.find("axis/limit")
        attrs = {"effort": "100", "velocity": "100"}
        if limit is not None:
            for key in ("lower", "upper", "effort", "velocity"):
                if (value := limit.findtext(key)) is not None:
                    attrs[key] = value.strip()
        if jtype != "continuous" or limit is not None:
            attrs.setdefault("lower", "0")
            attrs.setdefault("upper", "0")
            ET.SubElement(out, "limit", attrs)
        dynamics = joint.find("axis/dynamics")
        if dynamics is not None:
            ET.SubElement(
                out,
                "dynamics",
                damping=(dynamics.findtext("damping") or "0").strip(),
                friction=(dynamics.findtext("friction") or "0").strip(),
            )
    for n, link in links.items():
        sensors = link.findall("sensor")
        if sensors:
            gazebo = ET.SubElement(robot, "gazebo", reference=n)
            gazebo.extend(sensors)
    plugins = model.findall("plugin")
    if plugins:
        ET.SubElement(robot, "gazebo").extend(plugins)
    return ET.tostring(robot, encoding="unicode")
