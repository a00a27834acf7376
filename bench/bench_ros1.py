"""ROS 1 bridge benchmark (issue 16): latency and bulk throughput of images into rospy.

Run: ``python bench/bench_ros1.py [--repeats N]``. Needs the Debian ROS 1 packages (roscore,
python3-rospy, python3-sensor-msgs). Starts its own ``roscore -p PORT`` and VISNAV_DOMAIN.

* Latency: a visnav process publishes 640x480 rgb8 images at 30 Hz (``header.stamp`` = wall
  clock); ``visnav bridge ros1`` carries them; a rospy subscriber (system python) records
  receive time minus stamp. Target: p95 <= 10 ms.
* Latency reference: a rospy publisher at 30 Hz to the same rospy subscriber, same run (one
  process hop less than visnav -> bridge -> rospy).
* Throughput: messages per second received by the rospy subscriber (counted for
  ``--duration`` seconds after a 2 s warm-up from its first message), against a rospy
  publisher sending the same images to the same kind of rospy subscriber (the reference,
  measured in the same run). Target: ratio >= 0.8. Measured twice: with both publishers
  flooding (no sleep: a visnav publisher then offers 3,000-4,000 images/s, most of them
  dropped by keep-last queues; a rospy one is paced by its own serialization), and with both
  offered the same rate (``--rate``, default 1000 Hz: more than either path carries here).

Prints medians over repeats.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SYSTEM_PYTHON = "/usr/bin/python3"
WIDTH, HEIGHT = 640, 480

ROSPY_SUB = """
import json, sys, time, rospy
from sensor_msgs.msg import Image
topic, duration, warmup = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
rospy.init_node("bench_sub", anonymous=True, disable_signals=True)
lat, count, t0 = [], [0], [None]
def cb(msg):
    now = time.time()
    if t0[0] is None:
        t0[0] = now
    if now - t0[0] < warmup:
        return
    count[0] += 1
    lat.append((now - msg.header.stamp.to_sec()) * 1000.0)
rospy.Subscriber(topic, Image, cb, queue_size=2, tcp_nodelay=True, buff_size=1 << 24)
print("ready", flush=True)
deadline = time.time() + 30.0
while t0[0] is None and time.time() < deadline:
    time.sleep(0.01)
if t0[0] is None:
    duration = warmup = 0.0
time.sleep(warmup + duration)
print(json.dumps({"count": count[0], "seconds": duration, "lat_ms": lat}), flush=True)
rospy.signal_shutdown("done")
"""

ROSPY_PUB = """
import sys, time, rospy
from sensor_msgs.msg import Image
rospy.init_node("bench_pub", anonymous=True, disable_signals=True)
pub = rospy.Publisher(sys.argv[1], Image, queue_size=2, tcp_nodelay=True)
msg = Image(height=480, width=640, encoding="rgb8", step=640 * 3, data=bytes(640 * 480 * 3))
end = time.time() + float(sys.argv[2])
period = 1.0 / float(sys.argv[3]) if float(sys.argv[3]) > 0 else 0.0
nxt = time.time()
while time.time() < end:
    msg.header.stamp = rospy.Time.from_sec(time.time())
    pub.publish(msg)
    if period:
        nxt += period
        time.sleep(max(0.0, nxt - time.time()))
"""

VISNAV_PUB = """
import sys, time
import numpy as np
from visnav.graph import Context, Node
from visnav.msgs import Header
from visnav.msgs.image import numpy_to_image
from visnav.msgs.time import ns_to_time
topic, rate, duration = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
with Context() as ctx:
    node = Node("bench_pub", context=ctx)
    frame = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    msg = numpy_to_image(frame, "rgb8", header=Header(stamp=ns_to_time(0), frame_id="camera"))
    pub = node.create_publisher(type(msg), topic, 2)
    end = time.monotonic() + duration
    period = 1.0 / rate if rate > 0 else 0.0
    nxt = time.monotonic()
    while time.monotonic() < end:
        msg.header.stamp = ns_to_time(time.time_ns())  # the same image, a new stamp (as rospy's)
        pub.publish(msg)
        if period:
            nxt += period
            time.sleep(max(0.0, nxt - time.monotonic()))
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Procs:
    def __init__(self, env: dict[str, str], tmp: Path) -> None:
        self.env, self.tmp, self.procs = env, tmp, []

    def start(self, argv: list[str], *, pipe: bool = False) -> subprocess.Popen[str]:
        proc = subprocess.Popen(
            argv,
            env=self.env,
            stdout=subprocess.PIPE if pipe else subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            text=True,
            start_new_session=True,
            cwd=self.tmp,
        )
        self.procs.append(proc)
        return proc

    def stop(self, proc: subprocess.Popen[str]) -> None:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()

    def close(self) -> None:
        for p in reversed(self.procs):
            self.stop(p)


def _subscribe(procs: Procs, topic: str, duration: float, warmup: float) -> subprocess.Popen[str]:
    sub = procs.start(
        [SYSTEM_PYTHON, "-c", ROSPY_SUB, topic, str(duration), str(warmup)], pipe=True
    )
    assert sub.stdout is not None
    line = sub.stdout.readline().strip()
    if line != "ready":
        raise SystemExit(f"rospy subscriber did not start: {line!r}")
    return sub


