"""Robots in MuJoCo: kinematics agree with the URDF, sensors sit where the URDF says."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from visnav.description.rigid import make_transform
from visnav.description.robot import load_robot
from visnav.description.urdf import RobotDescriptionError
from visnav.sim.camera import CameraSensor
from visnav.sim.robot import add_robot_to_spec
from visnav.tf.robot_state import RobotStateModel

INERTIA = '<inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0" izz="0.04"/>'

ROBOT = f"""<?xml version="1.0"?>
<robot name="rover">
  <link name="base_footprint"/>
  <link name="base_link">
    <inertial><origin xyz="0.05 0 0.02" rpy="0 0 0.4"/><mass value="4"/>{INERTIA}</inertial>
    <visual><origin xyz="0 0 0.05"/><geometry><box size="0.5 0.3 0.1"/></geometry>
      <material name="m"><color rgba="0.2 0.3 0.4 1"/></material></visual>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.5 0.3 0.1"/></geometry>
    </collision>
  </link>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0 0 0.1"/></joint>
  <link name="mast"><inertial><mass value="0.5"/>{INERTIA}</inertial>
    <visual><geometry><cylinder radius="0.1" length="1.0"/></geometry></visual></link>
  <joint name="mast_joint" type="prismatic"><parent link="base_link"/><child link="mast"/>
    <origin xyz="-0.1 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.5" effort="50" velocity="1"/><dynamics damping="2"/></joint>
  <link name="pan"><inertial><mass value="0.3"/>{INERTIA}</inertial></link>
  <joint name="pan_joint" type="revolute"><parent link="mast"/><child link="pan"/>
    <origin xyz="0 0 0.5" rpy="0.1 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
  <link name="camera_link"/>
  <joint name="camera_joint" type="fixed"><parent link="pan"/><child link="camera_link"/>
    <origin xyz="0.05 0 0.02" rpy="0 0.3 0"/></joint>
  <link name="left_wheel"><inertial><mass value="0.2"/>{INERTIA}</inertial>
    <collision><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.1" length="0.04"/>
    </geometry></collision></link>
  <joint name="left_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="left_wheel"/><origin xyz="0 0.18 0"/><axis xyz="0 1 0"/></joint>
  <link name="right_wheel"><inertial><mass value="0.2"/>{INERTIA}</inertial>
    <collision><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.1" length="0.04"/>
    </geometry></collision></link>
  <joint name="right_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="right_wheel"/><origin xyz="0 -0.18 0"/><axis xyz="0 1 0"/>
    <mimic joint="left_wheel_joint" multiplier="1" offset="0"/></joint>
  <gazebo reference="base_link"><material>Gazebo/Orange</material><mu1>0.7</mu1>
    <sensor name="imu" type="imu"><update_rate>200</update_rate><pose>0.1 0 0 0 0 0</pose>
      <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so"/></sensor></gazebo>
  <gazebo reference="camera_link">
    <sensor name="cam" type="camera">
      <pose>0.01 0.02 0.03 0 0.1 -0.05</pose>
      <camera><horizontal_fov>1.2</horizontal_fov>
        <image><width>96</width><height>72</height></image><clip><near>0.05</near>
        <far>30</far></clip></camera>
      <plugin name="cam_plugin" filename="libgazebo_ros_camera.so"/>
    </sensor>
  </gazebo>
