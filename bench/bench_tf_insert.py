"""Benchmark: inserting ``/tf`` transforms (``Buffer.set_transform``) vs tf2's C++ ``BufferCore``.

Every node with a TF listener pays this per received transform (the viewer's sink, AMCL,
move_base's costmaps, SLAM): at 100 Hz ``/tf`` with 3 transforms per message it is 300
insertions a second per listener.

Rows (thread CPU time per insertion, median of batches; a batch inserts ``BATCH``
transforms of one child at increasing stamps, 10 ms apart, into a 10 s cache, so the
window slides as in a live run):

* ``Buffer.set_transform``: validation (frame ids, NaN, quaternion norm, stamp), the
  per-frame cache's append and slide;
* the viewer's ``FramePlacer.add_transforms`` of a 3-transform ``/tf`` message (the
  buffer's insertions plus the retry of data waiting for TF, none waiting here).

Reference, measured in the same run: tf2's C++ ``BufferCore.set_transform`` through its
Python binding ``tf2_py`` (Debian python3-tf2) in a system-Python subprocess, on the same
stamps (skipped when the package is absent).

Run: python bench/bench_tf_insert.py
"""

from __future__ import annotations

import json
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from visnav.msgs import Header, Quaternion, Time, Transform, TransformStamped, Vector3
from visnav.msgs.types import TFMessage
from visnav.tf import Buffer
from visnav.viz.placement import FramePlacer

S = 1_000_000_000
STEP_NS = 10_000_000
BATCH = 200
BATCHES = 150
SYSTEM_PYTHON = "/usr/bin/python3"

TF2_SCRIPT = r"""
import json, math, statistics, sys, time
import rospy, tf2_py
from geometry_msgs.msg import TransformStamped
S = 10**9
STEP, BATCH, BATCHES = json.loads(sys.argv[1])
def st(parent, child, ns, x):
    m = TransformStamped()
    m.header.frame_id = parent
    m.child_frame_id = child
    m.header.stamp = rospy.Time(ns // S, ns % S)
    m.transform.translation.x = x
    m.transform.rotation.z = math.sin(x / 2)
    m.transform.rotation.w = math.cos(x / 2)
    return m
bc = tf2_py.BufferCore(rospy.Duration(10))
n = BATCH * (BATCHES + 5)
msgs = [st("odom", "base_link", (i + 1) * STEP, i * 1e-3) for i in range(n)]
out = []
k = 0
for b in range(BATCHES + 5):
    batch = msgs[k : k + BATCH]
    k += BATCH
    t0 = time.thread_time_ns()
    for m in batch:
        bc.set_transform(m, "odom")
    if b >= 5:
        out.append((time.thread_time_ns() - t0) / BATCH / 1000)
print(json.dumps(statistics.median(out)), flush=True)
"""


def _stamped(parent: str, child: str, ns: int, x: float) -> TransformStamped:
    import math

    return TransformStamped(
        Header(Time(*divmod(ns, S)), parent),
        child,
        Transform(Vector3(x, 0.0, 0.0), Quaternion(0.0, 0.0, math.sin(x / 2), math.cos(x / 2))),
    )


def _median_us(items: list[object], insert: Callable[[object], object], per: int) -> float:
    out = []
    k = 0
    for b in range(BATCHES + 5):
        batch = items[k : k + BATCH]
        k += BATCH
        t0 = time.thread_time_ns()
        for item in batch:
            insert(item)
        if b >= 5:  # warm-up batches left out
            out.append((time.thread_time_ns() - t0) / BATCH / per / 1000)
    return statistics.median(out)


def _tf2_us() -> float | None:
    if not Path(SYSTEM_PYTHON).exists():
        return None
    args = json.dumps([STEP_NS, BATCH, BATCHES])
    proc = subprocess.run(
        [SYSTEM_PYTHON, "-c", TF2_SCRIPT, args], capture_output=True, text=True, check=False
    )
    if proc.returncode != 0:
        return None
    return float(proc.stdout.strip())


def main() -> None:
    """Measure and print."""
    n = BATCH * (BATCHES + 5)
    msgs: list[object] = [
        _stamped("odom", "base_link", (i + 1) * STEP_NS, i * 1e-3) for i in range(n)
    ]
    buf = Buffer(10.0)
    visnav_us = _median_us(msgs, lambda m: buf.set_transform(m, "odom"), 1)  # type: ignore[arg-type]
    tf2_us = _tf2_us()
    line = f"Buffer.set_transform: {visnav_us:.2f} us per transform"
    if tf2_us is not None:
        line += (
            f"; tf2 C++ BufferCore.set_transform: {tf2_us:.2f} us; ratio {visnav_us / tf2_us:.2f}"
        )
    print(line)
    tf_msgs: list[object] = [
        TFMessage(
            transforms=[
                _stamped("odom", "base_link", (i + 1) * STEP_NS, i * 1e-3),
                _stamped("base_link", "wheel_left", (i + 1) * STEP_NS, i * 1e-2),
                _stamped("base_link", "wheel_right", (i + 1) * STEP_NS, i * 1e-2),
            ]
        )
        for i in range(n)
    ]
    placer = FramePlacer("odom", cache_time_s=30.0)
    placer_us = _median_us(tf_msgs, lambda m: placer.add_transforms(m, static=False), 1)  # type: ignore[arg-type]
    print(
        f"viewer FramePlacer.add_transforms, 3 transforms per /tf message: {placer_us:.2f} us per message"
    )


if __name__ == "__main__":
    main()
