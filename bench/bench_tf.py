"""Benchmark: Buffer.lookup_transform through a 4-link chain vs pytransform3d.

Chain: map -> odom (dynamic, 10 Hz) -> base_link (dynamic, 50 Hz) -> camera_link
(static) -> camera_optical (static). Lookups at a time between samples, so both
dynamic links interpolate (lerp + slerp). The reference is pytransform3d's
TransformManager.get_transform on the same four links (static matrices: it has
no time axis), measured in the same run.

Run: python bench/bench_tf.py
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable

import numpy as np
from pytransform3d.transform_manager import TransformManager

from visnav.msgs import Header, Quaternion, Time, Transform, TransformStamped, Vector3
from visnav.tf import Buffer, quaternion_from_euler, translation_quaternion_to_matrix

S = 1_000_000_000
BATCH = 50
BATCHES = 400
TARGET_US = 20.0


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
        t0 = time.perf_counter_ns()
        for _ in range(BATCH):
            fn()
        per_call.append((time.perf_counter_ns() - t0) / BATCH / 1000.0)
    return statistics.median(per_call)


def main() -> None:
    buf = Buffer()
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
    t = 5_555_000_000  # between samples of both dynamic links

    tm = TransformManager(check=False)
    links = [
        ("map", "odom", buf.lookup_transform_matrix("map", "odom", t)),
        ("odom", "base_link", buf.lookup_transform_matrix("odom", "base_link", t)),
        ("base_link", "camera_link", buf.lookup_transform_matrix("base_link", "camera_link")),
        (
            "camera_link",
            "camera_optical",
            translation_quaternion_to_matrix([0, 0, 0], [-0.5, 0.5, -0.5, 0.5]),
        ),
    ]
    for parent, child, mat in links:
        tm.add_transform(child, parent, mat)  # child2parent
    ours = buf.lookup_transform_matrix("map", "camera_optical", t)
    ref = tm.get_transform("camera_optical", "map")
    err = float(np.max(np.abs(ours - ref)))
    assert err < 1e-9, f"results differ by {err}"

    rows = [
        (
            "lookup_transform (msg), interpolated",
            lambda: buf.lookup_transform("map", "camera_optical", t),
        ),
        ("lookup_transform (msg), time 0", lambda: buf.lookup_transform("map", "camera_optical")),
        (
            "lookup_transform (msg), inverse direction",
            lambda: buf.lookup_transform("camera_optical", "map", t),
        ),
        (
            "lookup_transform_matrix, interpolated",
            lambda: buf.lookup_transform_matrix("map", "camera_optical", t),
        ),
        ("can_transform", lambda: buf.can_transform("map", "camera_optical", t)),
    ]
    ref_us = median_us(lambda: tm.get_transform("camera_optical", "map"))
    print(
        f"4-link chain (2 dynamic links interpolated, 2 static): median of {BATCHES}x{BATCH} calls"
    )
    print(f"{'pytransform3d TransformManager.get_transform':48s} {ref_us:8.2f} us  (reference)")
    main_us = math.nan
    for name, fn in rows:
        us = median_us(fn)
        if name.startswith("lookup_transform (msg), interpolated"):
            main_us = us
        print(f"{name:48s} {us:8.2f} us  ratio to reference {us / ref_us:5.2f}")
    verdict = "OK" if main_us <= TARGET_US else "OVER TARGET"
    print(f"target: lookup_transform <= {TARGET_US:.0f} us median -> {main_us:.2f} us {verdict}")
    print(f"max |ours - pytransform3d| = {err:.2e}")


if __name__ == "__main__":
    main()
