"""The whole ``visnav run tb3-slam`` run: real-time factor and CPU per simulated second, A/B.

Runs ``visnav run tb3-slam --seed S --duration D`` (TurtleBot3 burger in turtlebot3_world at
1 kHz physics with its 1 kHz IMU, LDS, gmapping, explore_lite, move_base, the observer and the
bag recorder, all lock-step in one process) as a child process, alternately with this tree's
code and with git revision ``--against REV`` (default ``HEAD``: the committed code; its
``src/`` is unpacked with ``git archive`` into a temporary directory and put first on
``PYTHONPATH``), ``--repeat`` times each, after a 5 s warm-up run of each (numba compiles
and caches the revision's kernels there: the planners' and gmapping's, used from the first
scans on). Per run it prints the real-time factor of the run's loop (``summary.json``: sim time over the wall time from the first step to the end of the
run), the CPU seconds (all threads) of that loop per simulated second, and the CPU seconds
of the whole child (user + sys, start-up and wrap-up included) per simulated second; then the medians and their ratio to the revision's, measured in the same
run, and whether the two bags hold the same messages (per topic: bag time and CDR bytes;
the run is deterministic for a seed, so any difference is a change of behaviour).

A second reference: MuJoCo alone (``mj_step`` of the same world and robot, no plugins, no
graph) in this process, its CPU seconds per simulated second, the floor of the lock-step loop.

Run: ``python bench/bench_tb3_slam.py [--duration 20] [--repeat 2] [--against REV]
[--keep PATH ...]`` (``--keep``: paths under ``src/`` the reference takes from this tree, to
compare one change while another package changes too).
Absolute times are noisy when the machine is loaded (the load average is printed); compare
the ratios.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data" / "turtlebot3"


def _unpack(rev: str, into: Path, keep: list[str]) -> Path:
    """``src/`` of git revision ``rev`` (``git archive``, read only) under ``into``.

    ``keep``: paths (under ``src/``) copied from this tree over the revision's, to leave out
    of the comparison work that is not the subject (another package changed meanwhile).
    """
    into.mkdir(parents=True, exist_ok=True)
    archive = into / "src.tar"
    with archive.open("wb") as out:
        subprocess.run(["git", "archive", rev, "src"], cwd=ROOT, check=True, stdout=out)
    with tarfile.open(archive) as tar:
        tar.extractall(into, filter="data")
    for rel in keep:
        src, dst = ROOT / rel, into / rel
        if not src.is_relative_to(ROOT / "src") or not src.exists():
            msg = f"--keep {rel}: expected an existing path under src/ of this tree"
            raise SystemExit(msg)
        if src.is_dir():
            shutil.rmtree(dst, ignore_errors=True)
            shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, dst)
    return into / "src"


# The child: ``visnav run`` with the process CPU time (all threads) of the lock-step loop's
# slices summed into a file (the loop alone: no start-up, no wrap-up).
_CHILD = """
import sys, time, visnav
assert visnav.__file__.startswith(sys.argv[1]), visnav.__file__
from visnav.sim.sim_node import SimulatorNode
loop_file, run_lockstep, cpu = sys.argv[2], SimulatorNode.run_lockstep, [0.0]
def timed(self, *args, **kwargs):
    c0 = time.process_time()
    try:
        return run_lockstep(self, *args, **kwargs)
    finally:
        cpu[0] += time.process_time() - c0
SimulatorNode.run_lockstep = timed
from visnav.cli.main import main
sys.argv = ["visnav", *sys.argv[3:]]
try:
    main()
finally:
    open(loop_file, "w").write(repr(cpu[0]))
