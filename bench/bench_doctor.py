"""doctor benchmark (issue 6): ``visnav doctor --bag`` on a 60 s car recording, budget 10 s.

Run: ``python bench/bench_doctor.py [--seconds 60] [--keep DIR]``. Prints medians of repeated
runs.

The recording is built here with the bag writer from :mod:`visnav.doctor.synthetic`'s car
stream, because ``visnav run car`` does not exist yet: 640x480 rgb8 images and camera_info
at 30 Hz, 640x480 32FC1 depth, its camera_info and the organized 640x480 point cloud at
20 Hz, odometry and ``odom -> base_footprint`` at 50 Hz, ``/clock`` at 100 Hz, the mounts
on ``/tf_static`` (about 9 GB of MCAP). Reported:

* ``doctor``: :func:`visnav.doctor.doctor_bag` (read, observe, every check, report);
* reference: iterating the bag's raw messages with ``BagReader`` alone (the I/O floor),
  measured in the same run; the ratio doctor / reference is the cost of doctor's work.
Target: doctor <= 10 s.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

REPEATS = 3
BUDGET_S = 10.0


def build(path: Path, seconds: float) -> tuple[float, int]:
    from visnav.doctor.synthetic import CarStreamConfig, car_stream, write_bag

    cfg = CarStreamConfig(duration_s=seconds, width=640, height=480, cloud_stride=1)
    t = time.perf_counter()
    write_bag(car_stream(cfg), path)
    size = sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    return time.perf_counter() - t, size


def read_only(path: Path) -> float:
    from visnav.bag.reader import BagReader

    t = time.perf_counter()
    n = 0
    with BagReader(path) as reader:
        for raw in reader.raw_messages():
            n += len(raw.data)
    return time.perf_counter() - t


def doctor(path: Path) -> tuple[float, int, int]:
    from visnav.doctor import doctor_bag

    t = time.perf_counter()
    report = doctor_bag(path, fixed_frame="odom")
    dt = time.perf_counter() - t
    return dt, len(report.findings), int(report.summary["messages"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--keep", type=Path, default=None, help="build/reuse the bag here")
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_doctor_"))
    try:
        path = args.keep or tmp / "car"
        if not path.exists():
            build_s, size = build(path, args.seconds)
            print(
                f"built {args.seconds:.0f} s car recording: {size / 1e9:.2f} GB in {build_s:.1f} s"
            )
        read_only(path)  # warm the page cache
        ref = [read_only(path) for _ in range(REPEATS)]
        runs = [doctor(path) for _ in range(REPEATS)]
        times = [r[0] for r in runs]
        med, ref_med = statistics.median(times), statistics.median(ref)
        print(f"messages: {runs[0][2]}, findings on the clean recording: {runs[0][1]}")
        print(
            f"reference (raw read of the bag): median {ref_med:.2f} s  runs {[round(x, 2) for x in ref]}"
        )
        print(
            f"doctor --bag:                    median {med:.2f} s  runs {[round(x, 2) for x in times]}"
        )
        print(f"ratio doctor / raw read: {med / ref_med:.2f}")
        print(
            f"budget {BUDGET_S:.0f} s: {'met' if med <= BUDGET_S else 'MISSED'} ({med / BUDGET_S:.2f} of it)"
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