</robot>
"""


def compile_robot(
    text: str = ROBOT, *, prefix: str = "r/", spawn: tuple[float, ...] = (1.0, -2.0, 0.3, 0.7)
) -> tuple[mujoco.MjModel, mujoco.MjData, object, object]:
    desc = load_robot(text)
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1])
    handles = add_robot_to_spec(spec, desc, prefix=prefix, spawn_xyz_yaw=spawn)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, desc, handles


def body_pose(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    out = np.eye(4)
    body = model.body(name).id
    out[:3, :3] = data.xmat[body].reshape(3, 3)
    out[:3, 3] = data.xpos[body]
    return out


def test_link_frames_match_urdf_kinematics() -> None:
    model, data, desc, handles = compile_robot()
    q = {"mast_joint": 0.3, "pan_joint": 1.1, "left_wheel_joint": 0.5, "right_wheel_joint": 0.5}
    for joint, value in q.items():
        data.qpos[model.jnt_qposadr[model.joint(handles.joints[joint]).id]] = value
    mujoco.mj_kinematics(model, data)
    state = RobotStateModel(desc.urdf)
    spawn = make_transform((1.0, -2.0, 0.3), (0, 0, 0.7))
    world = {"base_footprint": spawn}
    for joint in desc.urdf.joints.values():  # parents come first in this URDF
        if joint.moves:
            t = state.joint_transform(joint.name, q[joint.name])
        else:
            t = joint.origin.matrix()
        world[joint.child] = world[joint.parent] @ t
    for link, expected in world.items():
        np.testing.assert_allclose(
            body_pose(model, data, handles.bodies[link]), expected, atol=1e-9, err_msg=link
        )
    assert handles.root_body == "r/base_footprint"
    assert handles.free_joint is not None
    assert model.joint(handles.free_joint).type == mujoco.mjtJoint.mjJNT_FREE


def test_joint_types_limits_and_dynamics() -> None:
    model, _, _, handles = compile_robot()
    mast = model.joint(handles.joints["mast_joint"])
    assert mast.type == mujoco.mjtJoint.mjJNT_SLIDE
    assert model.jnt_limited[mast.id]
    assert tuple(mast.range) == (0.0, 0.5)
    assert model.dof_damping[model.jnt_dofadr[mast.id]] == 2.0
    assert tuple(model.jnt_actfrcrange[mast.id]) == (-50.0, 50.0)
    wheel = model.joint(handles.joints["left_wheel_joint"])
    assert wheel.type == mujoco.mjtJoint.mjJNT_HINGE
    assert not model.jnt_limited[wheel.id]
    assert model.joint(handles.joints["pan_joint"]).type == mujoco.mjtJoint.mjJNT_HINGE
    # mimic -> joint equality: right = 0 + 1 * left
    assert model.neq == 1
    assert model.eq_type[0] == mujoco.mjtEq.mjEQ_JOINT
    assert model.eq_obj1id[0] == model.joint(handles.joints["right_wheel_joint"]).id
    assert model.eq_obj2id[0] == wheel.id
    assert tuple(model.eq_data[0][:2]) == (0.0, 1.0)


def test_inertials_colours_and_collisions() -> None:
    model, data, desc, handles = compile_robot()
    base = model.body(handles.bodies["base_link"])
    assert base.mass[0] == pytest.approx(4.0)
    inertial = desc.urdf.links["base_link"].inertial
    rot = make_transform(rpy=(0, 0, 0.4))[:3, :3]
    tensor = rot @ inertial.inertia_matrix() @ rot.T
    np.testing.assert_allclose(np.sort(base.inertia), np.linalg.eigvalsh(tensor), rtol=1e-9)
    com = body_pose(model, data, handles.bodies["base_link"]) @ np.array([0.05, 0, 0.02, 1])
    np.testing.assert_allclose(data.xipos[base.id], com[:3], atol=1e-12)
    # Massless links add nothing; total robot mass is the URDF's.
    robot_bodies = [model.body(b).id for b in handles.bodies.values()]
    assert model.body_mass[robot_bodies].sum() == pytest.approx(4 + 0.5 + 0.3 + 0.2 + 0.2)
    visual = model.geom("r/base_link:visual0")
    assert visual.group == 1
    assert visual.contype == 0
    assert visual.conaffinity == 0
    np.testing.assert_allclose(visual.rgba, [1.0, 0.5088, 0.0468, 1.0])  # Gazebo/Orange wins
    collision = model.geom("r/base_link:collision0")
    assert collision.group == 3
    assert collision.contype == 1
    assert collision.friction[0] == 0.7
    # Own bodies do not collide with each other (Gazebo's self_collide false).
    excluded = {
        (int(a), int(b))
        for a, b in zip(
            model.exclude_signature >> 16, model.exclude_signature & 0xFFFF, strict=True
        )
    }
    left, right = model.body("r/left_wheel").id, model.body("r/right_wheel").id
    assert (min(left, right), max(left, right)) in excluded or (
        max(left, right),
        min(left, right),
    ) in excluded


def test_cylinders_lie_along_z() -> None:
    model, data, _, handles = compile_robot(spawn=(0.0, 0.0, 0.0, 0.0))
    mast = body_pose(model, data, handles.bodies["mast"])
    geomid = np.zeros(1, dtype=np.int32)
    # A horizontal ray 0.45 m above the mast centre hits it (length 1 along z) ...
    start = mast[:3, 3] + np.array([-1.0, 0.0, 0.45])
    hit = mujoco.mj_ray(model, data, start, np.array([1.0, 0, 0]), None, 1, -1, geomid)
    assert hit == pytest.approx(0.9, abs=1e-9)
    assert model.geom(geomid[0]).name == "r/mast:visual0"
    # ... 0.55 m above it misses the mast.
    start[2] += 0.1
    mujoco.mj_ray(model, data, start, np.array([1.0, 0, 0]), None, 1, -1, geomid)
    assert geomid[0] == -1 or model.geom(geomid[0]).name != "r/mast:visual0"


def test_sensor_sites_cameras_and_imu() -> None:
    model, data, desc, handles = compile_robot()
    cam_spec = desc.gazebo.cameras[0]
    site = handles.sites["cam"]
    expected = body_pose(model, data, handles.bodies["camera_link"]) @ cam_spec.pose.matrix()
    sid = model.site(site).id
    np.testing.assert_allclose(data.site_xpos[sid], expected[:3, 3], atol=1e-12)
    np.testing.assert_allclose(data.site_xmat[sid].reshape(3, 3), expected[:3, :3], atol=1e-12)
    cam = model.camera(handles.cameras["cam"])
    np.testing.assert_allclose(data.cam_xpos[cam.id], expected[:3, 3], atol=1e-12)
    cam_rot = data.cam_xmat[cam.id].reshape(3, 3)
    np.testing.assert_allclose(cam_rot[:, 2], -expected[:3, 0], atol=1e-12)  # looks along x
    np.testing.assert_allclose(cam_rot[:, 1], expected[:3, 2], atol=1e-12)  # up is z
    assert tuple(model.cam_resolution[cam.id]) == (96, 72)
    gyro, accel, quat = handles.imu_sensors["imu"]
    mujoco.mj_step(model, data)
    assert model.sensor(accel).dim[0] == 3
    assert model.sensor(quat).dim[0] == 4
    assert data.sensor(gyro).data.shape == (3,)


def test_camera_through_the_robot_matches_projection(mujoco_gl: str) -> None:
    del mujoco_gl
    desc = load_robot(ROBOT)
    spec = mujoco.MjSpec()
    spec.visual.headlight.ambient = [1, 1, 1]
    spec.visual.headlight.diffuse = [0, 0, 0]
    spec.visual.headlight.specular = [0, 0, 0]
    handles = add_robot_to_spec(spec, desc, prefix="r/", spawn_xyz_yaw=(0.5, 0.2, 0.0, 0.4))
    pan = handles.joints["pan_joint"]

    def posed(model: mujoco.MjModel) -> mujoco.MjData:
        data = mujoco.MjData(model)
        data.qpos[model.jnt_qposadr[model.joint(pan).id]] = 0.2
        mujoco.mj_forward(model, data)
        return data

    # Targets in front of the camera: optical (x right, y down, z forward) -> world.
    model = spec.compile()
    data = posed(model)
    sid = model.site(handles.sites["cam"]).id
    t_world_sensor = np.eye(4)
    t_world_sensor[:3, :3] = data.site_xmat[sid].reshape(3, 3)
    t_world_sensor[:3, 3] = data.site_xpos[sid]
    optical_targets = np.array([[0.5, 0.3, 3.0], [-0.6, -0.4, 2.5], [0.1, -0.2, 4.0]])
    sensor_targets = np.stack(
        [optical_targets[:, 2], -optical_targets[:, 0], -optical_targets[:, 1]], axis=1
    )
    targets = (t_world_sensor @ np.c_[sensor_targets, np.ones(3)].T).T[:, :3]
    for p in targets:  # ~2.5 px radius: big enough for a sub-pixel centroid
        spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.14, 0, 0], pos=p.tolist(), rgba=[1, 0, 0, 1]
        )
    model = spec.compile()
    data = posed(model)
    cam_spec = desc.gazebo.cameras[0]
    sensor = CameraSensor(model, cam_spec, camera=handles.cameras["cam"])
    try:
        frame = sensor.render(data)
    finally:
        sensor.close()
    assert frame.color is not None
    assert frame.image is not None
    assert frame.image.header.frame_id == "camera_link"
    # Project with the published K: the robot placed the image where K says.
    k = np.array(cam_spec.k()).reshape(3, 3)
    uv = (k @ (optical_targets / optical_targets[:, 2:3]).T).T[:, :2]
    # Intensity-weighted centroids (anti-aliased edges count by coverage): the
    # thresholded centroid of a blob a few pixels wide is quantised by up to ~0.5 px.
    colour = frame.color.astype(np.float64)
    redness = np.clip((colour[..., 0] - colour[..., 1]) / 255.0, 0.0, 1.0)
    n, labels, _, _ = cv2.connectedComponentsWithStats((redness > 0.02).astype(np.uint8))
    assert n - 1 == len(targets)
    vs, us = np.mgrid[0 : redness.shape[0], 0 : redness.shape[1]]
    centroids = np.array(
        [
            [np.sum(us * w) / np.sum(w), np.sum(vs * w) / np.sum(w)]
            for w in (np.where(labels == i, redness, 0.0) for i in range(1, n))
        ]
    )
    for expected in uv:
        assert np.min(np.linalg.norm(centroids - expected, axis=1)) < 0.3


def test_fixed_base_robot_with_world_link() -> None:
    text = f"""<robot name="arm"><link name="world"/>
      <link name="base"><inertial><mass value="1"/>{INERTIA}</inertial></link>
      <joint name="fix" type="fixed"><parent link="world"/><child link="base"/>
        <origin xyz="0 0 1"/></joint>
      <link name="link1"><inertial><mass value="1"/>{INERTIA}</inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""
    model, data, _, handles = compile_robot(text, spawn=(2.0, 0.0, 0.0, math.pi / 2))
    assert handles.free_joint is None
    assert handles.bodies["world"] == "world"
    assert model.njnt == 1
    np.testing.assert_allclose(data.xpos[model.body("r/base").id], [2.0, 0.0, 1.0], atol=1e-12)


