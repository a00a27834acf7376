"""Benchmark: Buffer.lookup_transform on a 4-link chain vs tf2's C++ BufferCore and pytransform3d.

Chain: map -> odom (dynamic, 10 Hz) -> base_link (dynamic, 50 Hz) -> camera_link
(static) -> camera_optical (static). Lookups at a time between samples, so both
dynamic links interpolate (lerp + slerp).

References, measured in the same run:

* tf2's C++ ``BufferCore`` through its Python binding ``tf2_py`` (Debian package
  python3-tf2), driven in a worker subprocess of the system ``/usr/bin/python3`` on
  the same chain; it returns a ``geometry_msgs/TransformStamped`` as visnav does.
  Each row is timed for visnav and right after for tf2, ``ROUNDS`` times, so both
  see the same machine load. The column is skipped when the package is absent.
* pytransform3d's ``TransformManager.get_transform`` on the same four links (static
  matrices: it has no time axis and builds no message).

Times are thread CPU time (``time.thread_time_ns``) per batch of calls, so time
spent descheduled on a loaded machine is not counted; both sides are timed the same way.

Rows: one fixed lookup time; 1,000 distinct lookup times cycled (no answer can be
reused between calls); time 0 (latest common time); the inverse direction.

Run: python bench/bench_tf.py
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from pytransform3d.transform_manager import TransformManager

from visnav.msgs import Header, Quaternion, Time, Transform, TransformStamped, Vector3
from visnav.tf import Buffer, quaternion_from_euler, translation_quaternion_to_matrix

S = 1_000_000_000
BATCH = 50
BATCHES = 400
ROUNDS = 7  # each row: visnav then tf2, ROUNDS times; medians reported
T_FIXED = 5_555_000_000  # between samples of both dynamic links
# 1,000 distinct times in [1 s, 9 s), none on a sample stamp.
TIMES = [1_000_000_000 + 7_999_993 * k + 1_234_567 for k in range(1000)]
SYSTEM_PYTHON = "/usr/bin/python3"

# The same chain and timing loop in the system Python against tf2's C++ BufferCore.
TF2_SCRIPT = r"""
import json, math, statistics, sys, time
import rospy, tf2_py
from geometry_msgs.msg import TransformStamped
S = 10**9
BATCH, BATCHES, T_FIXED, TIMES = json.loads(sys.argv[1])
def yaw(a):
    return (0.0, 0.0, math.sin(a / 2), math.cos(a / 2))
