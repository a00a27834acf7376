"""RViz's RobotModel display: the links' visual geometry of ``robot_description``, placed by TF.

:func:`parse_robot_description` reads the URDF text (the one place the viewer uses the
URDF reader, which lives in the simulator's package for now); :func:`robot_visuals`
turns every ``<visual>`` into a :class:`LinkVisual` (plain data, no Rerun); a
:class:`RobotModel` logs their geometry once, static, each under its link's entity,
and then places the links: :meth:`RobotModel.log_links` logs each link's transform in
the fixed frame (looked up in TF, as RViz's RobotModel does with its TF prefix).

Entities: ``<root>/robot_model/<robot>/<link>`` (the link's pose) and
``.../<link>/visual_<i>`` (the visual's origin and geometry: ``Boxes3D``,
``Cylinders3D``, ``Ellipsoids3D`` for spheres, ``Capsules3D``, ``Asset3D`` for
``.stl`` / ``.obj`` / ``.glb`` / ``.gltf`` meshes, scaled by the mesh's ``scale``).
Collada (``.dae``) and MuJoCo ``.msh`` meshes, which Rerun does not read, are read by
visnav's mesh reader into one ``Mesh3D`` with their parts' colours; one that does not read
is drawn as nothing and named once in the log.
A link without a transform to the fixed frame is left where it was last placed (RViz
greys it out; Rerun keeps it).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from visnav.errors import VisnavError
from visnav.tf.transforms import matrix_to_quaternion
from visnav.viz._rerun import rr
from visnav.viz.errors import VizError

__all__ = [
    "MESH_FORMATS",
    "LinkVisual",
    "RobotModel",
    "parse_robot_description",
    "robot_visuals",
]

_LOG = logging.getLogger("visnav.viz")

MESH_FORMATS = (".stl", ".obj", ".glb", ".gltf")
"""Mesh files Rerun's ``Asset3D`` reads."""

_DEFAULT_RGBA = (0.8, 0.8, 0.8, 1.0)  # RViz draws links without a material light grey

Shape = Literal["box", "cylinder", "sphere", "capsule", "mesh"]


@dataclass(frozen=True)
class LinkVisual:
    """One ``<visual>`` of a link.

    Attributes:
        link: the link's name.
        index: its position among the link's visuals.
        shape: box, cylinder, sphere, capsule or mesh.
        T_link_visual: the visual's origin (4x4).
        size: box edge lengths; (radius, length) for cylinders and capsules; (radius,)
            for spheres; the mesh's scale for meshes.
        rgba: colour, 0..1.
        mesh_path: the mesh file (meshes only).
    """

    link: str
    index: int
    shape: Shape
    T_link_visual: NDArray[np.float64]
    size: tuple[float, ...]
    rgba: tuple[float, float, float, float]
    mesh_path: str = ""


def parse_robot_description(
    text: str, *, source: str = "robot_description", packages: Mapping[str, str] | None = None
) -> Any:
    """Parse a URDF (already Xacro-expanded) with visnav's URDF reader.

    ``packages`` (name -> directory) resolves its ``package://`` meshes.

    Raises:
        VizError: the text is not a valid URDF (the reader's message, naming ``source``).
    """
    from visnav.description.urdf import parse_urdf  # noqa: PLC0415

    try:
        return parse_urdf(text, source=source, packages=packages)
    except (VisnavError, ValueError) as exc:
        raise VizError(f"{source}: cannot show the robot model: {exc}") from exc


def robot_visuals(urdf: Any) -> list[LinkVisual]:
    """Every visual of every link of a parsed URDF, with its geometry and colour."""
    out: list[LinkVisual] = []
    for link in urdf.links.values():
        for i, visual in enumerate(link.visuals):
            geom = visual.geometry
            kind = type(geom).__name__.lower()
            material = visual.material
            rgba = material.rgba if material is not None and material.rgba else _DEFAULT_RGBA
            size: tuple[float, ...]
            path = ""
            if kind == "box":
                size = tuple(float(v) for v in geom.size)
            elif kind in ("cylinder", "capsule"):
                size = (float(geom.radius), float(geom.length))
            elif kind == "sphere":
                size = (float(geom.radius),)
            elif kind == "mesh":
                size = tuple(float(v) for v in geom.scale)
                path = str(geom.path)
            else:  # pragma: no cover - the URDF reader knows no other shape
                continue
            out.append(
                LinkVisual(
                    link.name,
                    i,
                    kind,  # type: ignore[arg-type]
                    np.asarray(visual.origin.matrix(), dtype=np.float64),
                    size,
                    (float(rgba[0]), float(rgba[1]), float(rgba[2]), float(rgba[3])),
                    path,
                )
            )
    return out


def _rgba8(rgba: tuple[float, float, float, float]) -> list[int]:
    return [round(255 * min(max(c, 0.0), 1.0)) for c in rgba]


