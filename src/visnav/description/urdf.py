"""A strict URDF parser producing typed, immutable dataclasses.

The parser checks what URDF requires and reports every problem as one
:class:`RobotDescriptionError` naming the file, the line, the element and the
fix. ``<gazebo>`` blocks are kept as XML elements (with their line numbers) for
:mod:`visnav.description.gazebo` to interpret.

Supported: links with inertials, visual and collision geometry (box, cylinder,
sphere, capsule, mesh), materials (colour; textures produce a warning), joints
(fixed, revolute, continuous, prismatic, and floating from a ``world`` link) with
origin, axis, limit, dynamics and mimic. Mesh and resource URIs ``package://``,
``file://``, ``model://`` and relative paths are resolved to existing files;
a missing file is an error naming the URI, the element and the paths tried.
Meshes may be Collada, STL, OBJ or MSH (read by :mod:`visnav.description.mesh_files`);
other formats produce a warning and the geometry is skipped.

Differences from ROS's urdfdom: unknown elements produce warnings instead of
being skipped silently; a zero axis, a non-positive size or a revolute joint
without ``<limit>`` is an error (urdfdom also rejects the last).
"""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from visnav.description.urdf_model import (
    MESH_EXTENSIONS,
    Box,
    Capsule,
    Collision,
    Cylinder,
    GazeboBlock,
    Geometry,
    Inertial,
    Joint,
    JointDynamics,
    JointLimit,
    JointType,
    Link,
    Material,
    Mesh,
    Mimic,
    Origin,
    RobotDescriptionError,
    Sphere,
    Urdf,
    Visual,
    XmlDoc,
    find_package,
    iter_links_depth_first,
    parse_xml,
    resolve_resource,
)
from visnav.textfile import read_text

__all__ = [
    "MESH_EXTENSIONS",
    "Box",
    "Capsule",
    "Collision",
    "Cylinder",
    "Geometry",
    "GazeboBlock",
    "Inertial",
    "Joint",
    "JointDynamics",
    "JointLimit",
    "JointType",
    "Link",
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
    "load_urdf",
    "parse_urdf",
    "parse_xml",
    "resolve_resource",
]

_LOG = logging.getLogger("visnav.description.urdf")
_JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic", "floating", "planar")


# --------------------------------------------------------------------------- parser


