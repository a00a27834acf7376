"""visnav.tf.initial_pose: nav2 AMCL's initial_pose.* group, shared by amcl and slam."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from visnav.graph import Context, Node
from visnav.graph.param_dataclass import declare_params
from visnav.mapping.amcl_node import AmclNode
from visnav.slam.node import SlamNode
from visnav.tf.errors import InvalidArgumentException
from visnav.tf.initial_pose import InitialPoseParams

finite = st.floats(-100.0, 100.0, allow_nan=False)


@settings(deadline=None)
@given(finite, finite, finite, st.floats(-10.0, 10.0, allow_nan=False))
def test_matrix_is_the_planar_pose(x: float, y: float, z: float, yaw: float) -> None:
    m = InitialPoseParams(x=x, y=y, z=z, yaw=yaw).matrix()
    expected = np.eye(4)
    expected[:3, :3] = Rotation.from_euler("z", yaw).as_matrix()
    expected[:3, 3] = (x, y, z)
    np.testing.assert_allclose(m, expected, atol=1e-12)
    # the form slam/node.py built by hand before: the same bits keep trajectories
    c, s = math.cos(yaw), math.sin(yaw)
    assert m[:2, :2].tolist() == [[c, -s], [s, c]]
    assert m[2, :3].tolist() == [0.0, 0.0, 1.0]


def test_a_non_finite_yaw_is_refused() -> None:
    with pytest.raises(InvalidArgumentException, match="yaw"):
        InitialPoseParams(yaw=math.inf).matrix()


def test_declared_with_nav2_names_on_both_nodes() -> None:
    pose = {"initial_pose.x": -6.0, "initial_pose.y": -1.5, "initial_pose.yaw": 1.5}
    with Context(transport="local") as ctx:
        node = Node("probe", context=ctx, parameter_overrides=pose)
        start = declare_params(node, InitialPoseParams, prefix="initial_pose.")
        assert (start.x, start.y, start.z, start.yaw) == (-6.0, -1.5, 0.0, 1.5)
        amcl = AmclNode(context=ctx, parameter_overrides=pose)
        assert amcl.initial == start
        slam = SlamNode(context=ctx, parameter_overrides={**pose, "set_initial_pose": True})
        for name in ("x", "y", "z", "yaw"):
            assert slam.has_parameter(f"initial_pose.{name}")
            assert amcl.has_parameter(f"initial_pose.{name}")