def _transform(matrix: NDArray[np.float64], scale: Iterable[float] | None = None) -> Any:
    quat = matrix_to_quaternion(matrix[:3, :3])
    kwargs: dict[str, Any] = {}
    if scale is not None:
        kwargs["scale"] = list(scale)
    return rr.Transform3D(translation=matrix[:3, 3], quaternion=rr.Quaternion(xyzw=quat), **kwargs)


def _archetype(visual: LinkVisual) -> Any | None:
    color = [_rgba8(visual.rgba)]
    if visual.shape == "box":
        return rr.Boxes3D(
            half_sizes=[[s / 2 for s in visual.size]], colors=color, fill_mode="solid"
        )
    if visual.shape == "cylinder":
        radius, length = visual.size
        return rr.Cylinders3D(lengths=[length], radii=[radius], colors=color, fill_mode="solid")
    if visual.shape == "capsule":
        radius, length = visual.size
        return rr.Capsules3D(
            lengths=[length], radii=[radius], translations=[[0.0, 0.0, -length / 2]], colors=color
        )
    if visual.shape == "sphere":
        r = visual.size[0]
        return rr.Ellipsoids3D(half_sizes=[[r, r, r]], colors=color, fill_mode="solid")
    if visual.mesh_path.lower().endswith(MESH_FORMATS):
        return rr.Asset3D(path=visual.mesh_path, albedo_factor=_rgba8(visual.rgba))
    if visual.mesh_path:  # Collada, MSH: triangles read by visnav's mesh reader
        return _read_mesh(visual)
    return None


def _read_mesh(visual: LinkVisual) -> Any | None:
    """A mesh Rerun cannot load itself as one ``Mesh3D`` with its parts' colours."""
    from visnav.description.mesh_files import load_mesh  # noqa: PLC0415 (trimesh, on use)

    try:
        data = load_mesh(visual.mesh_path)
    except (VisnavError, ValueError, OSError) as exc:
        _LOG.warning(
            "robot model: mesh %s of link %s not shown: %s", visual.mesh_path, visual.link, exc
        )
        return None
    if not data.parts:
        return None
    offsets = np.cumsum([0, *(len(p.vertices) for p in data.parts)])[:-1]
    verts = np.concatenate([p.vertices for p in data.parts]).astype(np.float32)
    faces = np.concatenate([p.faces + o for p, o in zip(data.parts, offsets, strict=True)])
    colors = np.concatenate(
        [
            np.tile(_rgba8(p.rgba if p.rgba is not None else visual.rgba), (len(p.vertices), 1))
            for p in data.parts
        ]
    ).astype(np.uint8)
    return rr.Mesh3D(
        vertex_positions=verts, triangle_indices=faces.astype(np.uint32), vertex_colors=colors
    )


class RobotModel:
    """The links of one robot description, logged to a recording.

    Args:
        urdf: a parsed URDF (:func:`parse_robot_description`).
        entity: the model's entity (``world/robot_model/<robot>``).
        tf_prefix: prepended to the link names to get their TF frames (RViz's TF Prefix).
    """

    def __init__(self, urdf: Any, entity: str, *, tf_prefix: str = "") -> None:
        self.name = str(urdf.name)
        self.entity = entity
        self.visuals = robot_visuals(urdf)
        prefix = tf_prefix.strip("/")
        self.frames = {
            link: f"{prefix}/{link}" if prefix else link
            for link in dict.fromkeys(v.link for v in self.visuals)
        }
        """Link name -> TF frame, for the links that have visuals."""
        self.skipped: list[str] = []
        """Visuals that cannot be drawn (meshes Rerun does not read)."""
        self.placed: set[str] = set()
        """Links placed at least once."""

    def link_entity(self, link: str) -> str:
        """The entity of ``link``."""
        return f"{self.entity}/{rr.escape_entity_path_part(link)}"

    def log_geometry(self, recording: Any) -> None:
        """Log every visual (static): its origin under the link and its shape."""
        for v in self.visuals:
            archetype = _archetype(v)
            if archetype is None:
                self.skipped.append(f"{v.link} visual {v.index}: {v.mesh_path}")
                continue
            entity = f"{self.link_entity(v.link)}/visual_{v.index}"
            scale = v.size if v.shape == "mesh" else None
            recording.log(entity, _transform(v.T_link_visual, scale), static=True)
            recording.log(entity, archetype, static=True)
        if self.skipped:
            _LOG.warning(
                "robot model %s: %d visual(s) not drawn (Rerun reads %s meshes only): %s",
                self.name,
                len(self.skipped),
                ", ".join(MESH_FORMATS),
                "; ".join(self.skipped[:5]),
            )

    def log_links(self, recording: Any, lookup: Callable[[str], NDArray[np.float64] | None]) -> int:
        """Log each link's pose in the fixed frame; return how many were placed.

        Args:
            recording: the recording (its time already set).
            lookup: TF frame -> ``T_fixed_frame`` (None when TF cannot place it).
        """
        placed = 0
        for link, frame in self.frames.items():
            matrix = lookup(frame)
            if matrix is None:
                continue
            recording.log(self.link_entity(link), _transform(matrix))
            self.placed.add(link)
            placed += 1
        return placed