class _Parser:
    """One URDF parse: the document, the resource resolver and the warnings."""

    def __init__(
        self, doc: XmlDoc, base_dir: Path | None, packages: Mapping[str, Path | str] | None
    ) -> None:
        self.doc = doc
        self.base_dir = base_dir
        self.packages = packages
        self.warnings: list[str] = []

    def warn(self, element: ET.Element, text: str) -> None:
        message = f"{self.doc.where(element)}: <{element.tag}>: {text}"
        self.warnings.append(message)
        _LOG.debug("%s", message)  # the loader logs one summary of them all

    # numbers -------------------------------------------------------------

    def floats(
        self,
        element: ET.Element,
        attr: str,
        count: int,
        *,
        default: tuple[float, ...] | None = None,
        owner: str = "",
    ) -> tuple[float, ...]:
        raw = element.get(attr)
        if raw is None:
            if default is not None:
                return default
            raise self.doc.error(element, f"{owner}missing attribute {attr!r}", f'add {attr}="..."')
        parts = raw.split()
        try:
            values = tuple(float(p) for p in parts)
        except ValueError:
            values = ()
        if len(values) != count or not all(math.isfinite(v) for v in values):
            raise self.doc.error(
                element,
                f"{owner}attribute {attr}={raw!r} is not {count} finite number(s)",
                f"write {attr} as {count} space-separated numbers",
            )
        return values

    def number(
        self,
        element: ET.Element,
        attr: str,
        *,
        default: float | None = None,
        minimum: float | None = None,
        strict: bool = False,
        owner: str = "",
    ) -> float:
        value = self.floats(
            element,
            attr,
            1,
            default=None if default is None else (default,),
            owner=owner,
        )[0]
        if minimum is not None and (value < minimum or (strict and value == minimum)):
            bound = f"> {minimum}" if strict else f">= {minimum}"
            raise self.doc.error(
                element,
                f"{owner}{attr}={value} is out of range (expected {bound})",
                f"set {attr} to a value {bound}",
            )
        return value

    def origin(self, parent: ET.Element, owner: str) -> Origin:
        element = parent.find("origin")
        if element is None:
            return Origin()
        xyz = self.floats(element, "xyz", 3, default=(0.0, 0.0, 0.0), owner=owner)
        rpy = self.floats(element, "rpy", 3, default=(0.0, 0.0, 0.0), owner=owner)
        return Origin((xyz[0], xyz[1], xyz[2]), (rpy[0], rpy[1], rpy[2]))

    # geometry ------------------------------------------------------------

    def geometry(self, parent: ET.Element, owner: str) -> Geometry | None:
        element = parent.find("geometry")
        if element is None:
            raise self.doc.error(
                parent,
                f"{owner}has no <geometry>",
                "add <geometry> with a box/cylinder/sphere/mesh",
            )
        shapes = list(element)
        if len(shapes) != 1:
            raise self.doc.error(
                element,
                f"{owner}<geometry> must hold exactly one shape, found {len(shapes)}",
                "keep one of <box>, <cylinder>, <sphere>, <capsule>, <mesh>",
            )
        shape = shapes[0]
        if shape.tag == "box":
            sx, sy, sz = self.floats(shape, "size", 3, owner=owner)
            if min(sx, sy, sz) <= 0.0:
                raise self.doc.error(
                    shape,
                    f"{owner}box size {sx} {sy} {sz} has a non-positive edge",
                    "give three positive edge lengths in metres",
                )
            return Box((sx, sy, sz))
        if shape.tag in ("cylinder", "capsule"):
            radius = self.number(shape, "radius", minimum=0.0, strict=True, owner=owner)
            length = self.number(
                shape, "length", minimum=0.0, strict=shape.tag == "cylinder", owner=owner
            )
            return Cylinder(radius, length) if shape.tag == "cylinder" else Capsule(radius, length)
        if shape.tag == "sphere":
            return Sphere(self.number(shape, "radius", minimum=0.0, strict=True, owner=owner))
        if shape.tag == "mesh":
            return self.mesh(shape, owner)
        raise self.doc.error(
            shape,
            f"{owner}unknown geometry <{shape.tag}>",
            "use <box>, <cylinder>, <sphere>, <capsule> or <mesh>",
        )

    def mesh(self, shape: ET.Element, owner: str) -> Mesh | None:
        filename = shape.get("filename")
        if not filename:
            raise self.doc.error(shape, f"{owner}<mesh> has no filename", 'add filename="..."')
        scale = self.floats(shape, "scale", 3, default=(1.0, 1.0, 1.0), owner=owner)
        if min(abs(s) for s in scale) == 0.0:
            raise self.doc.error(
                shape, f"{owner}mesh scale {scale} has a zero factor", "use non-zero scale factors"
            )
        path, tried = resolve_resource(filename, base_dir=self.base_dir, packages=self.packages)
        if path is None:
            if tried:
                tried_text = "tried " + ", ".join(str(p) for p in tried)
            elif filename.startswith("package://"):
                tried_text = (
                    "its package is unknown: no packages= entry, no base directory to search, "
                    "ROS_PACKAGE_PATH and AMENT_PREFIX_PATH unset"
                )
            else:
                tried_text = "no base directory to resolve it against"
            raise self.doc.error(
                shape,
                f"{owner}mesh file {filename!r} not found ({tried_text})",
                "correct the filename, or pass packages={'<pkg>': '/path/to/pkg'} so "
                "package:// URIs resolve",
            )
        if path.suffix.lower() not in MESH_EXTENSIONS:
            self.warn(
                shape,
                f"{owner}mesh {filename!r} is {path.suffix or 'extensionless'}; visnav reads "
                f"{', '.join(MESH_EXTENSIONS)} only, so this geometry is skipped (convert it, "
                "e.g. with Blender, to Collada, STL or OBJ)",
            )
            return None
        return Mesh(filename, path, (scale[0], scale[1], scale[2]))

    # materials -------------------------------------------------------------

    def material(self, element: ET.Element, owner: str) -> Material:
        name = element.get("name", "")
        rgba: tuple[float, float, float, float] | None = None
        texture: str | None = None
        color = element.find("color")
        if color is not None:
            values = self.floats(color, "rgba", 4, owner=owner)
            if not all(0.0 <= v <= 1.0 for v in values):
                raise self.doc.error(
                    color,
                    f"{owner}color rgba={values} is outside 0..1",
                    "give red, green, blue, alpha in 0..1",
                )
            rgba = (values[0], values[1], values[2], values[3])
        tex = element.find("texture")
        if tex is not None:
            texture = tex.get("filename")
            self.warn(
                tex,
                f"{owner}textures on URDF materials are not rendered yet; "
                f"{texture!r} is ignored and the colour is used",
            )
        return Material(name=name, rgba=rgba, texture=texture)

    # links -----------------------------------------------------------------

    def link(self, element: ET.Element, materials: dict[str, Material]) -> Link:
        name = element.get("name")
        if not name:
            raise self.doc.error(element, "link without a name", 'add name="..."')
        owner = f"link {name!r}: "
        inertial = None
        visuals: list[Visual] = []
        collisions: list[Collision] = []
        for child in element:
            if child.tag == "inertial":
                inertial = self.inertial(child, owner)
            elif child.tag == "visual":
                visual = self.visual(child, owner, materials, len(visuals))
                if visual is not None:
                    visuals.append(visual)
            elif child.tag == "collision":
                geometry = self.geometry(child, owner)
                if geometry is not None:
                    collisions.append(
                        Collision(
                            name=child.get("name") or f"{name}_collision_{len(collisions)}",
                            origin=self.origin(child, owner),
                            geometry=geometry,
                        )
                    )
            else:
                self.warn(child, f"{owner}unknown element <{child.tag}> in a link is ignored")
        return Link(name, inertial, tuple(visuals), tuple(collisions))

    def inertial(self, element: ET.Element, owner: str) -> Inertial:
        mass_el = element.find("mass")
        if mass_el is None:
            raise self.doc.error(
                element, f"{owner}<inertial> without <mass>", 'add <mass value="..."/>'
            )
        mass = self.number(mass_el, "value", minimum=0.0, owner=owner)
        inertia_el = element.find("inertia")
        if inertia_el is None:
            raise self.doc.error(
                element,
                f"{owner}<inertial> without <inertia>",
                "add <inertia ixx ixy ixz iyy iyz izz/>",
            )
        names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        values = tuple(self.number(inertia_el, n, default=0.0, owner=owner) for n in names)
        physical = _nearest_physical_inertia(values)
        if physical is not None:
            eig = np.linalg.eigvalsh(_inertia_matrix(values))
            self.warn(
                inertia_el,
                f"{owner}inertia {values} is not physical (principal moments "
                f"{np.round(eig, 9).tolist()}); the nearest physical tensor "
                f"{tuple(round(v, 9) for v in physical)} is used (ixx ixy ixz iyy iyz izz; "
                "Gazebo runs it as written, MuJoCo cannot; moments must be >= 0 and satisfy "
                "the triangle inequality: recompute them from the geometry and mass)",
            )
            values = physical
        return Inertial(self.origin(element, owner), mass, values)  # type: ignore[arg-type]

    def visual(
        self, element: ET.Element, owner: str, materials: dict[str, Material], index: int
    ) -> Visual | None:
        geometry = self.geometry(element, owner)
        if geometry is None:
            return None
        material = None
        mat_el = element.find("material")
        if mat_el is not None:
            material = self.material(mat_el, owner)
            if material.rgba is None and material.texture is None:
                # A reference to a top-level material (may be defined later in the file).
                material = materials.get(material.name, material)
        link_name = owner.split("'")[1] if "'" in owner else "link"
        return Visual(
            name=element.get("name") or f"{link_name}_visual_{index}",
            origin=self.origin(element, owner),
            geometry=geometry,
            material=material,
        )

    # joints ----------------------------------------------------------------

    def joint(self, element: ET.Element) -> Joint:
        name = element.get("name")
        if not name:
            raise self.doc.error(element, "joint without a name", 'add name="..."')
        owner = f"joint {name!r}: "
        jtype = element.get("type")
        if jtype not in _JOINT_TYPES:
            raise self.doc.error(
                element,
                f"{owner}type={jtype!r} is not a URDF joint type",
                "use fixed, revolute, continuous, prismatic (or floating)",
            )
        if jtype == "planar":
            raise self.doc.error(
                element,
                f"{owner}planar joints are not supported",
                "model the plane with two prismatic joints and a continuous joint",
            )
        links: dict[str, str] = {}
        for tag in ("parent", "child"):
            el = element.find(tag)
            if el is None or not el.get("link"):
                raise self.doc.error(
                    element, f'{owner}missing <{tag} link="..."/>', f"add the <{tag}> element"
                )
            links[tag] = str(el.get("link"))
        axis: tuple[float, ...] = (1.0, 0.0, 0.0)
        axis_el = element.find("axis")
        if axis_el is not None and jtype not in ("fixed", "floating"):  # urdfdom reads no other
            axis = self.floats(axis_el, "xyz", 3, default=(1.0, 0.0, 0.0), owner=owner)
            norm = math.sqrt(sum(a * a for a in axis))
            if norm < 1e-9:
                raise self.doc.error(
                    axis_el,
                    f"{owner}axis xyz={axis} is zero",
                    'give a non-zero axis, e.g. xyz="0 0 1"',
                )
            axis = tuple(a / norm for a in axis)
        limit = None
        limit_el = element.find("limit")
        if limit_el is not None:
            limit = JointLimit(
                lower=self.number(limit_el, "lower", default=0.0, owner=owner),
                upper=self.number(limit_el, "upper", default=0.0, owner=owner),
                effort=self.number(limit_el, "effort", default=0.0, minimum=0.0, owner=owner),
                velocity=self.number(limit_el, "velocity", default=0.0, minimum=0.0, owner=owner),
            )
            if jtype in ("revolute", "prismatic") and limit.lower > limit.upper:
                raise self.doc.error(
                    limit_el,
                    f"{owner}limit lower={limit.lower} > upper={limit.upper}",
                    "swap or correct the bounds",
                )
        elif jtype in ("revolute", "prismatic"):
            raise self.doc.error(
                element,
                f"{owner}a {jtype} joint needs <limit>",
                'add <limit lower="..." upper="..." effort="..." velocity="..."/> '
                '(or use type="continuous" for an unbounded revolute joint)',
            )
        dynamics = JointDynamics()
        dyn_el = element.find("dynamics")
        if dyn_el is not None:
            dynamics = JointDynamics(
                damping=self.number(dyn_el, "damping", default=0.0, minimum=0.0, owner=owner),
                friction=self.number(dyn_el, "friction", default=0.0, minimum=0.0, owner=owner),
            )
        mimic = None
        mimic_el = element.find("mimic")
        if mimic_el is not None:
            target = mimic_el.get("joint")
            if not target:
                raise self.doc.error(
                    mimic_el, f"{owner}<mimic> without joint", 'add joint="<mimicked joint>"'
                )
            mimic = Mimic(
                target,
                self.number(mimic_el, "multiplier", default=1.0, owner=owner),
                self.number(mimic_el, "offset", default=0.0, owner=owner),
            )
        known = {"origin", "parent", "child", "axis", "limit", "dynamics", "mimic"}
        for child in element:
            if child.tag in ("calibration", "safety_controller"):
                continue  # real-robot metadata with no meaning in simulation
            if child.tag not in known:
                self.warn(child, f"{owner}unknown element <{child.tag}> in a joint is ignored")
        return Joint(
            name=name,
            type=jtype,  # type: ignore[arg-type]
            parent=links["parent"],
            child=links["child"],
            origin=self.origin(element, owner),
            axis=(axis[0], axis[1], axis[2]),
            limit=limit,
            dynamics=dynamics,
            mimic=mimic,
        )


