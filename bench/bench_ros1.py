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
  flooding (no sleep: a rospy publisher offers 500-1,000 images/s, most dropped by its
  per-subscriber queue; a visnav one calls ``publish`` tens of thousands of times a second
  and sends only while the bridge's paced subscription has room, the rest skipped), and
  with both offered the same rate (``--rate``, default 1000 Hz: more than either path
  carries here).
* For each bulk run also the rate each publisher offered in the counting window (SIGUSR1
  makes it print its count), the rate a visnav one sent (not skipped), and the CPU the
  processes used in it (cores: publisher, bridge, rospy subscriber, each also as CPU ms
  per image delivered): on a loaded machine the scheduler's shares decide the rates, and
  these say where the CPU went. The last lines give the median CPU per image delivered
  of the bridge and of all processes of each path, each path's publisher CPU (cores: both
  are busy loops when flooding, a fair contest needs them comparable) and the frames the
  rospy subscriber read per image it delivered (it reads whatever its socket holds and
  deserializes only the newest ``queue_size`` = 2 of each read: frames sent further ahead
  of it cost it a read and two copies each for nothing).

``--flood-only`` runs only the both-flooding bulk runs. Prints medians over repeats.
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
from typing import Any

SYSTEM_PYTHON = "/usr/bin/python3"
WIDTH, HEIGHT = 640, 480

ROSPY_SUB = """
import json, sys, time, rospy
import rospy.impl.tcpros_base as tcpros_base
from sensor_msgs.msg import Image
topic, duration, warmup = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
frames = [0, False]  # complete frames rospy read off the socket in the window (counting?)
_deserialize = tcpros_base.deserialize_messages
def deserialize_messages(b, msg_queue, data_class, queue_size=None, max_msgs=None, start=0):
    # rospy reads whatever the socket holds and deserializes only the newest queue_size
    # frames of it: count the complete frames it read (their length prefixes), then let it
    if frames[1]:
        pos, end = start, b.tell()
        while end - pos >= 4:
            b.seek(pos)
            size = int.from_bytes(b.read(4), "little")
            if end - pos - 4 < size:
                break
            pos += 4 + size
            frames[0] += 1
        b.seek(end)
    _deserialize(b, msg_queue, data_class, queue_size=queue_size, max_msgs=max_msgs, start=start)
tcpros_base.deserialize_messages = deserialize_messages
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
time.sleep(max(0.0, t0[0] + warmup - time.time()) if t0[0] else 0.0)
print("counting", flush=True)
frames[1] = True
cpu0 = time.process_time()
time.sleep(duration)
cpu = time.process_time() - cpu0
frames[1] = False
result = {"count": count[0], "seconds": duration, "lat_ms": lat, "cpu_s": cpu, "frames": frames[0]}
print(json.dumps(result), flush=True)
rospy.signal_shutdown("done")
"""

ROSPY_PUB = """
import signal, sys, time, rospy
from sensor_msgs.msg import Image
rospy.init_node("bench_pub", anonymous=True, disable_signals=True)
pub = rospy.Publisher(sys.argv[1], Image, queue_size=2, tcp_nodelay=True)
msg = Image(height=480, width=640, encoding="rgb8", step=640 * 3, data=bytes(640 * 480 * 3))
end = time.time() + float(sys.argv[2])
period = 1.0 / float(sys.argv[3]) if float(sys.argv[3]) > 0 else 0.0
nxt = time.time()
n = [0]  # SIGUSR1 prints the count and the time (the rate offered in a window)
signal.signal(signal.SIGUSR1, lambda *_: print(n[0], time.monotonic(), flush=True))
try:
    while time.time() < end:
        msg.header.stamp = rospy.Time.from_sec(time.time())
        pub.publish(msg)
        n[0] += 1
        if period:
            nxt += period
            time.sleep(max(0.0, nxt - time.time()))
except KeyboardInterrupt:
    pass
"""