def st(parent, child, ns, xyz, q):
    m = TransformStamped()
    m.header.frame_id = parent
    m.child_frame_id = child
    m.header.stamp = rospy.Time(ns // S, ns % S)
    tr, r = m.transform.translation, m.transform.rotation
    tr.x, tr.y, tr.z = xyz
    r.x, r.y, r.z, r.w = q
    return m
bc = tf2_py.BufferCore(rospy.Duration(10))
for i in range(100):
    bc.set_transform(st("map", "odom", i * S // 10, (0.01 * i, 0, 0), yaw(0.001 * i)), "slam")
for i in range(500):
    bc.set_transform(st("odom", "base_link", i * S // 50, (0.1 * i, 0.2, 0), yaw(0.01 * i)), "odom")
bc.set_transform_static(st("base_link", "camera_link", 0, (0.1, 0, 0.5), yaw(0.0)), "rsp")
bc.set_transform_static(
    st("camera_link", "camera_optical", 0, (0, 0, 0), (-0.5, 0.5, -0.5, 0.5)), "rsp")
t = rospy.Time(T_FIXED // S, T_FIXED % S)
zero = rospy.Time(0)
times = [rospy.Time(x // S, x % S) for x in TIMES]
def median_us(fn):
    for _ in range(200):
        fn()
    out = []
    for _ in range(BATCHES):
        t0 = time.thread_time_ns()
        for _ in range(BATCH):
            fn()
        out.append((time.thread_time_ns() - t0) / BATCH / 1000)
    return statistics.median(out)
def cycling():
    it = iter(())
    def fn():
        nonlocal it
        try:
            x = next(it)
        except StopIteration:
            it = iter(times)
            x = next(it)
        return bc.lookup_transform_core("map", "camera_optical", x)
    return fn
r = bc.lookup_transform_core("map", "camera_optical", t)
tr, q = r.transform.translation, r.transform.rotation
rows = {
    "fixed": lambda: bc.lookup_transform_core("map", "camera_optical", t),
    "cycling": cycling(),
    "zero": lambda: bc.lookup_transform_core("map", "camera_optical", zero),
    "inverse": lambda: bc.lookup_transform_core("camera_optical", "map", t),
}
print(json.dumps([tr.x, tr.y, tr.z, q.x, q.y, q.z, q.w]), flush=True)
for line in sys.stdin:  # one row name per line -> its median in microseconds
    print(json.dumps(median_us(rows[line.strip()])), flush=True)
"""


def stamped(
    parent: str,
    child: str,
    stamp_ns: int,
    xyz: tuple[float, float, float],
    yaw: float,
    q: tuple[float, float, float, float] | None = None,
) -> TransformStamped:
    qq = q if q is not None else tuple(quaternion_from_euler(0.0, 0.0, yaw))
    return TransformStamped(
        Header(Time(*divmod(stamp_ns, S)), parent),
        child,
        Transform(Vector3(*xyz), Quaternion(*qq)),
    )


def median_us(fn: Callable[[], object]) -> float:
    """Median over BATCHES of the mean per-call time of BATCH calls, in microseconds."""
    for _ in range(200):
        fn()
    per_call = []
    for _ in range(BATCHES):
        t0 = time.thread_time_ns()
        for _ in range(BATCH):
            fn()
        per_call.append((time.thread_time_ns() - t0) / BATCH / 1000.0)
    return statistics.median(per_call)


def cycling(lookup: Callable[[int], object]) -> Callable[[], object]:
    """A call that looks up the next of TIMES each time, wrapping around (as the tf2 side)."""
    it: Iterator[int] = iter(())

    def fn() -> object:
        nonlocal it
        try:
            x = next(it)
        except StopIteration:
            it = iter(TIMES)
            x = next(it)
        return lookup(x)

    return fn


class Tf2Worker:
    """tf2's C++ BufferCore in a system-Python subprocess, timing one row per request."""

    def __init__(self) -> None:
        args = json.dumps([BATCH, BATCHES, T_FIXED, TIMES])
        self._proc = subprocess.Popen(
            [SYSTEM_PYTHON, "-c", TF2_SCRIPT, args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self.pose = [float(v) for v in json.loads(self._readline())]

    def _readline(self) -> str:
        assert self._proc.stdout is not None
        line = self._proc.stdout.readline()
        if not line:
            raise SystemExit("the tf2 worker ended early")
        return line

    def median_us(self, row: str) -> float:
        assert self._proc.stdin is not None
        self._proc.stdin.write(row + "\n")
        self._proc.stdin.flush()
        return float(json.loads(self._readline()))

    def close(self) -> None:
        assert self._proc.stdin is not None
        self._proc.stdin.close()
        self._proc.wait(timeout=30)


def tf2_worker() -> Tf2Worker | None:
    """Start the tf2 side in the system Python; None when python3-tf2 is not installed."""
    if not Path(SYSTEM_PYTHON).exists():
        return None
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import tf2_py, rospy, geometry_msgs.msg"],
        capture_output=True,
        check=False,
    )
    return Tf2Worker() if probe.returncode == 0 else None


def build_buffer(*, jit: bool = False) -> Buffer:
    buf = Buffer(jit=jit)
    for i in range(100):  # 10 s of map -> odom at 10 Hz
        buf.set_transform(
            stamped("map", "odom", i * S // 10, (0.01 * i, 0.0, 0.0), 0.001 * i), "slam"
        )
    for i in range(500):  # 10 s of odom -> base_link at 50 Hz
        buf.set_transform(
            stamped("odom", "base_link", i * S // 50, (0.1 * i, 0.2, 0.0), 0.01 * i), "odom"
        )
    buf.set_transform_static(stamped("base_link", "camera_link", 0, (0.1, 0.0, 0.5), 0.0), "rsp")
    buf.set_transform_static(
        stamped("camera_link", "camera_optical", 0, (0.0, 0.0, 0.0), 0.0, (-0.5, 0.5, -0.5, 0.5)),
        "rsp",
    )
    return buf


def pytransform3d_reference(buf: Buffer) -> TransformManager:
    tm = TransformManager(check=False)
    links = [
        ("map", "odom", buf.lookup_transform_matrix("map", "odom", T_FIXED)),
        ("odom", "base_link", buf.lookup_transform_matrix("odom", "base_link", T_FIXED)),
        ("base_link", "camera_link", buf.lookup_transform_matrix("base_link", "camera_link")),
        (
            "camera_link",
            "camera_optical",
            translation_quaternion_to_matrix([0, 0, 0], [-0.5, 0.5, -0.5, 0.5]),
        ),
    ]
    for parent, child, mat in links:
        tm.add_transform(child, parent, mat)  # child2parent
    return tm


def main() -> None:
    buf = build_buffer()
    tm = pytransform3d_reference(buf)
    ours = buf.lookup_transform_matrix("map", "camera_optical", T_FIXED)
    err = float(np.max(np.abs(ours - tm.get_transform("camera_optical", "map"))))
    if err > 1e-9:
        raise SystemExit(f"visnav and pytransform3d differ by {err}")

    tf2 = tf2_worker()
    if tf2 is not None:
        msg = buf.lookup_transform("map", "camera_optical", T_FIXED).transform
        mine = [msg.translation.x, msg.translation.y, msg.translation.z]
        mine += [msg.rotation.x, msg.rotation.y, msg.rotation.z, msg.rotation.w]
        tf2_err = max(abs(a - b) for a, b in zip(mine, tf2.pose, strict=True))
        if tf2_err > 1e-9:
            raise SystemExit(f"visnav and tf2 differ by {tf2_err}")

    t0 = time.perf_counter()
    fast = build_buffer(jit=True)  # numba: import, compile or load the cache
    jit_setup_s = time.perf_counter() - t0
    jit_err = max(
        abs(a - b)
        for a, b in zip(
            fast.lookup_transform_matrix("map", "camera_optical", T_FIXED).ravel(),
            ours.ravel(),
            strict=True,
        )
    )
    if jit_err > 1e-12:
        raise SystemExit(f"Buffer(jit=True) and Buffer() differ by {jit_err}")
    rows: list[tuple[str, str, Callable[[], object]]] = [
        (
            "lookup_transform, interpolated, fixed time",
            "fixed",
            lambda: buf.lookup_transform("map", "camera_optical", T_FIXED),
        ),
        (
            "lookup_transform, interpolated, 1000 times",
            "cycling",
            cycling(lambda t: buf.lookup_transform("map", "camera_optical", t)),
        ),
        ("lookup_transform, time 0", "zero", lambda: buf.lookup_transform("map", "camera_optical")),
        (
            "lookup_transform, inverse direction",
            "inverse",
            lambda: buf.lookup_transform("camera_optical", "map", T_FIXED),
        ),
        (
            "lookup_transform_matrix, interpolated",
            "",
            lambda: buf.lookup_transform_matrix("map", "camera_optical", T_FIXED),
        ),
        ("can_transform", "", lambda: buf.can_transform("map", "camera_optical", T_FIXED)),
        (
            "Buffer(jit=True): interpolated, fixed time",
            "fixed",
            lambda: fast.lookup_transform("map", "camera_optical", T_FIXED),
        ),
        (
            "Buffer(jit=True): interpolated, 1000 times",
            "cycling",
            cycling(lambda t: fast.lookup_transform("map", "camera_optical", t)),
        ),
        (
            "Buffer(jit=True): time 0",
            "zero",
            lambda: fast.lookup_transform("map", "camera_optical"),
        ),
        (
            "Buffer(jit=True): inverse direction",
            "inverse",
            lambda: fast.lookup_transform("camera_optical", "map", T_FIXED),
        ),
    ]
    ref_us = median_us(lambda: tm.get_transform("camera_optical", "map"))
    ours_us: dict[str, list[float]] = {name: [] for name, _, _ in rows}
    tf2_us: dict[str, list[float]] = {name: [] for name, key, _ in rows if key}
    for _ in range(ROUNDS):  # each row: visnav, then tf2 right after (load drifts slowly)
        for name, key, fn in rows:
            ours_us[name].append(median_us(fn))
            if tf2 is not None and key:
                tf2_us[name].append(tf2.median_us(key))
    if tf2 is not None:
        tf2.close()
    print(
        f"4-link chain (2 dynamic links interpolated, 2 static): median of {ROUNDS} rounds of "
        f"{BATCHES}x{BATCH} calls, visnav and tf2 alternating per row; load average "
        f"{os.getloadavg()[0]:.2f}"
    )
    if tf2 is None:
        print("tf2 column skipped: python3-tf2 (tf2_py) not importable by /usr/bin/python3")
    head = f"{'':44s} {'visnav':>9s} {'tf2 C++':>9s} {'ratio':>6s} {'pytr3d':>9s} {'ratio':>6s}"
    print(head)
    worst = worst_jit = 0.0
    for name, _, _ in rows:
        us = statistics.median(ours_us[name])
        theirs = tf2_us.get(name, [])
        ref_tf2 = statistics.median(theirs) if theirs else math.nan
        # The ratio of each round's paired measurements, then the median over rounds.
        ratios = [a / b for a, b in zip(ours_us[name], theirs, strict=False)]
        ratio = statistics.median(ratios) if ratios else math.nan
        if not math.isnan(ratio) and name.startswith("Buffer(jit"):
            worst_jit = max(worst_jit, ratio)
        elif not math.isnan(ratio):
            worst = max(worst, ratio)
        print(
            f"{name:44s} {us:7.2f}us {ref_tf2:7.2f}us {ratio:6.2f} {ref_us:7.2f}us "
            f"{us / ref_us:6.2f}"
        )
    if tf2 is not None:
        for label, value in (("Buffer()", worst), ("Buffer(jit=True)", worst_jit)):
            verdict = "OK" if value <= 1.0 else "OVER TARGET"
            print(f"target <= 1.0x tf2 on every row: {label} worst {value:.2f}x {verdict}")
    print(f"max |visnav - pytransform3d| = {err:.2e}; Buffer(jit=True) set-up {jit_setup_s:.2f} s")


if __name__ == "__main__":
    main()