def _inertia_matrix(values: tuple[float, ...]) -> NDArray[np.float64]:
    ixx, ixy, ixz, iyy, iyz, izz = values
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _nearest_physical_inertia(values: tuple[float, ...]) -> tuple[float, ...] | None:
    """The nearest physical inertia tensor (ixx ixy ixz iyy iyz izz), None if it is one.

    In the tensor's own principal axes: negative moments become 0, then, if the largest
    moment exceeds the sum of the other two, the three move by the same amount towards
    equality (the closest point, in moments, where the triangle inequality holds).
    """
    matrix = _inertia_matrix(values)
    eig, axes = np.linalg.eigh(matrix)
    tol = 1e-12 + 1e-9 * float(np.max(np.abs(eig)))
    if float(eig.min()) >= -tol and eig[0] + eig[1] >= eig[2] - tol:
        return None
    moments = np.maximum(eig, 0.0)
    excess = float(moments[2] - moments[0] - moments[1])
    if excess > 0.0:
        moments = moments + np.array([excess, excess, -excess]) / 3.0
    fixed = axes @ np.diag(moments) @ axes.T
    return (
        float(fixed[0, 0]), float(fixed[0, 1]), float(fixed[0, 2]),
        float(fixed[1, 1]), float(fixed[1, 2]), float(fixed[2, 2]),
    )  # fmt: skip