VISNAV_PUB = """
import signal, sys, time
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
    n = [0]  # SIGUSR1 prints the count, the time and the samples skipped (nobody had room)
    zpub = pub._zpub
    signal.signal(
        signal.SIGUSR1,
        lambda *_: print(n[0], time.monotonic(), getattr(zpub, "skipped", 0), flush=True),
    )
    try:
        while time.monotonic() < end:
            msg.header.stamp = ns_to_time(time.time_ns())  # the same image, a new stamp (as rospy's)
            pub.publish(msg)
            n[0] += 1
            if period:
                nxt += period
                time.sleep(max(0.0, nxt - time.monotonic()))
    except KeyboardInterrupt:
        pass
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Procs:
    def __init__(self, env: dict[str, str], tmp: Path) -> None:
        self.env, self.tmp = env, tmp
        self.procs: list[subprocess.Popen[str]] = []

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


def _cpu_s(pid: int) -> float:
    """CPU time (user + system) a process has used so far, in seconds."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _result(
    procs: Procs, sub: subprocess.Popen[str], pub: subprocess.Popen[str], bridge: int | None
) -> dict[str, Any]:
    """The subscriber's counts, with the CPU shares (cores) of the processes in its window."""
    assert sub.stdout is not None
    assert pub.stdout is not None
    others = {"pub": pub.pid} if bridge is None else {"pub": pub.pid, "bridge": bridge}
    line = sub.stdout.readline().strip()
    t0, cpu0 = time.monotonic(), {k: _cpu_s(p) for k, p in others.items()}
    counting = line == "counting"
    if counting:
        pub.send_signal(signal.SIGUSR1)
        line = sub.stdout.readline()
        pub.send_signal(signal.SIGUSR1)
    t1, cpu1 = time.monotonic(), {k: _cpu_s(p) for k, p in others.items()}
    sub.wait(timeout=30)
    res: dict[str, Any] = json.loads(line)
    res["cores"] = {k: (cpu1[k] - cpu0[k]) / (t1 - t0) for k in others}
    res["cores"]["sub"] = res["cpu_s"] / res["seconds"] if res["seconds"] else float("nan")
    res["offered"] = res["sent"] = float("nan")
    if counting:
        try:
            (n0, s0, k0), (n1, s1, k1) = (
                [*map(float, pub.stdout.readline().split()), 0.0][:3] for _ in range(2)
            )
            res["offered"] = (n1 - n0) / (s1 - s0)
            res["sent"] = (n1 - n0 - (k1 - k0)) / (s1 - s0)
        except ValueError:
            pass
    procs.stop(pub)
    return res


def run_visnav(
    procs: Procs, topic: str, rate: float, duration: float, bridge: int
) -> dict[str, Any]:
    sub = _subscribe(procs, topic, duration, warmup=2.0)
    pub = procs.start(
        [sys.executable, "-c", VISNAV_PUB, topic, str(rate), str(duration + 30)], pipe=True
    )
    return _result(procs, sub, pub, bridge)


def run_rospy(procs: Procs, topic: str, rate: float, duration: float) -> dict[str, Any]:
    sub = _subscribe(procs, topic, duration, warmup=2.0)
    pub = procs.start(
        [SYSTEM_PYTHON, "-c", ROSPY_PUB, topic, str(duration + 30), str(rate)], pipe=True
    )
    return _result(procs, sub, pub, None)


def _pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))] if s else float("nan")


def _cores(res: dict[str, Any], seconds: float) -> str:
    """Rates offered/sent, each process's cores and its CPU ms per image delivered."""
    cores = res["cores"]
    per = 1000.0 * seconds / max(res["count"], 1)
    parts = [
        f"{k} {cores[k]:.2f} ({cores[k] * per:.2f} ms/img)"
        for k in ("pub", "bridge", "sub")
        if k in cores
    ]
    sent = "" if res["sent"] != res["sent"] else f", sent {res['sent']:.0f}/s"
    read = f", sub read {res['frames'] / max(res['count'], 1):.2f} frames/img"
    return f"offered {res['offered']:.0f}/s{sent}{read}, cores: " + ", ".join(parts)