def test_two_robots_need_distinct_prefixes() -> None:
    desc = load_robot(ROBOT)
    spec = mujoco.MjSpec()
    add_robot_to_spec(spec, desc, prefix="a/")
    add_robot_to_spec(spec, desc, prefix="b/", spawn_xyz_yaw=(2, 0, 0, 0))
    model = spec.compile()
    assert model.camera("a/cam").id != model.camera("b/cam").id
    with pytest.raises(RobotDescriptionError, match=r"already exists.*prefix"):
        add_robot_to_spec(spec, desc, prefix="a/")


def test_moving_link_without_mass_is_an_error() -> None:
    text = f"""<robot name="x"><link name="a"><inertial><mass value="1"/>{INERTIA}</inertial>
      </link><link name="b"/><joint name="j" type="continuous"><parent link="a"/>
      <child link="b"/></joint></robot>"""
    with pytest.raises(RobotDescriptionError, match=r"link 'b' is moved by continuous joint 'j'"):
        add_robot_to_spec(mujoco.MjSpec(), load_robot(text))
    floating = '<robot name="x"><link name="a"/></robot>'
    with pytest.raises(RobotDescriptionError, match="root link 'a' floats freely"):
        add_robot_to_spec(mujoco.MjSpec(), load_robot(floating))
    with pytest.raises(RobotDescriptionError, match="spawn_xyz_yaw"):
        add_robot_to_spec(mujoco.MjSpec(), load_robot(ROBOT), spawn_xyz_yaw=(0, 0, 0))


def test_point_mass_gets_minimal_inertia_and_mesh_geoms(tmp_path: Path) -> None:
    (tmp_path / "part.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    )
    path = tmp_path / "p.urdf"
    path.write_text(
        """<robot name="p"><link name="a"><inertial><mass value="2"/>
        <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
        <visual><geometry><mesh filename="part.obj" scale="0.5 0.5 0.5"/></geometry></visual>
        <collision><geometry><mesh filename="part.obj" scale="0.5 0.5 0.5"/></geometry>
        </collision></link></robot>"""
    )
    desc = load_robot(path)
    spec = mujoco.MjSpec()
    add_robot_to_spec(spec, desc)
    model = spec.compile()
    assert model.nmesh == 2  # the visual's triangles, the collision's convex hull points
    assert model.body("a").mass[0] == 2.0
    assert (model.body("a").inertia > 0).all()
