"""Observe a bag: every message with its record time, through the same builder as live.

A bag has no graph: checks that need subscriptions are skipped, and the publishers'
offered QoS comes from the bag's metadata. Record times are receive times (wall clock,
or ``/clock`` time for a recorder with ``use_sim_time``); ``/clock`` in the bag maps
them to ROS time as live.

Images recorded through image_transport's compressed transports (``<topic>/compressed``,
``<topic>/compressedDepth``, as ``visnav run --record-images`` stores them) are observed as
an image_transport subscriber sees them: as the ``sensor_msgs/Image`` topic ``<topic>``, its
sampled frames decoded, so the image, depth and camera_info checks run on them (unless the
raw topic itself is in the bag too; then the compressed one is observed as it is).
"""

from __future__ import annotations

import struct
from pathlib import Path

from visnav.bag.errors import CorruptBagError
from visnav.bag.image_compression import IMAGE, decode_image, image_topics
from visnav.bag.qos import playback_qos
from visnav.bag.reader import BagReader
from visnav.doctor.builder import HEAVY_TYPES, ObservationBuilder, SamplingPolicy
from visnav.doctor.errors import DoctorError
from visnav.doctor.observation import Observation

__all__ = ["observe_bag", "read_header"]

_CDR_LE = b"\x00\x01"
_CDR_BE = b"\x00\x00"


def read_header(data: bytes | memoryview, *, ros1: bool = False) -> tuple[int, str] | None:
    """``(stamp ns, frame_id)`` of a serialized message that starts with a ``std_msgs/Header``.

    Reads CDR (ROS 2) or ROS 1 bytes without deserializing the rest (images and clouds
    that are not kept as samples). None when the bytes do not look like a header.
    """
    buf = memoryview(data)
    try:
        if ros1:  # uint32 seq, uint32 sec, uint32 nsec, uint32 len, chars
            _, sec, nsec, n = struct.unpack_from("<IIII", buf, 0)
            start = 16
        else:
            if bytes(buf[:2]) == _CDR_LE:
                order = "<"
            elif bytes(buf[:2]) == _CDR_BE:
                order = ">"
            else:
                return None
            sec, nsec, n = struct.unpack_from(order + "iII", buf, 4)
            start = 16
            n = max(0, n - 1)  # CDR strings count their NUL
        if nsec >= 1_000_000_000 or start + n > len(buf):
            return None
        frame = bytes(buf[start : start + n]).decode("utf-8")
    except (struct.error, UnicodeDecodeError):
        return None
    return sec * 1_000_000_000 + nsec, frame


def observe_bag(
    path: str | Path,
    *,
    duration_s: float | None = None,
    policy: SamplingPolicy | None = None,
) -> Observation:
    """Read a bag (any format visnav reads) into an observation.

    Args:
        path: the bag.
        duration_s: only the first ``duration_s`` seconds of record time (default: all).
        policy: sample decimation.

    Raises:
        BagNotFoundError, UnknownStorageError, CorruptBagError: the bag cannot be read.
        DoctorError: a non-positive duration.
    """
    if duration_s is not None and not duration_s > 0:
        msg = f"--duration is {duration_s}: expected seconds > 0"
        raise DoctorError(msg)
    builder = ObservationBuilder(source="bag", label=f"bag {path}", policy=policy)
    with BagReader(path) as reader:
        topics = reader.topics
        as_image = {
            stored: base
            for base, stored in image_topics((n, m.type_name) for n, m in topics.items()).items()
            if stored != base
        }
        for name, meta in topics.items():
            profiles = [playback_qos([q]) for q in meta.qos]
            shown, type_name = (
                (as_image[name], IMAGE) if name in as_image else (name, meta.type_name)
            )
            builder.declare_topic(shown, type_name, qos=profiles)
        stop = None
        if duration_s is not None and reader.start_ns:
            stop = reader.start_ns + round(duration_s * 1e9)
        broken: set[str] = set()
        for raw in reader.raw_messages(stop_ns=stop):
            if raw.topic in broken:
                continue
            name, type_name = raw.topic, raw.type_name
            if name in as_image:
                name, type_name = as_image[name], IMAGE
            if type_name in HEAVY_TYPES and not builder.wants_sample(name, type_name, raw.t_ns):
                header = read_header(raw.data, ros1=reader.is_ros1)
                if header is not None:
                    builder.add_header(name, type_name, raw.t_ns, *header)
                    continue
            try:
                message = reader.decode(raw)
                if name != raw.topic:
                    message = decode_image(message)
            except (CorruptBagError, ValueError):
                broken.add(raw.topic)
                builder.mark_undecodable(name, type_name)
                continue
            builder.add(name, type_name, raw.t_ns, message)
        if reader.start_ns or reader.end_ns:
            end = reader.end_ns if stop is None else min(reader.end_ns, stop)
            builder.set_window(reader.start_ns, end)
    return builder.build()