def _result(sub: subprocess.Popen[str]) -> dict[str, object]:
    assert sub.stdout is not None
    out = sub.stdout.readline()
    sub.wait(timeout=30)
    return json.loads(out)


def run_visnav(procs: Procs, topic: str, rate: float, duration: float) -> dict[str, object]:
    sub = _subscribe(procs, topic, duration, warmup=2.0)
    pub = procs.start([sys.executable, "-c", VISNAV_PUB, topic, str(rate), str(duration + 30)])
    res = _result(sub)
    procs.stop(pub)
    return res


def run_rospy(procs: Procs, topic: str, rate: float, duration: float) -> dict[str, object]:
    sub = _subscribe(procs, topic, duration, warmup=2.0)
    pub = procs.start([SYSTEM_PYTHON, "-c", ROSPY_PUB, topic, str(duration + 30), str(rate)])
    res = _result(sub)
    procs.stop(pub)
    return res


def _pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))] if s else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--rate", type=float, default=1000.0, help="offered rate of the 2nd bulk")
    args = parser.parse_args()
    print("load average (1, 5, 15 min) at the start: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    tmp = Path(tempfile.mkdtemp(prefix="bench_ros1_"))
    port = _free_port()
    env = {
        **os.environ,
        "ROS_MASTER_URI": f"http://127.0.0.1:{port}/",
        "ROS_IP": "127.0.0.1",
        "ROS_HOME": str(tmp),
        "VISNAV_DOMAIN": str(900_000 + os.getpid() % 50_000),
    }
    procs = Procs(env, tmp)
    try:
        procs.start(["roscore", "-p", str(port)])
        time.sleep(4.0)
        procs.start([sys.executable, "-m", "visnav.cli.main", "bridge", "ros1"])
        time.sleep(3.0)
        p50s, p95s, vis_rates, ros_rates, ref50s, ref95s = [], [], [], [], [], []
        vis_r: list[float] = []
        ros_r: list[float] = []
        for i in range(args.repeats):
            lat = run_visnav(procs, f"/lat{i}", 30.0, args.duration)
            lats = list(lat["lat_ms"])  # type: ignore[call-overload]
            p50s.append(_pct(lats, 0.5))
            p95s.append(_pct(lats, 0.95))
            ref_lat = run_rospy(procs, f"/reflat{i}", 30.0, args.duration)
            ref_lats = list(ref_lat["lat_ms"])  # type: ignore[call-overload]
            ref50s.append(_pct(ref_lats, 0.5))
            ref95s.append(_pct(ref_lats, 0.95))
            bulk = run_visnav(procs, f"/bulk{i}", 0.0, args.duration)
            ref = run_rospy(procs, f"/ref{i}", 0.0, args.duration)
            vis_rates.append(int(bulk["count"]) / args.duration)  # type: ignore[call-overload]
            ros_rates.append(int(ref["count"]) / args.duration)  # type: ignore[call-overload]
            bulk = run_visnav(procs, f"/rbulk{i}", args.rate, args.duration)
            ref = run_rospy(procs, f"/rref{i}", args.rate, args.duration)
            vis_r.append(int(bulk["count"]) / args.duration)  # type: ignore[call-overload]
            ros_r.append(int(ref["count"]) / args.duration)  # type: ignore[call-overload]
            print(
                f"run {i}: latency p50 {p50s[-1]:.2f} ms p95 {p95s[-1]:.2f} ms "
                f"({len(lats)} msgs at 30 Hz; rospy->rospy p50 {ref50s[-1]:.2f} p95 "
                f"{ref95s[-1]:.2f} ms); bulk visnav->rospy {vis_rates[-1]:.1f}/s, "
                f"rospy->rospy {ros_rates[-1]:.1f}/s; offered {args.rate:.0f} Hz: visnav->rospy "
                f"{vis_r[-1]:.1f}/s, rospy->rospy {ros_r[-1]:.1f}/s",
                flush=True,
            )
        med = statistics.median
        print(
            f"median over {args.repeats}: 640x480 rgb8 visnav -> rospy at 30 Hz: latency p50 "
            f"{med(p50s):.2f} ms, p95 {med(p95s):.2f} ms (target <= 10 ms); rospy -> rospy "
            f"in the same run: p50 {med(ref50s):.2f} ms, p95 {med(ref95s):.2f} ms"
        )
        ratio = med(vis_rates) / med(ros_rates)
        print(
            f"bulk, both flooding: visnav -> rospy {med(vis_rates):.1f} img/s, rospy -> rospy "
            f"{med(ros_rates):.1f} img/s, ratio {ratio:.2f} (target >= 0.8)"
        )
        print(
            f"bulk, both offered {args.rate:.0f} Hz: visnav -> rospy {med(vis_r):.1f} img/s, "
            f"rospy -> rospy {med(ros_r):.1f} img/s, ratio {med(vis_r) / med(ros_r):.2f} "
            "(target >= 0.8)"
        )
        print(
            "load average (1, 5, 15 min) at the end: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
        )
    finally:
        procs.close()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
