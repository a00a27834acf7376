"""URDF robot model: typed, immutable dataclasses, XML line tracking and resource lookup.

Produced by :func:`visnav.description.urdf.parse_urdf`. ``T_a_b`` transforms map
points from frame ``b`` into frame ``a``; :meth:`Origin.matrix` of a joint is
``T_parent_child``.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal
from xml.parsers import expat

import numpy as np
from numpy.typing import NDArray

from visnav.description.errors import RobotDescriptionError
from visnav.description.rigid import make_transform
from visnav.description.xacro_locations import LOCATION_ATTRIBUTE

__all__ = [
    "Box",
    "Capsule",
    "Collision",
    "Cylinder",
    "GazeboBlock",
    "Geometry",
    "Inertial",
    "Joint",
    "JointDynamics",
    "JointLimit",
    "JointType",
    "Link",
    "MESH_EXTENSIONS",
    "Material",
    "Mesh",
    "Mimic",
    "Origin",
    "RobotDescriptionError",
    "Sphere",
    "Urdf",
    "Visual",
    "XmlDoc",
    "find_package",
    "iter_links_depth_first",
    "parse_xml",
    "resolve_resource",
]

MESH_EXTENSIONS = (".dae", ".stl", ".obj", ".msh")
"""Mesh file extensions visnav reads (compared case-insensitively; see mesh_files)."""

JointType = Literal["fixed", "revolute", "continuous", "prismatic", "floating"]


# --------------------------------------------------------------------------- XML with lines


@dataclass(frozen=True)
class XmlDoc:
    """A parsed XML document's source name and each element's line number.

    ``origins`` holds, for the elements of an expanded Xacro document, the file and
    line where each was written (:mod:`visnav.description.xacro_locations`).
    """

    source: str
    lines: Mapping[int, int] = field(repr=False)
    origins: Mapping[int, str] = field(default_factory=dict, repr=False)

    def where(self, element: ET.Element) -> str:
        """Return ``"file:line"`` where an element of this document was written."""
        origin = self.origins.get(id(element))
        if origin is not None:
            return origin
        line = self.lines.get(id(element))
        return f"{self.source}:{line}" if line is not None else self.source

    def error(self, element: ET.Element, what: str, fix: str) -> RobotDescriptionError:
        """Return an error naming this document, the element's line and tag, the problem and fix."""
        return RobotDescriptionError(f"{self.where(element)}: <{element.tag}>: {what}. Fix: {fix}")


def parse_xml(text: str, source: str) -> tuple[ET.Element, XmlDoc]:
    """Parse XML text, recording each element's line number.

    An element's :data:`~visnav.description.xacro_locations.LOCATION_ATTRIBUTE`
    (left by Xacro expansion) is taken off it and becomes its location.

    Args:
        text: the XML document.
        source: the file name (or ``"<string>"``) used in error messages.

    Returns:
        The root element and the :class:`XmlDoc` that locates elements.

    Raises:
        RobotDescriptionError: the text is not well-formed XML.
    """
    builder = ET.TreeBuilder()
    lines: dict[int, int] = {}
    origins: dict[int, str] = {}
    parser = expat.ParserCreate()

    def start(tag: str, attrs: dict[str, str]) -> None:
        origin = attrs.pop(LOCATION_ATTRIBUTE, None)
        element = builder.start(tag, attrs)
        lines[id(element)] = parser.CurrentLineNumber
        if origin:
            origins[id(element)] = origin

    def end(tag: str) -> None:
        builder.end(tag)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        msg = (
            f"{source}:{exc.lineno}:{exc.offset}: malformed XML: "
            f"{expat.errors.messages[exc.code]}. Fix: correct the XML syntax at that position"
        )
        raise RobotDescriptionError(msg) from exc
    return builder.close(), XmlDoc(source=source, lines=lines, origins=origins)


# --------------------------------------------------------------------------- dataclasses


