"""DisplaySink batching: one wake-up per batch, a batch's /tf merged in order, flush not delayed."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

pytest.importorskip("rerun")

from visnav.viz.display_sink import DisplaySink

MS = 1_000_000


class _Calls:
    """A stand-in RerunSink keeping every (topic, message) the worker hands it."""

    fixed_frame = None

    def __init__(self) -> None:
        self.calls: list[tuple[str, Any]] = []
        self.release = threading.Event()
        self.release.set()

    def log(self, topic: str, msg: Any, stamp_ns: int | None = None) -> bool:
        self.release.wait(10.0)
        self.calls.append((topic, msg))
        return True

    def poll(self) -> None:
        pass

    def close(self) -> None:
        pass

    def stats(self) -> dict[str, dict[str, Any]]:
        return {}


def _stamps(msg: Any) -> list[int]:
    return [t.header.stamp.sec * 10**9 + t.header.stamp.nanosec for t in msg.transforms]


def test_a_batch_of_tf_messages_is_one_message_with_every_transform_in_order(vz: Any) -> None:
    rec = _Calls()
    sink = DisplaySink(rec, batch_hz=0.5)  # type: ignore[arg-type]
    try:
        sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", 0)))  # wakes the worker: 1st batch
        assert sink.flush(5.0)
        for i in range(1, 11):  # queued while the worker waits out its batch interval
            sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", i * MS), vz.tf("base", "cam", i * MS)))
        sink.log("/tf_static", vz.tf_msg(vz.tf("base", "lidar", 0)))
        sink.log("/tf", vz.tf_msg(vz.tf("map", "odom", 11 * MS)))
        assert sink.flush(5.0)
    finally:
        sink.close()
    topics = [topic for topic, _ in rec.calls]
    assert topics == ["/tf", "/tf", "/tf_static"]  # the merged /tf before the static one
    merged = rec.calls[1][1]
    assert merged.__msgtype__ == "tf2_msgs/msg/TFMessage"
    expected = [t * MS for i in range(1, 11) for t in (i, i)] + [11 * MS]
    assert _stamps(merged) == expected
    assert [t.child_frame_id for t in merged.transforms][-3:] == ["base", "cam", "odom"]


def test_bulky_messages_are_not_merged_and_keep_their_order(vz: Any) -> None:
    rec = _Calls()
    rec.release.clear()  # the worker holds the first message until the rest are queued
    sink = DisplaySink(rec, batch_hz=0.0)  # type: ignore[arg-type]
    try:
        sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", 0)))
        time.sleep(0.05)
        for i in range(1, 4):
            sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", i * 100 * MS)))
            sink.log("/odom_text", vz.header("odom", i))  # not a TF message: passed as is
        rec.release.set()
        assert sink.flush(5.0)
    finally:
        sink.close()
    expected = ["/tf", "/tf", *["/odom_text"] * 3]
    assert [topic for topic, _ in rec.calls] == expected
    assert _stamps(rec.calls[1][1]) == [100 * MS, 200 * MS, 300 * MS]


def test_flush_and_close_do_not_wait_for_the_batch_interval(vz: Any) -> None:
    rec = _Calls()
    sink = DisplaySink(rec, batch_hz=0.1)  # a batch every 10 s at most
    try:
        sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", 0)))
        assert sink.flush(5.0)
        sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", MS)))
        start = time.perf_counter()
        assert sink.flush(5.0)
        assert time.perf_counter() - start < 2.0
        sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", 2 * MS)))
        start = time.perf_counter()
    finally:
        sink.close()
    assert time.perf_counter() - start < 2.0
    assert len(rec.calls) == 3  # close logged the last one
