"""do_transform_* and Buffer.transform against hand-computed values, pytransform3d and tf2.

The oracle is ROS 1's tf2_geometry_msgs / tf2_sensor_msgs (Debian
python3-tf2-geometry-msgs, python3-tf2-sensor-msgs) run in the system Python on
the same inputs.
"""

from __future__ import annotations

import json
import math
import subprocess
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pytransform3d import transformations as pt

from visnav.msgs import (
    Header,
    Point,
    PointStamped,
    Pose,
    PoseStamped,
    PoseWithCovariance,
    PoseWithCovarianceStamped,
    Quaternion,
    Time,
    Transform,
    TransformStamped,
    Vector3,
    Vector3Stamped,
    Wrench,
    WrenchStamped,
)
from visnav.msgs.pointcloud import cloud_to_structured, structured_to_cloud
from visnav.tf import (
    Buffer,
    ExtrapolationException,
    InvalidArgumentException,
    TransformException,
    do_transform_cloud,
    do_transform_point,
    do_transform_pose,
    do_transform_pose_with_covariance_stamped,
    do_transform_vector3,
    do_transform_wrench,
    quaternion_from_euler,
)

S = 1_000_000_000
SYSTEM_PYTHON = "/usr/bin/python3"


def tf(
    parent: str, child: str, xyz: tuple[float, float, float], q: Any, stamp_ns: int = 2 * S
) -> TransformStamped:
    return TransformStamped(
        Header(Time(*divmod(stamp_ns, S)), parent),
        child,
        Transform(Vector3(*xyz), Quaternion(*[float(v) for v in q])),
    )


# map <- base: 90 degrees about z, then (1, 2, 3).
YAW90 = tf("map", "base", (1.0, 2.0, 3.0), (0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)))
BASE_HEADER = Header(Time(2, 0), "base")


def test_point_rotates_and_translates() -> None:
    out = do_transform_point(PointStamped(BASE_HEADER, Point(1.0, 0.0, 0.0)), YAW90)
    assert (out.point.x, out.point.y, out.point.z) == pytest.approx((1.0, 3.0, 3.0))
    assert out.header.frame_id == "map"
    assert out.header.stamp == YAW90.header.stamp


def test_vector_and_wrench_only_rotate() -> None:
    v = do_transform_vector3(Vector3Stamped(BASE_HEADER, Vector3(1.0, 0.0, 0.0)), YAW90)
    assert (v.vector.x, v.vector.y, v.vector.z) == pytest.approx((0.0, 1.0, 0.0))
    assert YAW90.transform.translation.x == 1.0  # ROS 1 zeroes it in place; visnav does not
    w = do_transform_wrench(
        WrenchStamped(BASE_HEADER, Wrench(Vector3(0.0, 2.0, 0.0), Vector3(0.0, 0.0, 5.0))), YAW90
    )
    assert (w.wrench.force.x, w.wrench.force.y) == pytest.approx((-2.0, 0.0))
    assert w.wrench.torque.z == pytest.approx(5.0)
    assert w.header.frame_id == "map"


def test_pose_and_unstamped_pose_match_pytransform3d() -> None:
    q = quaternion_from_euler(0.3, -0.2, 1.1)
    pose = Pose(Point(0.5, -1.0, 2.0), Quaternion(*[float(v) for v in q]))
    stamped = do_transform_pose(PoseStamped(BASE_HEADER, pose), YAW90)
    plain = do_transform_pose(pose, YAW90)
    assert isinstance(stamped, PoseStamped)
    assert isinstance(plain, Pose)
    assert stamped.pose == plain
    # pytransform3d: T_map_pose = T_map_base @ T_base_pose (its quaternions are w first).
    t_map_base = pt.transform_from_pq([1, 2, 3, math.sqrt(0.5), 0, 0, math.sqrt(0.5)])
    t_base_pose = pt.transform_from_pq([0.5, -1.0, 2.0, q[3], q[0], q[1], q[2]])
    ref = pt.pq_from_transform(t_map_base @ t_base_pose)
    o = plain.orientation
    got_q = np.array([o.w, o.x, o.y, o.z])
    assert np.allclose([plain.position.x, plain.position.y, plain.position.z], ref[:3])
    assert np.allclose(got_q * np.sign(got_q[0]), ref[3:] * np.sign(ref[3]))