def _check_tree(
    parser: _Parser,
    root_el: ET.Element,
    links: Mapping[str, Link],
    joints: Mapping[str, Joint],
    joint_elements: Mapping[str, ET.Element],
) -> str:
    doc = parser.doc
    parent_of: dict[str, str] = {}
    for joint in joints.values():
        element = joint_elements[joint.name]
        for role, link in (("parent", joint.parent), ("child", joint.child)):
            if link not in links:
                raise doc.error(
                    element,
                    f"joint {joint.name!r}: {role} link {link!r} does not exist",
                    f'define <link name="{link}"/> or correct the name '
                    f"(links: {', '.join(sorted(links)) or 'none'})",
                )
        if joint.child in parent_of:
            raise doc.error(
                element,
                f"joint {joint.name!r}: link {joint.child!r} is already the child of joint "
                f"{parent_of[joint.child]!r}",
                "a link has at most one parent joint; URDF describes a tree",
            )
        parent_of[joint.child] = joint.name
        if joint.type == "floating" and joint.parent != "world":
            raise doc.error(
                element,
                f"joint {joint.name!r}: floating joints are only supported from the 'world' link",
                "remove the joint (a robot without a 'world' link floats freely) or make it fixed",
            )
        if joint.mimic is not None and joint.mimic.joint not in joints:
            raise doc.error(
                element,
                f"joint {joint.name!r}: mimicked joint {joint.mimic.joint!r} does not exist",
                'name an existing joint in <mimic joint="..."/>',
            )
    roots = [name for name in links if name not in parent_of]
    if len(roots) != 1:
        what = (
            "no root link (the joints form a cycle)"
            if not roots
            else (
                f"{len(roots)} root links ({', '.join(roots)}): every link but one must be the "
                "child of a joint"
            )
        )
        raise doc.error(root_el, what, "connect the links into a single tree with joints")
    # cycles unreachable from the root
    reachable = {roots[0]}
    frontier = [roots[0]]
    while frontier:
        link = frontier.pop()
        for joint in joints.values():
            if joint.parent == link and joint.child not in reachable:
                reachable.add(joint.child)
                frontier.append(joint.child)
    if len(reachable) != len(links):
        stray = sorted(set(links) - reachable)
        raise doc.error(
            root_el,
            f"links {stray} are not connected to the root {roots[0]!r} (a joint cycle)",
            "connect every link to the tree exactly once",
        )
    return roots[0]


