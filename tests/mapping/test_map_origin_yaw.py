"""Map origin and initial-pose orientations go through visnav.tf.transforms (one yaw formula)."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.graph import Context
from visnav.mapping.amcl_node import AmclNode
from visnav.mapping.likelihood_field import LikelihoodField, LikelihoodFieldError
from visnav.mapping.map_io import MapMetadata, OccupancyMap
from visnav.msgs import make
from visnav.msgs.types import OccupancyGrid, PoseWithCovarianceStamped, Quaternion
from visnav.tf.transforms import quaternion_from_yaw


def _grid(yaw: float) -> OccupancyGrid:
    grid = np.zeros((4, 5), dtype=np.int8)
    meta = MapMetadata(image=Path("x"), resolution=0.5, origin=(1.0, -2.0, yaw))
    return OccupancyMap(grid, meta).to_msg()


@pytest.mark.parametrize("yaw", [0.0, 0.3, -2.5, math.pi])
def test_map_origin_yaw_round_trips(yaw: float) -> None:
    msg = _grid(yaw)
    assert msg.info.origin.orientation == quaternion_from_yaw(yaw)
    field = LikelihoodField.from_msg(msg)
    assert field.origin[:2] == (1.0, -2.0)
    assert math.remainder(field.origin[2] - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def test_a_zero_origin_quaternion_is_a_clear_error() -> None:
    msg = _grid(0.0)
    msg.info.origin.orientation = Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)
    with pytest.raises(LikelihoodFieldError, match=r"info\.origin\.orientation.*zero length"):
        LikelihoodField.from_msg(msg)


@settings(deadline=None, max_examples=50)
@given(st.tuples(*[st.floats(allow_nan=True, allow_infinity=True)] * 4))
def test_fuzz_origin_orientation_raises_only_the_field_error(q: tuple[float, ...]) -> None:
    msg = _grid(0.0)
    msg.info.origin.orientation = Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
    try:
        field = LikelihoodField.from_msg(msg)
    except LikelihoodFieldError:
        return
    assert math.isfinite(field.origin[2])


def test_amcl_ignores_an_initialpose_without_rotation(caplog: pytest.LogCaptureFixture) -> None:
    with Context(transport="local") as ctx:
        node = AmclNode(context=ctx)
        msg: PoseWithCovarianceStamped = make(PoseWithCovarianceStamped)
        msg.header.frame_id = "map"
        msg.pose.pose.orientation = Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)
        with caplog.at_level(logging.ERROR):
            node._on_initial_pose(msg)
        text = caplog.text
        assert "initialpose: pose.pose.orientation" in text
        assert "zero length" in text
        errors = len(caplog.records)
        msg.pose.pose.orientation = quaternion_from_yaw(0.7)
        with caplog.at_level(logging.ERROR):
            node._on_initial_pose(msg)  # a rotation: no error
        assert len(caplog.records) == errors