def test_pose_with_covariance_rotates_the_covariance() -> None:
    cov = np.zeros((6, 6))
    cov[0, 0] = 4.0  # variance along base x ...
    cov[5, 5] = 0.1
    msg = PoseWithCovarianceStamped(
        BASE_HEADER,
        PoseWithCovariance(Pose(Point(0.0, 0.0, 0.0), Quaternion(0.0, 0.0, 0.0, 1.0)), cov.ravel()),
    )
    out = do_transform_pose_with_covariance_stamped(msg, YAW90)
    rotated = np.asarray(out.pose.covariance).reshape(6, 6)
    assert rotated[1, 1] == pytest.approx(4.0)  # ... is along map y
    assert rotated[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert rotated[5, 5] == pytest.approx(0.1)


def test_cloud_moves_xyz_and_keeps_other_fields() -> None:
    dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])
    pts = np.zeros((2, 3), dtype=dtype)  # organized 2 x 3
    pts["x"] = [[1, 2, 3], [4, 5, np.nan]]
    pts["intensity"] = [[10, 20, 30], [40, 50, 60]]
    cloud = structured_to_cloud(pts, header=BASE_HEADER, is_dense=False)
    out = do_transform_cloud(cloud, YAW90)
    assert (out.height, out.width, out.is_dense) == (2, 3, False)
    assert out.header.frame_id == "map"
    got = cloud_to_structured(out).reshape(2, 3)
    assert np.allclose(got["x"][0], [1.0, 1.0, 1.0])
    assert np.allclose(got["y"][0], [3.0, 4.0, 5.0])
    assert np.isnan(got["x"][1, 2])
    assert np.array_equal(got["intensity"], pts["intensity"])


def test_buffer_transform_looks_up_at_the_stamp_and_converts() -> None:
    buf = Buffer()
    buf.set_transform(tf("map", "base", (0.0, 0.0, 0.0), (0, 0, 0, 1), 1 * S), "t")
    buf.set_transform(tf("map", "base", (2.0, 0.0, 0.0), (0, 0, 0, 1), 3 * S), "t")
    point = PointStamped(Header(Time(2, 0), "base"), Point(0.0, 1.0, 0.0))
    out = buf.transform(point, "map")
    assert (out.point.x, out.point.y) == pytest.approx((1.0, 1.0))  # interpolated at 2 s
    assert out.header.frame_id == "map"
    arr = buf.transform(point, "map", new_type=np.ndarray)
    assert np.allclose(arr, [1.0, 1.0, 0.0])
    pose = PoseStamped(Header(Time(2, 0), "base"), Pose(Point(0, 0, 0), Quaternion(0, 0, 0, 1)))
    assert np.allclose(buf.transform(pose, "map", new_type=np.ndarray)[:3, 3], [1.0, 0.0, 0.0])
    late = PointStamped(Header(Time(5, 0), "base"), Point(0.0, 0.0, 0.0))
    with pytest.raises(ExtrapolationException):
        buf.transform(late, "map")
    with pytest.raises(TransformException, match="not a registered type for tf2 transform"):
        buf.transform(Point(0.0, 0.0, 0.0), "map")
    with pytest.raises(TransformException, match=r"converts only to numpy\.ndarray"):
        buf.transform(point, "map", new_type=dict)