def parse_urdf(
    text: str,
    *,
    source: str = "<string>",
    base_dir: str | Path | None = None,
    packages: Mapping[str, Path | str] | None = None,
) -> Urdf:
    """Parse and validate a URDF document.

    Args:
        text: the URDF XML (already Xacro-expanded).
        source: the file name used in messages.
        base_dir: directory for relative mesh paths (default: the source's
            directory when ``source`` is an existing file).
        packages: package name -> directory for ``package://`` URIs.

    Returns:
        The robot.

    Raises:
        RobotDescriptionError: malformed XML, a missing mesh, an invalid value or a
            broken link tree; the message names the file, line and element.
    """
    root_el, doc = parse_xml(text, source)
    if base_dir is None and source != "<string>" and Path(source).is_file():
        base_dir = Path(source).resolve().parent
    parser = _Parser(doc, Path(base_dir) if base_dir is not None else None, packages)
    if root_el.tag != "robot":
        raise doc.error(root_el, "the root element is not <robot>", "wrap the model in <robot>")
    name = root_el.get("name")
    if not name:
        raise doc.error(root_el, "<robot> has no name", 'add name="..." to <robot>')
    materials: dict[str, Material] = {}
    for element in root_el.findall("material"):
        material = parser.material(element, "")
        if not material.name:
            raise doc.error(element, "top-level <material> without a name", 'add name="..."')
        materials[material.name] = material
    links: dict[str, Link] = {}
    joints: dict[str, Joint] = {}
    joint_elements: dict[str, ET.Element] = {}
    gazebo: list[GazeboBlock] = []
    transmissions: list[ET.Element] = []
    for element in root_el:
        if element.tag == "link":
            link = parser.link(element, materials)
            if link.name in links:
                raise doc.error(
                    element, f"duplicate link name {link.name!r}", "give every link a unique name"
                )
            links[link.name] = link
        elif element.tag == "joint":
            joint = parser.joint(element)
            if joint.name in joints:
                raise doc.error(
                    element,
                    f"duplicate joint name {joint.name!r}",
                    "give every joint a unique name",
                )
            joints[joint.name] = joint
            joint_elements[joint.name] = element
        elif element.tag == "gazebo":
            gazebo.append(GazeboBlock(element.get("reference"), element))
        elif element.tag == "material":
            continue
        elif element.tag == "transmission":
            transmissions.append(element)  # read with the libgazebo_ros_control.so plugin
        else:
            parser.warn(element, f"unknown top-level element <{element.tag}> is ignored")
    if not links:
        raise doc.error(root_el, f"robot {name!r} has no links", "add at least one <link>")
    plugins = (p.get("filename") for b in gazebo for p in b.element.iter("plugin"))
    if transmissions and "libgazebo_ros_control.so" not in plugins:
        for element in transmissions:
            parser.warn(
                element,
                f"transmission {element.get('name')!r} is ignored: no libgazebo_ros_control.so "
                "plugin drives it (add one, or drive the joints with a gazebo plugin such as "
                "libgazebo_ros_diff_drive.so)",
            )
    # Resolve visual material references defined after their use.
    links = {
        lname: Link(
            link.name,
            link.inertial,
            tuple(_resolve_material(v, materials) for v in link.visuals),
            link.collisions,
        )
        for lname, link in links.items()
    }
    root = _check_tree(parser, root_el, links, joints, joint_elements)
    return Urdf(
        name=name,
        links=links,
        joints=joints,
        root=root,
        materials=materials,
        gazebo=tuple(gazebo),
        doc=doc,
        base_dir=parser.base_dir,
        warnings=tuple(parser.warnings),
        transmissions=tuple(transmissions),
    )


def _resolve_material(visual: Visual, materials: Mapping[str, Material]) -> Visual:
    mat = visual.material
    if mat is not None and mat.rgba is None and mat.texture is None and mat.name in materials:
        return Visual(visual.name, visual.origin, visual.geometry, materials[mat.name])
    return visual


def load_urdf(path: str | Path, *, packages: Mapping[str, Path | str] | None = None) -> Urdf:
    """Read and parse a URDF file (see :func:`parse_urdf`).

    Raises:
        RobotDescriptionError: the file cannot be read, or anything
            :func:`parse_urdf` rejects.
    """
    file = Path(path)
    text = read_text(file, what="the URDF", error=RobotDescriptionError)
    return parse_urdf(text, source=str(file), base_dir=file.resolve().parent, packages=packages)
