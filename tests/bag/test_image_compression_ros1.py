"""Compressed images in a ROS 1 bag, read back by Debian's rosbag and decoded independently.

The recorder writes a ROS 1 ``.bag`` with ``<topic>/compressed`` and
``<topic>/compressedDepth``; the system Python's ``rosbag`` (ROS 1, genpy messages) reads it,
and PIL decodes the JPEG and the PNG, the compressedDepth header and inverse depth being undone
as compressed_depth_image_transport's decoder does (``A / (v - B)``, 0 -> NaN), written here
from its description, not from visnav's codec.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from visnav.bag import BagRecorder
from visnav.bag.image_compression import ImageCompression
from visnav.graph import Context, Node
from visnav.msgs import Header, Image
from visnav.msgs.image import numpy_to_image
from visnav.msgs.time import ns_to_time

SYSTEM_PYTHON = "/usr/bin/python3"

READER = r"""
import io, json, struct, sys
import numpy as np
import rosbag
from PIL import Image as PILImage
out = {}
with rosbag.Bag(sys.argv[1]) as bag:
    for topic, msg, t in bag.read_messages():
        data = bytes(msg.data)
        entry = {"type": msg._type, "format": msg.format, "frame_id": msg.header.frame_id,
                 "stamp": [msg.header.stamp.secs, msg.header.stamp.nsecs]}
        if "compressedDepth" in msg.format:
            fmt, a, b = struct.unpack("<iff", data[:12])
            png = np.array(PILImage.open(io.BytesIO(data[12:])), dtype=np.float64)
            depth = np.where(png != 0, a / (png - b), np.nan)
            entry.update(config=[fmt, a, b], depth=np.nan_to_num(depth, nan=-1.0).tolist())
        else:
            rgb = np.array(PILImage.open(io.BytesIO(data)).convert("RGB"), dtype=np.int64)
            entry.update(rgb_mean=rgb.reshape(-1, 3).mean(axis=0).tolist(), shape=list(rgb.shape))
        out[topic] = entry
print(json.dumps(out))
"""


def _system_rosbag() -> bool:
    if shutil.which(SYSTEM_PYTHON) is None:
        return False
    probe = "import rosbag, numpy, PIL"
    found = subprocess.run([SYSTEM_PYTHON, "-c", probe], check=False, capture_output=True)
    return found.returncode == 0


@pytest.mark.skipif(not _system_rosbag(), reason="Debian python3-rosbag with numpy/PIL needed")
def test_ros1_rosbag_reads_compressed_images(tmp_path: Path) -> None:
    h, w = 24, 32
    y, x = np.mgrid[0:h, 0:w]
    depth = (1.0 + 0.1 * x + 0.05 * y).astype(np.float32)
    depth[0, 0] = np.nan
    header = Header(stamp=ns_to_time(5_000_000_123), frame_id="cam_optical")
    colour = numpy_to_image(np.full((h, w, 3), (220, 40, 90), np.uint8), "rgb8", header=header)
    with Context(transport="local") as ctx:
        node = Node("camera", context=ctx)
        pubs = [
            node.create_publisher(Image, "/cam/image_raw", 10),
            node.create_publisher(Image, "/cam/depth", 10),
        ]
        rec = BagRecorder(
            ctx, None, tmp_path / "b.bag", fmt="ros1", image_transport=ImageCompression()
        )
        rec.start()
        ctx.spin_some()
        pubs[0].publish(colour)
        pubs[1].publish(numpy_to_image(depth, "32FC1", header=header))
        ctx.spin_some()
        path = rec.stop()
    result = subprocess.run(
        [SYSTEM_PYTHON, "-c", READER, str(path)], capture_output=True, text=True, check=True
    )
    got = json.loads(result.stdout)
    jpeg = got["/cam/image_raw/compressed"]
    assert jpeg["type"] == "sensor_msgs/CompressedImage"
    assert jpeg["format"] == "rgb8; jpeg compressed bgr8"
    assert jpeg["frame_id"] == "cam_optical"
    assert jpeg["stamp"] == [5, 123]
    assert jpeg["shape"] == [h, w, 3]
    assert np.allclose(jpeg["rgb_mean"], (220, 40, 90), atol=3)  # R, G, B: not swapped
    png = got["/cam/depth/compressedDepth"]
    assert png["format"] == "32FC1; compressedDepth png"
    fmt, a, b = png["config"]
    assert fmt == 0
    assert a == pytest.approx(10100.0)
    assert b == pytest.approx(1.0 - 10100.0 / 10.0)
    back = np.array(png["depth"])
    assert back[0, 0] == -1.0  # NaN stays invalid
    ok = np.isfinite(depth)
    assert np.abs(back[ok] - depth[ok]).max() <= (depth[ok] ** 2 / a).max() * 1.01