def test_transform_full_through_a_fixed_frame() -> None:
    buf = Buffer()
    for k in range(4):  # the robot drives along x in odom at 1 m/s
        buf.set_transform(tf("odom", "base", (float(k), 0.0, 0.0), (0, 0, 0, 1), k * S), "t")
    seen = PointStamped(Header(Time(1, 0), "base"), Point(2.0, 0.0, 0.0))  # 2 m ahead at 1 s
    now = buf.transform_full(seen, "base", 3 * S, "odom")
    assert now.point.x == pytest.approx(0.0)  # reached by 3 s


# ------------------------------------------------------------------ ROS 1 oracle

ORACLE = r"""
import json, sys
import rospy
from geometry_msgs.msg import (TransformStamped, PointStamped, Vector3Stamped, PoseStamped,
                               WrenchStamped)
import tf2_geometry_msgs as g
from tf2_sensor_msgs.tf2_sensor_msgs import do_transform_cloud
from sensor_msgs import point_cloud2
from std_msgs.msg import Header
out = []
for t, p, v, pose, f, m in json.loads(sys.argv[1]):
    def tr():
        x = TransformStamped()
        x.header.frame_id, x.child_frame_id = "map", "base"
        x.header.stamp = rospy.Time(7, 5)
        (x.transform.translation.x, x.transform.translation.y,
         x.transform.translation.z) = t[:3]
        r = x.transform.rotation
        r.x, r.y, r.z, r.w = t[3:]
        return x
    ps = PointStamped(); ps.point.x, ps.point.y, ps.point.z = p
    vs = Vector3Stamped(); vs.vector.x, vs.vector.y, vs.vector.z = v
    po = PoseStamped(); po.pose.position.x, po.pose.position.y, po.pose.position.z = pose[:3]
    o = po.pose.orientation; o.x, o.y, o.z, o.w = pose[3:]
    w = WrenchStamped(); w.wrench.force.x, w.wrench.force.y, w.wrench.force.z = f
    w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z = m
    rp = g.do_transform_point(ps, tr()).point
    rv = g.do_transform_vector3(vs, tr()).vector
    rpose = g.do_transform_pose(po, tr()).pose
    rw = g.do_transform_wrench(w, tr()).wrench
    cloud = point_cloud2.create_cloud_xyz32(Header(frame_id="base"), [p, v])
    rc = list(point_cloud2.read_points(do_transform_cloud(cloud, tr())))
    q = rpose.orientation
    out.append({"point": [rp.x, rp.y, rp.z], "vector": [rv.x, rv.y, rv.z],
                "pose": [rpose.position.x, rpose.position.y, rpose.position.z,
                         q.x, q.y, q.z, q.w],
                "force": [rw.force.x, rw.force.y, rw.force.z],
                "torque": [rw.torque.x, rw.torque.y, rw.torque.z],
                "cloud": [list(c) for c in rc]})
print(json.dumps(out))
"""


def oracle_available() -> bool:
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import tf2_geometry_msgs, tf2_sensor_msgs.tf2_sensor_msgs"],
        capture_output=True,
        check=False,
    )
    return probe.returncode == 0