"""


def _run(src: Path, out: Path, seed: int, duration: float) -> dict[str, float]:
    """One ``visnav run tb3-slam`` with the package in ``src``: RTF, CPU s per sim s, wall s."""
    env = dict(os.environ, PYTHONPATH=str(src), ROS_PACKAGE_PATH=str(DATA))
    args = ["run", "tb3-slam", "--seed", str(seed), "--duration", str(duration)]
    loop_file = out.parent / f"{out.name}.loop_cpu"
    cmd = [sys.executable, "-c", _CHILD, str(src), str(loop_file), *args, "--out", str(out)]
    cmd.append("--quiet")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - wall0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    summary = json.loads((out / "summary.json").read_text())
    sim = float(summary["sim_duration_s"])
    loop = float(loop_file.read_text())
    return {
        "rtf": float(summary["real_time_factor"]),
        "cpu_per_sim_s": cpu / sim,
        "loop_cpu_per_sim_s": loop / sim,
        "wall": wall,
    }


def _bag_digest(bag: Path) -> dict[str, tuple[int, str]]:
    """Per topic: message count and a hash of every (bag time, CDR bytes) in order."""
    from visnav.bag.reader import BagReader

    digests: dict[str, hashlib._Hash] = defaultdict(hashlib.sha256)
    counts: dict[str, int] = defaultdict(int)
    with BagReader(bag) as reader:
        for raw in reader.raw_messages():
            h = digests[raw.topic]
            h.update(raw.t_ns.to_bytes(8, "little", signed=True))
            h.update(bytes(raw.data))
            counts[raw.topic] += 1
    return {topic: (counts[topic], h.hexdigest()) for topic, h in digests.items()}


def _physics_alone(seconds: float) -> float:
    """CPU seconds per simulated second of ``mj_step`` alone on the tb3-slam world and robot."""
    import logging

    import mujoco

    from visnav.graph import Context
    from visnav.sim.simulator import RobotSpawn, Simulator

    logging.getLogger("visnav").setLevel(logging.ERROR)  # the robot's xacro warnings
    os.environ["GAZEBO_MODEL_PATH"] = str(DATA / "turtlebot3_gazebo" / "models")
    desc = DATA / "turtlebot3_description"
    spawn = RobotSpawn(
        source=desc / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": desc},
        spawn=(-2.0, -0.5, 0.0, 0.0),
    )
    world = DATA / "turtlebot3_gazebo" / "worlds" / "turtlebot3_world.world"
    with Context(transport="local") as ctx, Simulator(world, [spawn], context=ctx) as sim:
        model, data = sim.model, sim.data
        steps = round(seconds / model.opt.timestep)
        c0 = time.process_time()
        mujoco.mj_step(model, data, nstep=steps)
        return (time.process_time() - c0) / seconds


def main() -> None:
    """Parse the arguments, run both codes alternately, print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds per run")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each code")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--against", default="HEAD", metavar="REV", help="the reference revision")
    ap.add_argument(
        "--keep",
        nargs="*",
        default=[],
        metavar="PATH",
        help="paths under src/ taken from this tree in the reference too (e.g. a package "
        "another change touches)",
    )
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} (2 cores; noisy when others run)")
    results: dict[str, list[dict[str, float]]] = {args.against: [], "this tree": []}
    digests: dict[str, dict[str, tuple[int, str]]] = {}
    with tempfile.TemporaryDirectory(prefix="bench_tb3_slam_") as tmp:
        codes = {
            args.against: _unpack(args.against, Path(tmp) / "rev", args.keep),
            "this tree": ROOT / "src",
        }
        for k, src in enumerate(codes.values()):  # numba compiles each tree's kernels once
            _run(src, Path(tmp) / f"warm_{k}", args.seed, 5.0)
        for i in range(args.repeat):
            for name, src in codes.items():
                out = Path(tmp) / f"run_{i}_{'ref' if name == args.against else 'new'}"
                r = _run(src, out, args.seed, args.duration)
                results[name].append(r)
                print(
                    f"{name}: RTF {r['rtf']:.3f}, {r['loop_cpu_per_sim_s']:.3f} CPU s per sim s "
                    f"in the loop, {r['cpu_per_sim_s']:.3f} with start-up and wrap-up, "
                    f"{r['wall']:.1f} s wall (load {os.getloadavg()[0]:.1f})",
                    flush=True,
                )
                if i == 0:
                    digests[name] = _bag_digest(out / "bag")
    ref, new = (results[n] for n in (args.against, "this tree"))
    rtf_ref, rtf_new = (statistics.median(r["rtf"] for r in rs) for rs in (ref, new))
    cpu_ref, cpu_new = (statistics.median(r["cpu_per_sim_s"] for r in rs) for rs in (ref, new))
    loop_ref, loop_new = (
        statistics.median(r["loop_cpu_per_sim_s"] for r in rs) for rs in (ref, new)
    )
    physics = _physics_alone(min(args.duration, 10.0))
    print(
        f"tb3-slam seed {args.seed}, {args.duration:g} s: median RTF {rtf_new:.3f} "
        f"({args.against}: {rtf_ref:.3f}, ratio {rtf_new / rtf_ref:.2f}x); median CPU s per "
        f"sim s in the loop {loop_new:.3f} ({args.against}: {loop_ref:.3f}, ratio "
        f"{loop_ref / loop_new:.2f}x less), with start-up and wrap-up {cpu_new:.3f} "
        f"({args.against}: {cpu_ref:.3f}, {cpu_ref / cpu_new:.2f}x less); MuJoCo alone "
        f"{physics:.3f} CPU s per sim s"
    )
    a, b = digests[args.against], digests["this tree"]
    differ = sorted(t for t in set(a) | set(b) if a.get(t) != b.get(t))
    if differ:
        print(
            "bags DIFFER on: "
            + ", ".join(f"{t} {a.get(t, (0,))[0]}/{b.get(t, (0,))[0]}" for t in differ)
        )
    else:
        print(f"bags identical: {len(a)} topics, {sum(c for c, _ in a.values())} messages")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
