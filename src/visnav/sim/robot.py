"""A robot description (:mod:`visnav.description.robot`) as MuJoCo bodies, joints and sensors.

The simulator composes a MuJoCo model from a world spec and robots::

    spec = build_world_spec(world)                      # visnav.sim.world_spec
    robot = load_robot("car.urdf.xacro", args={"camera": "true"})  # visnav.description.robot
    handles = add_robot_to_spec(spec, robot, prefix="car/", spawn_xyz_yaw=(0, 0, 0.1, 0))
    model = spec.compile()
    body_id = model.body(handles.bodies["base_link"]).id

Mapping to MuJoCo:

* every link is a body whose frame is the link frame (fixed joints are welded,
  not merged, so every URDF frame exists for TF, sensors and p3d);
* revolute -> hinge with range, continuous -> hinge without range, prismatic ->
  slide with range; ``<dynamics>`` -> damping / frictionloss; ``<limit effort>``
  -> the joint's actuator force range; ``<mimic>`` -> a joint equality;
* a robot whose root link is not ``world`` gets a free joint (Gazebo's default
  for a spawned URDF); a ``world`` root fixes the robot at the spawn pose;
* inertials are used as given (principal axes computed here); visual geoms are
  group 1 without contacts or mass, collision geoms group 3 with contacts and no
  mass; ``<gazebo reference><material>`` colours and ``mu1`` friction apply;
  the robot's own bodies do not collide with each other (Gazebo's default
  ``self_collide`` false);
* mesh files (Collada, OBJ, STL, MSH; :mod:`visnav.description.mesh_files`) become one
  geom per coloured part, from vertex data; a visual without a URDF or ``<gazebo>``
  colour shows the mesh's own colours; collisions use each part's convex hull;
* each camera sensor becomes a MuJoCo camera at its link and ``<pose>`` whose
  intrinsics reproduce the published K (see :mod:`visnav.sim.camera`); each
  camera and IMU also gets a site in the sensor frame, and each IMU MuJoCo
  gyro, accelerometer and framequat sensors on that site.

Requires the spec's ``compiler.inertiafromgeom`` to stay ``AUTO`` (the default).
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from visnav.description.errors import MeshFileError
from visnav.description.mesh_convex import thickened
from visnav.description.mesh_files import load_mesh
from visnav.description.rigid import R_SENSOR_MJCAM, make_transform, matrix_to_quat_wxyz
from visnav.description.robot import RobotDescription
from visnav.description.urdf import (
    Box,
    Capsule,
    Cylinder,
    Geometry,
    Link,
    Mesh,
    RobotDescriptionError,
    Sphere,
    Urdf,
    iter_links_depth_first,
)
from visnav.sim.camera import configure_mujoco_camera
from visnav.sim.mesh_geoms import add_mesh_asset

__all__ = ["RobotHandles", "add_robot_to_spec"]

_LOG = logging.getLogger("visnav.sim.robot")
_DEFAULT_RGBA = (0.7, 0.7, 0.7, 1.0)
_MIN_INERTIA = 1e-9  # kg m^2, for point masses MuJoCo would reject


@dataclass(frozen=True)
class RobotHandles:
    """MuJoCo element names of one robot added to a spec (look ids up after compiling).

    Attributes:
        prefix: the name prefix used for every element.
        root_body: body of the URDF root link (``"world"`` for a fixed-base robot).
        free_joint: the free joint of a floating base, or None.
        bodies: URDF link -> MuJoCo body name (a ``world`` link maps to ``"world"``).
        joints: moving URDF joint -> MuJoCo joint name.
        cameras: camera sensor name -> MuJoCo camera name.
        sites: sensor name (camera or IMU) -> MuJoCo site in the sensor frame.
        imu_sensors: IMU name -> (gyro, accelerometer, framequat) MuJoCo sensor names.
    """

    prefix: str
    root_body: str
    free_joint: str | None
    bodies: Mapping[str, str]
    joints: Mapping[str, str]
    cameras: Mapping[str, str]
    sites: Mapping[str, str]
    imu_sensors: Mapping[str, tuple[str, str, str]]


# --------------------------------------------------------------------------- MuJoCo


_MeshAssets = dict[tuple[str, tuple[float, float, float], bool], list[tuple[str, Any]]]


def _mesh_assets(
    spec: mujoco.MjSpec, geometry: Mesh, meshes: _MeshAssets, prefix: str, *, visual: bool
) -> list[tuple[str, Any]]:
    """MuJoCo mesh assets of a mesh file: ``[(name, rgba or None)]``.

    Visual: one per coloured part. Collision: one of all vertices (MuJoCo collides with
    its convex hull, as it did with the whole file); a flat mesh gets a 1 mm thickness.
    """
    key = (str(geometry.path), geometry.scale, visual)
    if key not in meshes:
        try:
            data = load_mesh(geometry.path, geometry.scale)
        except MeshFileError as exc:
            msg = f"robot mesh {geometry.filename!r}: {exc}"
            raise RobotDescriptionError(msg) from None
        for text in data.warnings:
            _LOG.warning("%s", text)
        assets = []
        if visual:
            for i, part in enumerate(data.parts):
                name = f"{prefix}mesh{len(meshes)}.{i}:{geometry.path.stem}"
                assets.append((add_mesh_asset(spec, name, part.vertices, part.faces), part.rgba))
        else:
            name = f"{prefix}mesh{len(meshes)}:{geometry.path.stem}"
            points = thickened(data.vertices, 1e-3)
            assets.append((add_mesh_asset(spec, name, points), None))
        meshes[key] = assets
    return meshes[key]


def _add_geoms(
    body: Any,
    spec: mujoco.MjSpec,
    geometry: Geometry,
    t_link_geom: NDArray[np.float64],
    name: str,
    meshes: _MeshAssets,
    prefix: str,
    *,
    visual: bool,
) -> list[tuple[Any, Any]]:
    """Geoms of one URDF geometry: ``[(geom, the mesh part's own rgba or None)]``."""
    pos = t_link_geom[:3, 3].tolist()
    quat = list(matrix_to_quat_wxyz(t_link_geom[:3, :3]))
    if isinstance(geometry, Mesh):
        out = []
        assets = _mesh_assets(spec, geometry, meshes, prefix, visual=visual)
        for i, (mesh_name, rgba) in enumerate(assets):
            geom = body.add_geom(
                name=name if len(assets) == 1 else f"{name}.{i}",
                type=mujoco.mjtGeom.mjGEOM_MESH,
                meshname=mesh_name,
                pos=pos,
                quat=quat,
            )
            geom.density = 0.0
            out.append((geom, rgba))
        return out
    return [(_add_geom(body, geometry, t_link_geom, name), None)]


def _add_geom(body: Any, geometry: Geometry, t_link_geom: NDArray[np.float64], name: str) -> Any:
    geom = body.add_geom(name=name)
    pos = t_link_geom[:3, 3]
    rot = t_link_geom[:3, :3]
    if isinstance(geometry, Box):
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = [s / 2.0 for s in geometry.size]
    elif isinstance(geometry, Cylinder):
        geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        geom.size = [geometry.radius, geometry.length / 2.0, 0.0]
    elif isinstance(geometry, Capsule):
        geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        geom.size = [geometry.radius, geometry.length / 2.0, 0.0]
    elif isinstance(geometry, Sphere):
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [geometry.radius, 0.0, 0.0]
    geom.pos = pos.tolist()
    geom.quat = list(matrix_to_quat_wxyz(rot))
    geom.density = 0.0
    return geom


def _set_inertial(body: Any, link: Link, warnings: list[str], source: str) -> None:
    inertial = link.inertial
    if inertial is None or inertial.mass <= 0.0:
        return
    t_link_inertial = inertial.origin.matrix()
    rot = t_link_inertial[:3, :3]
    tensor = rot @ inertial.inertia_matrix() @ rot.T
    eigvals, eigvecs = np.linalg.eigh(tensor)
    if np.linalg.det(eigvecs) < 0:
        eigvecs[:, 0] = -eigvecs[:, 0]
    if float(eigvals.min()) <= _MIN_INERTIA:
        message = (
            f"{source}: link {link.name!r} has mass {inertial.mass:g} kg but principal inertia "
            f"{np.round(eigvals, 12).tolist()}; MuJoCo needs positive inertia, so moments below "
            f"{_MIN_INERTIA:g} kg m^2 are raised to it"
        )
        warnings.append(message)
        _LOG.warning("%s", message)
        eigvals = np.maximum(eigvals, _MIN_INERTIA)
    body.mass = float(inertial.mass)
    body.ipos = t_link_inertial[:3, 3].tolist()
    body.iquat = list(matrix_to_quat_wxyz(eigvecs))
    body.inertia = eigvals.tolist()
    body.explicitinertial = True


def _check_masses(urdf: Urdf) -> None:
    """Every moving link with its welded (fixed-joint) descendants must have mass."""

    def welded_mass(link: str) -> float:
        inertial = urdf.links[link].inertial
        total = inertial.mass if inertial is not None else 0.0
        for joint in urdf.child_joints(link):
            if not joint.moves:
                total += welded_mass(joint.child)
        return total

    for joint in urdf.joints.values():
        if joint.moves and welded_mass(joint.child) <= 0.0:
            msg = (
                f"{urdf.source}: link {joint.child!r} is moved by {joint.type} joint "
                f"{joint.name!r} but has no mass (no <inertial>, or mass 0, on it or on links "
                "fixed to it). Fix: add <inertial> with <mass value> > 0 and an <inertia> to "
                f"link {joint.child!r}"
            )
            raise RobotDescriptionError(msg)
    root_mass = welded_mass(urdf.root)
    if urdf.root != "world" and root_mass <= 0.0:
        msg = (
            f"{urdf.source}: the root link {urdf.root!r} floats freely but has no mass. Fix: add "
            f"<inertial> to {urdf.root!r} (or fix the robot with a 'world' link and a fixed joint)"
        )
        raise RobotDescriptionError(msg)


def add_robot_to_spec(
    spec: mujoco.MjSpec,
    robot: RobotDescription,
    *,
    prefix: str = "",
    spawn_xyz_yaw: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
) -> RobotHandles:
    """Add a robot's bodies, joints, geoms, inertials, cameras and sensor sites to a spec.

    Args:
        spec: the MuJoCo spec to extend (e.g. from ``build_world_spec``).
        robot: the robot description.
        prefix: prepended to every MuJoCo name (use one per robot instance).
        spawn_xyz_yaw: initial position (m) and yaw (rad) of the root link in the world.

    Returns:
        The MuJoCo names of the robot's elements.

    Raises:
        RobotDescriptionError: a moving link without mass, or a name already in
            the spec (choose another ``prefix``).
    """
    urdf = robot.urdf
    if len(spawn_xyz_yaw) != 4 or not all(math.isfinite(float(v)) for v in spawn_xyz_yaw):
        msg = f"spawn_xyz_yaw is {tuple(spawn_xyz_yaw)}: expected 4 finite numbers x, y, z, yaw"
        raise RobotDescriptionError(msg)
    _check_masses(urdf)
    x, y, z, yaw = (float(v) for v in spawn_xyz_yaw)
    t_world_spawn = make_transform((x, y, z), (0.0, 0.0, yaw))
    props = robot.gazebo.link_properties
    warnings: list[str] = []
    meshes: _MeshAssets = {}
    bodies: dict[str, str] = {}
    mj_bodies: dict[str, Any] = {}
    joints: dict[str, str] = {}
    free_joint: str | None = None
    colliding: list[str] = []
    existing = {b.name for b in spec.bodies} | {"world"}
    for link, joint in iter_links_depth_first(urdf):
        if link.name == "world" and joint is None:
            bodies[link.name] = "world"
            mj_bodies[link.name] = spec.worldbody
            continue
        body_name = f"{prefix}{link.name}"
        if body_name in existing:
            msg = (
                f"{urdf.source}: MuJoCo body {body_name!r} already exists in the spec. Fix: pass "
                "a distinct prefix= to add_robot_to_spec for each robot"
            )
            raise RobotDescriptionError(msg)
        if joint is None:  # floating root
            parent, t_parent_link = spec.worldbody, t_world_spawn
        elif joint.parent == "world" and urdf.root == "world":
            parent, t_parent_link = spec.worldbody, t_world_spawn @ joint.origin.matrix()
        else:
            parent, t_parent_link = mj_bodies[joint.parent], joint.origin.matrix()
        body = parent.add_body(name=body_name)
        body.pos = t_parent_link[:3, 3].tolist()
        body.quat = list(matrix_to_quat_wxyz(t_parent_link[:3, :3]))
        bodies[link.name] = body_name
        mj_bodies[link.name] = body
        _set_inertial(body, link, warnings, urdf.source)
        if joint is None or joint.type == "floating":
            free_joint = f"{prefix}{joint.name if joint is not None else link.name + ':free'}"
            body.add_freejoint(name=free_joint)
        elif joint.moves:
            mj_joint = body.add_joint(name=f"{prefix}{joint.name}")
            mj_joint.type = (
                mujoco.mjtJoint.mjJNT_SLIDE
                if joint.type == "prismatic"
                else mujoco.mjtJoint.mjJNT_HINGE
            )
            mj_joint.axis = list(joint.axis)
            if joint.type in ("revolute", "prismatic") and joint.limit is not None:
                mj_joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
                mj_joint.range = [joint.limit.lower, joint.limit.upper]
            else:
                mj_joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE
            if joint.limit is not None and joint.limit.effort > 0.0:
                mj_joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
                mj_joint.actfrcrange = [-joint.limit.effort, joint.limit.effort]
            mj_joint.damping = [joint.dynamics.damping, 0.0, 0.0]
            mj_joint.frictionloss = joint.dynamics.friction
            joints[joint.name] = mj_joint.name
        link_props = props.get(link.name)
        for i, visual in enumerate(link.visuals):
            rgba = None
            if link_props is not None and link_props.rgba is not None:
                rgba = link_props.rgba
            elif visual.material is not None and visual.material.rgba is not None:
                rgba = visual.material.rgba
            for geom, part_rgba in _add_geoms(
                body,
                spec,
                visual.geometry,
                visual.origin.matrix(),
                f"{body_name}:visual{i}",
                meshes,
                prefix,
                visual=True,
            ):
                geom.rgba = list(rgba or part_rgba or _DEFAULT_RGBA)
                geom.group = 1
                geom.contype = 0
                geom.conaffinity = 0
        for i, collision in enumerate(link.collisions):
            for geom, _ in _add_geoms(
                body,
                spec,
                collision.geometry,
                collision.origin.matrix(),
                f"{body_name}:collision{i}",
                meshes,
                prefix,
                visual=False,
            ):
                geom.group = 3
                geom.contype = 1
                geom.conaffinity = 1
                if link_props is not None and link_props.mu1 is not None:
                    friction = list(geom.friction)
                    friction[0] = link_props.mu1
                    geom.friction = friction
        if link.collisions:
            colliding.append(body_name)
    for joint in urdf.joints.values():
        if joint.mimic is not None and joint.name in joints and joint.mimic.joint in joints:
            equality = spec.add_equality(
                type=mujoco.mjtEq.mjEQ_JOINT,
                name1=joints[joint.name],
                name2=joints[joint.mimic.joint],
                name=f"{prefix}{joint.name}:mimic",
            )
            data = list(equality.data)
            data[:5] = [joint.mimic.offset, joint.mimic.multiplier, 0.0, 0.0, 0.0]
            equality.data = data
    for a, b in itertools.combinations(colliding, 2):
        spec.add_exclude(bodyname1=a, bodyname2=b)
    cameras: dict[str, str] = {}
    sites: dict[str, str] = {}
    for camera in robot.gazebo.cameras:
        body = mj_bodies[camera.link]
        t_link_sensor = camera.pose.matrix()
        t_link_cam = t_link_sensor.copy()
        t_link_cam[:3, :3] = t_link_sensor[:3, :3] @ R_SENSOR_MJCAM
        cam = body.add_camera(name=f"{prefix}{camera.name}")
        cam.pos = t_link_cam[:3, 3].tolist()
        cam.quat = list(matrix_to_quat_wxyz(t_link_cam[:3, :3]))
        configure_mujoco_camera(cam, camera)
        cameras[camera.name] = cam.name
        sites[camera.name] = _add_site(body, f"{prefix}{camera.name}:site", t_link_sensor)
    imu_sensors: dict[str, tuple[str, str, str]] = {}
    for imu in robot.gazebo.imus:
        body = mj_bodies[imu.link]
        site = _add_site(body, f"{prefix}{imu.name}:site", imu.pose.matrix())
        sites[imu.name] = site
        names = (
            f"{prefix}{imu.name}:gyro",
            f"{prefix}{imu.name}:accel",
            f"{prefix}{imu.name}:quat",
        )
        for sensor_name, sensor_type in zip(
            names,
            (
                mujoco.mjtSensor.mjSENS_GYRO,
                mujoco.mjtSensor.mjSENS_ACCELEROMETER,
                mujoco.mjtSensor.mjSENS_FRAMEQUAT,
            ),
            strict=True,
        ):
            spec.add_sensor(
                name=sensor_name, type=sensor_type, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site
            )
        imu_sensors[imu.name] = names
    return RobotHandles(
        prefix=prefix,
        root_body=bodies[urdf.root],
        free_joint=free_joint,
        bodies=bodies,
        joints=joints,
        cameras=cameras,
        sites=sites,
        imu_sensors=imu_sensors,
    )


def _add_site(body: Any, name: str, t_link_site: NDArray[np.float64]) -> str:
    site = body.add_site(name=name)
    site.pos = t_link_site[:3, 3].tolist()
    site.quat = list(matrix_to_quat_wxyz(t_link_site[:3, :3]))
    site.group = 4
    site.size = [0.005, 0.005, 0.005]
    return str(site.name)