@pytest.mark.skipif(not oracle_available(), reason="python3-tf2-geometry-msgs/-sensor-msgs absent")
def test_equals_ros1_tf2_geometry_and_sensor_msgs() -> None:
    rng = np.random.default_rng(18)
    cases = []
    for _ in range(25):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        pq = rng.normal(size=4)
        pq /= np.linalg.norm(pq)
        cases.append(
            [
                [*rng.uniform(-5, 5, 3).tolist(), *q.tolist()],
                rng.uniform(-5, 5, 3).tolist(),
                rng.uniform(-5, 5, 3).tolist(),
                [*rng.uniform(-5, 5, 3).tolist(), *pq.tolist()],
                rng.uniform(-5, 5, 3).tolist(),
                rng.uniform(-5, 5, 3).tolist(),
            ]
        )
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", ORACLE, json.dumps(cases)],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    for (t, p, v, pose, f, m), want in zip(cases, json.loads(done.stdout), strict=True):
        transform = tf("map", "base", tuple(t[:3]), t[3:], 7 * S + 5)
        h = Header(Time(3, 0), "base")
        rp = do_transform_point(PointStamped(h, Point(*p)), transform)
        assert np.allclose([rp.point.x, rp.point.y, rp.point.z], want["point"], atol=1e-12)
        assert rp.header.stamp == Time(7, 5)
        rv = do_transform_vector3(Vector3Stamped(h, Vector3(*v)), transform).vector
        assert np.allclose([rv.x, rv.y, rv.z], want["vector"], atol=1e-12)
        rpose = do_transform_pose(
            PoseStamped(h, Pose(Point(*pose[:3]), Quaternion(*pose[3:]))), transform
        )
        assert isinstance(rpose, PoseStamped)
        o = rpose.pose.orientation
        got = np.array([*_xyz(rpose.pose.position), o.x, o.y, o.z, o.w])
        ref = np.array(want["pose"])
        assert np.allclose(got[:3], ref[:3], atol=1e-12)
        assert np.allclose(got[3:] * np.sign(got[6]), ref[3:] * np.sign(ref[6]), atol=1e-12)
        rw = do_transform_wrench(
            WrenchStamped(h, Wrench(Vector3(*f), Vector3(*m))), transform
        ).wrench
        assert np.allclose(_xyz(rw.force), want["force"], atol=1e-12)
        assert np.allclose(_xyz(rw.torque), want["torque"], atol=1e-12)
        dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
        pts = np.array([tuple(p), tuple(v)], dtype=dtype)
        rc = cloud_to_structured(do_transform_cloud(structured_to_cloud(pts, header=h), transform))
        got_c = np.stack([rc["x"], rc["y"], rc["z"]], axis=1)
        assert np.allclose(got_c, want["cloud"], atol=1e-4)  # float32 fields


def _xyz(v: Any) -> list[float]:
    return [v.x, v.y, v.z]


@settings(max_examples=50, deadline=None)
@given(
    q=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
        lambda q: sum(x * x for x in q) > 0.1
    ),
    t=st.lists(st.floats(-10, 10), min_size=3, max_size=3),
    p=st.lists(st.floats(-10, 10), min_size=3, max_size=3),
)
def test_point_round_trip_through_the_inverse(
    q: list[float], t: list[float], p: list[float]
) -> None:
    n = math.sqrt(sum(x * x for x in q))
    quat = [x / n for x in q]
    forward = tf("map", "base", (t[0], t[1], t[2]), quat)
    buf = Buffer()
    buf.set_transform_static(forward, "t")
    there = do_transform_point(PointStamped(BASE_HEADER, Point(*p)), forward)
    back = buf.transform(there, "base")
    assert np.allclose(_xyz(back.point), p, atol=1e-9)


@settings(max_examples=150, deadline=None)
@given(
    data=st.binary(max_size=64),
    height=st.integers(0, 3),
    width=st.integers(0, 5),
    point_step=st.integers(0, 20),
    names=st.lists(st.sampled_from(["x", "y", "z", "rgb", ""]), max_size=4),
    datatype=st.integers(0, 9),
    offsets=st.lists(st.integers(-2, 24), min_size=4, max_size=4),
)
def test_fuzz_transform_cloud_only_tf_errors(
    data: bytes,
    height: int,
    width: int,
    point_step: int,
    names: list[str],
    datatype: int,
    offsets: list[int],
) -> None:
    from visnav.msgs import PointCloud2, PointField

    fields = [
        PointField(name=n, offset=o, datatype=datatype, count=1)
        for n, o in zip(names, offsets, strict=False)
    ]
    cloud = PointCloud2(
        header=BASE_HEADER,
        height=height,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=point_step,
        row_step=point_step * width,
        data=np.frombuffer(data, dtype=np.uint8),
        is_dense=False,
    )
    try:
        out = do_transform_cloud(cloud, YAW90)
    except InvalidArgumentException:
        return
    assert out.header.frame_id == "map"
