"""Shared helpers of the bag tests: sample messages of several kinds and their comparison."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from visnav.msgs import (
    CameraInfo,
    Header,
    Image,
    String,
    make,
    message_to_dict,
    ns_to_time,
)
from visnav.msgs.serde import get_message_class


def tf_message(i: int) -> Any:
    tf_cls = get_message_class("tf2_msgs/msg/TFMessage")
    ts_cls = get_message_class("geometry_msgs/msg/TransformStamped")
    ts = make(ts_cls, header=Header(stamp=ns_to_time(i), frame_id="odom"), child_frame_id="base")
    ts.transform.translation.x = float(i)
    ts.transform.rotation.w = 1.0
    return make(tf_cls, transforms=[ts])


def sample(topic: str, i: int) -> Any:
    """The i-th message of a test topic."""
    stamp = ns_to_time(1_000_000_000 + i)
    if topic == "/image":
        data = (np.arange(4 * 6 * 3, dtype=np.uint16) + i).astype(np.uint8)
        return make(
            Image,
            header=Header(stamp=stamp, frame_id="cam"),
            height=4,
            width=6,
            encoding="rgb8",
            step=18,
            data=data,
        )
    if topic == "/camera_info":
        msg = make(CameraInfo, header=Header(stamp=stamp, frame_id="cam"), width=6, height=4)
        msg.k[:] = np.arange(9, dtype=np.float64) + i
        msg.d = np.array([0.1, 0.2, 0.0, 0.0, float(i)])
        msg.distortion_model = "plumb_bob"
        return msg
    if topic == "/tf":
        return tf_message(i)
    return String(data=f"hello {i}")


TYPES = {
    "/image": Image,
    "/camera_info": CameraInfo,
    "/tf": get_message_class("tf2_msgs/msg/TFMessage"),
    "/chatter": String,
}


def as_dict(msg: Any) -> Any:
    """A comparable form of a message (numpy arrays -> lists)."""

    def fix(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, dict):
            return {k: fix(x) for k, x in v.items()}
        if isinstance(v, list):
            return [fix(x) for x in v]
        return v

    return fix(message_to_dict(msg))


@pytest.fixture
def local_ctx() -> Any:
    from visnav.graph import Context

    with Context(transport="local") as ctx:
        yield ctx


@pytest.fixture
def bagdata() -> Any:
    """The helpers above, for test modules (fixtures are how conftest helpers are shared)."""
    from types import SimpleNamespace

    return SimpleNamespace(sample=sample, as_dict=as_dict, TYPES=TYPES, tf_message=tf_message)