@dataclass(frozen=True)
class Origin:
    """A URDF ``<origin xyz rpy>``: translation in metres, fixed-axis roll/pitch/yaw."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def matrix(self) -> NDArray[np.float64]:
        """Return the 4x4 transform ``T_parent_child`` this origin describes."""
        return make_transform(self.xyz, self.rpy)


@dataclass(frozen=True)
class Box:
    """A box; ``size`` is the full edge lengths x, y, z in metres."""

    size: tuple[float, float, float]


@dataclass(frozen=True)
class Cylinder:
    """A cylinder along the local z axis, centred at the origin."""

    radius: float
    length: float


@dataclass(frozen=True)
class Sphere:
    """A sphere centred at the origin."""

    radius: float


@dataclass(frozen=True)
class Capsule:
    """A capsule along z; ``length`` is the cylinder part (URDF 1.x ``capsule``)."""

    radius: float
    length: float


@dataclass(frozen=True)
class Mesh:
    """A mesh file: the URI as written and the resolved existing path."""

    filename: str
    path: Path
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)


Geometry = Box | Cylinder | Sphere | Capsule | Mesh


@dataclass(frozen=True)
class Material:
    """A material: RGBA colour in 0..1 (None if only a texture is given)."""

    name: str
    rgba: tuple[float, float, float, float] | None = None
    texture: str | None = None


@dataclass(frozen=True)
class Visual:
    """A link's visual geometry."""

    name: str
    origin: Origin
    geometry: Geometry
    material: Material | None = None


@dataclass(frozen=True)
class Collision:
    """A link's collision geometry."""

    name: str
    origin: Origin
    geometry: Geometry


@dataclass(frozen=True)
class Inertial:
    """Mass properties; ``inertia`` is (ixx, ixy, ixz, iyy, iyz, izz) in the origin's frame."""

    origin: Origin
    mass: float
    inertia: tuple[float, float, float, float, float, float]

    def inertia_matrix(self) -> NDArray[np.float64]:
        """Return the 3x3 inertia tensor in the inertial origin's frame."""
        ixx, ixy, ixz, iyy, iyz, izz = self.inertia
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


@dataclass(frozen=True)
class Link:
    """A URDF link."""

    name: str
    inertial: Inertial | None = None
    visuals: tuple[Visual, ...] = ()
    collisions: tuple[Collision, ...] = ()


@dataclass(frozen=True)
class JointLimit:
    """``<limit>``: position bounds (rad or m), effort (N or Nm) and velocity."""

    lower: float = 0.0
    upper: float = 0.0
    effort: float = 0.0
    velocity: float = 0.0


@dataclass(frozen=True)
class JointDynamics:
    """``<dynamics>``: viscous damping and Coulomb friction."""

    damping: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True)
class Mimic:
    """``<mimic>``: this joint = ``multiplier * joint + offset``."""

    joint: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Joint:
    """A URDF joint; ``axis`` is a unit vector in the child (joint) frame."""

    name: str
    type: JointType
    parent: str
    child: str
    origin: Origin = field(default_factory=Origin)
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    limit: JointLimit | None = None
    dynamics: JointDynamics = field(default_factory=JointDynamics)
    mimic: Mimic | None = None

    @property
    def moves(self) -> bool:
        """True for joints with a degree of freedom (everything but ``fixed``)."""
        return self.type != "fixed"


@dataclass(frozen=True)
class GazeboBlock:
    """A ``<gazebo>`` element (``reference`` is a link or joint name, or None)."""

    reference: str | None
    element: ET.Element = field(repr=False)


@dataclass(frozen=True)
class Urdf:
    """A parsed, validated URDF robot."""

    name: str
    links: Mapping[str, Link]
    joints: Mapping[str, Joint]
    root: str
    materials: Mapping[str, Material] = field(default_factory=dict)
    gazebo: tuple[GazeboBlock, ...] = ()
    doc: XmlDoc = field(default_factory=lambda: XmlDoc("<string>", {}), repr=False)
    base_dir: Path | None = None
    warnings: tuple[str, ...] = ()
    transmissions: tuple[ET.Element, ...] = field(default=(), repr=False)
    """The ``<transmission>`` elements (read by the ``libgazebo_ros_control.so`` parser)."""

    @property
    def source(self) -> str:
        """The file name (or ``"<string>"``) the robot was read from."""
        return self.doc.source

    def child_joints(self, link: str) -> list[Joint]:
        """Return the joints whose parent is ``link``, in document order."""
        return [j for j in self.joints.values() if j.parent == link]

    def parent_joint(self, link: str) -> Joint | None:
        """Return the joint whose child is ``link`` (None for the root)."""
        for joint in self.joints.values():
            if joint.child == link:
                return joint
        return None