def _bulk(procs: Procs, i: int, rate: float, args: argparse.Namespace, bridge: int) -> str:
    """One visnav -> rospy and one rospy -> rospy bulk run; appends rates, returns the text."""
    tag = "r" if rate else ""
    vis = run_visnav(procs, f"/{tag}bulk{i}", rate, args.duration, bridge)
    ref = run_rospy(procs, f"/{tag}ref{i}", rate, args.duration)
    key = "offered" if rate else "flood"
    args.rates[key].append((vis["count"] / args.duration, ref["count"] / args.duration))
    per = 1000.0 * args.duration / max(vis["count"], 1)
    args.bridge_ms[key].append(vis["cores"]["bridge"] * per)
    ref_per = 1000.0 * args.duration / max(ref["count"], 1)
    args.cpu_ms[key].append(
        (sum(vis["cores"].values()) * per, sum(ref["cores"].values()) * ref_per)
    )
    args.pub_cores[key].append((vis["cores"]["pub"], ref["cores"]["pub"]))
    args.sub_ms[key].append((vis["cores"]["sub"] * per, ref["cores"]["sub"] * ref_per))
    args.frames[key].append(
        (vis["frames"] / max(vis["count"], 1), ref["frames"] / max(ref["count"], 1))
    )
    return (
        f"  {'offered ' + str(int(rate)) + ' Hz' if rate else 'flooding'}: visnav->rospy "
        f"{vis['count'] / args.duration:.1f}/s ({_cores(vis, args.duration)}), rospy->rospy "
        f"{ref['count'] / args.duration:.1f}/s ({_cores(ref, args.duration)})"
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--rate", type=float, default=1000.0, help="offered rate of the 2nd bulk")
    parser.add_argument(
        "--flood-only", action="store_true", help="only the both-flooding bulk runs"
    )
    args = parser.parse_args()
    args.rates = {"flood": [], "offered": []}
    args.bridge_ms = {"flood": [], "offered": []}
    args.cpu_ms = {"flood": [], "offered": []}
    args.pub_cores = {"flood": [], "offered": []}
    args.sub_ms = {"flood": [], "offered": []}
    args.frames = {"flood": [], "offered": []}
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
    med = statistics.median
    try:
        procs.start(["roscore", "-p", str(port)])
        time.sleep(4.0)
        bridge = procs.start([sys.executable, "-m", "visnav.cli.main", "bridge", "ros1"]).pid
        time.sleep(3.0)
        p50s, p95s, ref50s, ref95s = [], [], [], []
        for i in range(args.repeats):
            lines = [f"run {i}:"]
            if not args.flood_only:
                lat = run_visnav(procs, f"/lat{i}", 30.0, args.duration, bridge)
                lats = list(lat["lat_ms"])
                p50s.append(_pct(lats, 0.5))
                p95s.append(_pct(lats, 0.95))
                ref_lat = run_rospy(procs, f"/reflat{i}", 30.0, args.duration)
                ref_lats = list(ref_lat["lat_ms"])
                ref50s.append(_pct(ref_lats, 0.5))
                ref95s.append(_pct(ref_lats, 0.95))
                lines.append(
                    f"  latency p50 {p50s[-1]:.2f} ms p95 {p95s[-1]:.2f} ms ({len(lats)} msgs at "
                    f"30 Hz; rospy->rospy p50 {ref50s[-1]:.2f} p95 {ref95s[-1]:.2f} ms)"
                )
            lines.append(_bulk(procs, i, 0.0, args, bridge))
            if not args.flood_only:
                lines.append(_bulk(procs, i, args.rate, args, bridge))
            print("\n".join(lines), flush=True)
        if p50s:
            print(
                f"median over {args.repeats}: 640x480 rgb8 visnav -> rospy at 30 Hz: latency p50 "
                f"{med(p50s):.2f} ms, p95 {med(p95s):.2f} ms (target <= 10 ms); rospy -> rospy "
                f"in the same run: p50 {med(ref50s):.2f} ms, p95 {med(ref95s):.2f} ms"
            )
        for key, what in (
            ("flood", "both flooding"),
            ("offered", f"both offered {args.rate:.0f} Hz"),
        ):
            pairs = args.rates[key]
            if not pairs:
                continue
            vis, ref = med(p[0] for p in pairs), med(p[1] for p in pairs)
            ratios = ", ".join(f"{p[0] / p[1]:.2f}" if p[1] else "nan" for p in pairs)
            print(
                f"bulk, {what}: visnav -> rospy {vis:.1f} img/s, rospy -> rospy {ref:.1f} img/s, "
                f"ratio of medians {vis / ref:.2f} (per run {ratios}; target >= 0.8); bridge "
                f"CPU per image delivered {med(args.bridge_ms[key]):.2f} ms, all processes "
                f"{med(c[0] for c in args.cpu_ms[key]):.2f} ms against "
                f"{med(c[1] for c in args.cpu_ms[key]):.2f} ms for rospy -> rospy (medians)"
            )
            print(
                f"  {what}, visnav path / rospy path (medians): publisher "
                f"{med(c[0] for c in args.pub_cores[key]):.2f} / "
                f"{med(c[1] for c in args.pub_cores[key]):.2f} cores; rospy subscriber "
                f"{med(c[0] for c in args.sub_ms[key]):.2f} / "
                f"{med(c[1] for c in args.sub_ms[key]):.2f} ms CPU per image, reading "
                f"{med(c[0] for c in args.frames[key]):.2f} / "
                f"{med(c[1] for c in args.frames[key]):.2f} frames per image it delivers"
            )
        print(
            "load average (1, 5, 15 min) at the end: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
        )
    finally:
        procs.close()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