# --------------------------------------------------------------------------- resources


def _package_name(directory: Path) -> str | None:
    manifest = directory / "package.xml"
    if not manifest.is_file():
        return None
    try:
        match = re.search(r"<name>\s*([^<\s]+)\s*</name>", manifest.read_text(errors="replace"))
    except OSError:
        return None
    return match.group(1) if match else None


def _package_candidates(
    package: str, base_dir: Path | None, packages: Mapping[str, Path | str] | None
) -> list[Path]:
    out: list[Path] = []
    if packages and package in packages:
        out.append(Path(packages[package]))
    if base_dir is not None:
        for ancestor in (base_dir, *base_dir.parents):
            if ancestor.name == package or _package_name(ancestor) == package:
                out.append(ancestor)
            out.append(ancestor / package)
    for root in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep):
        if root:
            out.append(Path(root) / package)
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            out.append(Path(prefix) / "share" / package)
    return out


def find_package(
    name: str, *, base_dir: Path | None, packages: Mapping[str, Path | str] | None = None
) -> Path | None:
    """Return the directory of ROS package ``name`` (see :func:`resolve_resource`), or None."""
    for candidate in _package_candidates(name, base_dir, packages):
        if candidate.is_dir():
            return candidate.resolve()
    return None


def resolve_resource(
    uri: str,
    *,
    base_dir: Path | None,
    packages: Mapping[str, Path | str] | None = None,
) -> tuple[Path | None, list[Path]]:
    """Resolve a URDF resource URI to an existing file.

    ``package://pkg/rel`` is searched in ``packages[pkg]``, in the ancestors of
    ``base_dir`` (a directory named ``pkg`` or whose ``package.xml`` names it,
    or a ``pkg`` sub-directory), then ``ROS_PACKAGE_PATH`` entries and
    ``AMENT_PREFIX_PATH/share``. ``model://m/rel`` is searched in
    ``GAZEBO_MODEL_PATH``. ``file://`` and absolute paths are taken as they are;
    other relative paths are relative to ``base_dir``.

    Args:
        uri: the filename as written in the URDF.
        base_dir: the directory of the URDF file (None for a string without one).
        packages: explicit package name -> directory mapping.

    Returns:
        The existing path (None if not found) and every candidate tried.
    """
    candidates: list[Path] = []
    if uri.startswith("package://"):
        rest = uri[len("package://") :]
        package, _, rel = rest.partition("/")
        candidates = [root / rel for root in _package_candidates(package, base_dir, packages)]
    elif uri.startswith("model://"):
        rest = uri[len("model://") :]
        for root in os.environ.get("GAZEBO_MODEL_PATH", "").split(os.pathsep):
            if root:
                candidates.append(Path(root) / rest)
        if base_dir is not None:
            candidates.append(base_dir / rest)
    elif uri.startswith("file://"):
        candidates = [Path(uri[len("file://") :])]
    else:
        path = Path(uri)
        candidates = [path] if path.is_absolute() or base_dir is None else [base_dir / path]
    seen: list[Path] = []
    for candidate in candidates:
        if candidate in seen:
            continue
        seen.append(candidate)
        if candidate.is_file():
            return candidate.resolve(), seen
    return None, seen


def iter_links_depth_first(urdf: Urdf) -> Iterable[tuple[Link, Joint | None]]:
    """Yield each link with its parent joint, parents before children."""
    stack: list[tuple[str, Joint | None]] = [(urdf.root, None)]
    while stack:
        name, joint = stack.pop()
        yield urdf.links[name], joint
        for child in reversed(urdf.child_joints(name)):
            stack.append((child.child, child))
