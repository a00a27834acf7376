"""Service benchmarks: round trip in and across processes, node creation with parameter services.

Run: ``python bench/bench_services.py``. Prints medians and p99 of the round trip of a
``std_srvs/srv/SetBool`` call:

* in process (client and server in one context, the executor spinning in this thread);
* across processes: a visnav client calling a visnav server in a child process, against
  the reference measured in the same run, a raw Zenoh ``get`` to a bare queryable in the
  same child that replies the same bytes (the ratio is visnav / raw; goal <= 1.3). The
  visnav and raw calls alternate one by one (``--block 1``, the default; the first of
  each pair alternates too), so both see the same load: on a shared machine the p99 is
  mostly other processes' doing. ``--block 100`` is the earlier method (blocks of 100);
* the same in one process: two contexts (two Zenoh sessions), the server's spinning in
  a thread, against a raw ``get`` between the same two sessions;

* against real ROS 1 (Debian's ``roscore`` and the system ``/usr/bin/python3`` with rospy
  and std_srvs): a ``rospy.ServiceProxy`` calling a rospy ``SetBool`` service in another
  process, non-persistent (rospy's default: a new TCPROS connection and a master lookup
  per call) and ``persistent=True``, measured in the same run, interleaved with the visnav
  runs; the ratio is visnav cross-process / rospy (goal <= 0.5). The roscore listens on a
  free loopback port with its own ``ROS_HOME``; every ROS process is stopped at the end.
  Skipped (with a line saying so) when ROS 1 is not installed, or with ``--no-rospy``;

and the cost of creating a node with and without its six parameter services, in a
local-only context and with Zenoh. Each run uses its own private domain.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

N_CALLS = 2000
N_NODES = 200
REPEATS = 3
_RAW_KEY = "raw_bench/queryable"
SYSTEM_PYTHON = "/usr/bin/python3"
ROSCORE = "/usr/bin/roscore"

ROSPY_SERVER = """
import sys
import rospy
from std_srvs.srv import SetBool, SetBoolResponse
rospy.init_node("bench_rospy_server", disable_signals=True)
rospy.Service("/bench/rospy_set", SetBool, lambda req: SetBoolResponse(bool(req.data), "ok"))
print("ready", flush=True)
sys.stdin.read()  # until the benchmark closes our stdin
rospy.signal_shutdown("done")
"""

ROSPY_CLIENT = """
import json, sys, time
import rospy
from std_srvs.srv import SetBool
n, block = int(sys.argv[1]), int(sys.argv[2])
rospy.init_node("bench_rospy_client", anonymous=True, disable_signals=True)
rospy.wait_for_service("/bench/rospy_set", timeout=30.0)
plain = rospy.ServiceProxy("/bench/rospy_set", SetBool)
persistent = rospy.ServiceProxy("/bench/rospy_set", SetBool, persistent=True)
for _ in range(50):
    assert plain(True).success and persistent(True).success
out = {"plain": [], "persistent": []}
for _ in range(n // block):
    for name, proxy in (("plain", plain), ("persistent", persistent)):
        for _ in range(block):
            t = time.perf_counter()
            proxy(True)
            out[name].append(time.perf_counter() - t)
persistent.close()
print(json.dumps(out), flush=True)
rospy.signal_shutdown("done")
"""


def _stats(samples_s: list[float]) -> tuple[float, float]:
    ordered = sorted(samples_s)
    median = statistics.median(ordered) * 1e3
    p99 = ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))] * 1e3
    return median, p99


def serve(seconds: float) -> None:
    """Child process: a visnav SetBool server and a bare Zenoh queryable with the same reply."""
    import zenoh

    from visnav.graph import Context, Node
    from visnav.msgs.serde import serialize
    from visnav.msgs.srv import get_service_type

    set_bool = get_service_type("std_srvs/srv/SetBool")
    reply = serialize(set_bool.Response(success=True, message="ok"))

    def answer(req: Any, resp: Any) -> Any:
        resp.success = bool(req.data)
        resp.message = "ok"
        return resp

    with Context() as ctx:
        node = Node("bench_server", context=ctx)
        node.create_service(set_bool, "/bench/set", answer)
        z = ctx.zenoh
        assert z is not None
        domain = ctx.domain
        z.session.declare_queryable(
            f"{domain}/{_RAW_KEY}",
            zenoh.handlers.Callback(lambda q: q.reply(q.key_expr, reply), indirect=False),
            allowed_origin=zenoh.Locality.REMOTE,
        )
        ctx.flush_tokens()
        print("ready", flush=True)
        ctx.spin(duration_s=seconds)


def bench_in_process(n: int = N_CALLS) -> tuple[float, float]:
    """Round trip of call_async + spin in one context (ms median, p99)."""
    from visnav.graph import Context, Node
    from visnav.msgs.srv import get_service_type

    set_bool = get_service_type("std_srvs/srv/SetBool")
    with Context(transport="local") as ctx:
        node = Node("bench", context=ctx, start_parameter_services=False)
        node.create_service(set_bool, "set", lambda q, r: r)
        client = node.create_client(set_bool, "set")
        request = set_bool.Request(data=True)
        samples = []
        for _ in range(n):
            t = time.perf_counter()
            future = client.call_async(request)
            while not future.done():
                ctx.spin_once(0.1)
            samples.append(time.perf_counter() - t)
    return _stats(samples)


def bench_cross_process(n: int = N_CALLS, block: int = 1) -> dict[str, tuple[float, float]]:
    """visnav call vs raw Zenoh get against a child process, interleaved in blocks."""

    from visnav.graph import Context, Node
    from visnav.msgs.serde import serialize
    from visnav.msgs.srv import get_service_type

    domain = 2_000_000 + os.getpid() % 100_000
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    child = subprocess.Popen(
        [sys.executable, __file__, "--serve", "600"], env=env, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        if child.stdout.readline().strip() != "ready":
            msg = "the server process did not start"
            raise RuntimeError(msg)
        set_bool = get_service_type("std_srvs/srv/SetBool")
        with Context(domain) as ctx:
            client = Node(
                "bench_client", context=ctx, start_parameter_services=False
            ).create_client(set_bool, "/bench/set")
            if not client.wait_for_service(20.0):
                msg = "the service did not appear"
                raise RuntimeError(msg)
            z = ctx.zenoh
            assert z is not None
            session = z.session
            request = set_bool.Request(data=True)
            payload = serialize(request)
            raw_key = f"{domain}/{_RAW_KEY}"

            return _paired(
                lambda: client.call(request, timeout_sec=10.0),
                functools.partial(_raw_get, session, raw_key, payload),
                n,
                block,
            )
    finally:
        child.kill()
        child.wait(10)


def _raw_get(session: Any, key: str, payload: bytes) -> None:
    """One raw Zenoh get, zenoh-python's own idiom: the default FIFO channel read here."""
    try:
        reply = session.get(key, payload=payload, timeout=10.0).recv()
    except Exception as exc:
        msg = "raw get got no reply"
        raise RuntimeError(msg) from exc
    if reply.ok is None:
        msg = "raw get got no reply"
        raise RuntimeError(msg)


def _paired(
    visnav_call: Any, raw_call: Any, n: int, block: int = 1
) -> dict[str, tuple[float, float]]:
    """Time ``n`` calls of each, alternating in blocks of ``block`` (who goes first too).

    ``block=1`` pairs every visnav call with a raw call made at the same moment, so both
    see the same load (on a shared machine the p99 is mostly other processes' doing).
    """
    for _ in range(100):  # warm up both paths
        visnav_call()
        raw_call()
    samples: dict[str, list[float]] = {"visnav": [], "raw": []}
    order = (("visnav", visnav_call), ("raw", raw_call))
    for i in range(n // block):
        for name, call in order if i % 2 == 0 else order[::-1]:
            out = samples[name]
            for _ in range(block):
                t = time.perf_counter()
                call()
                out.append(time.perf_counter() - t)
    return {name: _stats(values) for name, values in samples.items()}


def bench_in_process_zenoh(n: int = N_CALLS, block: int = 1) -> dict[str, tuple[float, float]]:
    """Two contexts of one process (two Zenoh sessions): visnav call vs raw Zenoh get.

    The server context spins in a thread; the bare queryable is declared on its session.
    """
    import zenoh

    from visnav.graph import Context, Node
    from visnav.msgs.serde import serialize
    from visnav.msgs.srv import get_service_type

    set_bool = get_service_type("std_srvs/srv/SetBool")
    reply = serialize(set_bool.Response(success=True, message="ok"))

    def answer(req: Any, resp: Any) -> Any:
        resp.success = bool(req.data)
        resp.message = "ok"
        return resp

    domain = 4_000_000 + os.getpid() % 100_000
    with Context(domain) as server_ctx, Context(domain) as client_ctx:
        Node("bench_server", context=server_ctx).create_service(set_bool, "/bench/set", answer)
        zs, zc = server_ctx.zenoh, client_ctx.zenoh
        assert zs is not None
        assert zc is not None
        raw_key = f"{domain}/{_RAW_KEY}"

        def reply_raw(query: Any) -> None:
            query.reply(query.key_expr, reply)

        zs.session.declare_queryable(
            raw_key,
            zenoh.handlers.Callback(reply_raw, indirect=False),
            allowed_origin=zenoh.Locality.REMOTE,
        )
        spinner = threading.Thread(target=server_ctx.spin, daemon=True)
        spinner.start()
        try:
            client = Node(
                "bench_client", context=client_ctx, start_parameter_services=False
            ).create_client(set_bool, "/bench/set")
            if not client.wait_for_service(20.0):
                msg = "the service did not appear"
                raise RuntimeError(msg)
            request = set_bool.Request(data=True)
            payload = serialize(request)
            session = zc.session

            return _paired(
                lambda: client.call(request, timeout_sec=10.0),
                functools.partial(_raw_get, session, raw_key, payload),
                n,
                block,
            )
        finally:
            server_ctx.shutdown()
            spinner.join(5.0)


def bench_node_creation(kind: str, n: int = N_NODES) -> dict[str, float]:
    """Median ms to create a node with and without parameter services."""
    from visnav.graph import Context, Node

    out: dict[str, float] = {}
    domain = 3_000_000 + os.getpid() % 100_000
    with Context(domain, transport=kind) as ctx:
        Node("warm", context=ctx)
        for services in (False, True):
            samples = []
            for i in range(n):
                t = time.perf_counter()
                Node(f"n{i}_{int(services)}", context=ctx, start_parameter_services=services)
                samples.append(time.perf_counter() - t)
            ctx.flush_tokens()
            out["with" if services else "without"] = statistics.median(samples) * 1e3
    return out


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _master_up(port: int) -> bool:
    import xmlrpc.client

    proxy = xmlrpc.client.ServerProxy(f"http://127.0.0.1:{port}/")
    try:
        code, _, _ = proxy.getPid("/bench")
    except OSError:
        return False
    return bool(code == 1)


class Ros1:
    """A private roscore and a rospy SetBool server; :meth:`close` stops every process."""

    def __init__(self) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="bench_services_ros1_"))
        self.port = _free_port()
        self.env = {
            **os.environ,
            "ROS_MASTER_URI": f"http://127.0.0.1:{self.port}/",
            "ROS_IP": "127.0.0.1",
            "ROS_HOME": str(self.tmp),
            "ROS_LOG_DIR": str(self.tmp / "log"),
            "PYTHONPATH": "",
        }
        self.procs: list[subprocess.Popen[str]] = []

    def _start(self, argv: list[str], **kwargs: Any) -> subprocess.Popen[str]:
        # own session (process group): roscore's rosmaster and rosout are stopped with it
        proc = subprocess.Popen(
            argv,
            env=self.env,
            text=True,
            start_new_session=True,
            cwd=self.tmp,
            stderr=subprocess.DEVNULL,
            **kwargs,
        )
        self.procs.append(proc)
        return proc

    def start(self) -> None:
        """Start roscore and the rospy server; raise RuntimeError when they do not come up."""
        self._start([ROSCORE, "-p", str(self.port)], stdout=subprocess.DEVNULL)
        deadline = time.monotonic() + 30.0
        while not _master_up(self.port):
            if time.monotonic() > deadline or self.procs[0].poll() is not None:
                msg = f"roscore did not start on 127.0.0.1:{self.port}"
                raise RuntimeError(msg)
            time.sleep(0.2)
        server = self._start(
            [SYSTEM_PYTHON, "-c", ROSPY_SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE
        )
        assert server.stdout is not None
        if server.stdout.readline().strip() != "ready":
            msg = "the rospy server did not start"
            raise RuntimeError(msg)

    def calls(self, n: int, block: int = 100) -> dict[str, tuple[float, float]]:
        """N non-persistent and N persistent rospy calls (interleaved in blocks): ms median, p99."""
        client = self._start(
            [SYSTEM_PYTHON, "-c", ROSPY_CLIENT, str(n), str(block)], stdout=subprocess.PIPE
        )
        try:
            out, _ = client.communicate(timeout=600)
        finally:
            self._stop(client)
        if client.returncode != 0 or not out.strip():
            msg = f"the rospy client failed (exit {client.returncode})"
            raise RuntimeError(msg)
        samples = json.loads(out.strip().splitlines()[-1])
        return {name: _stats(values) for name, values in samples.items()}

    @staticmethod
    def _stop(proc: subprocess.Popen[str]) -> None:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        # children left in the group (rosmaster, rosout after roscore's exit)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)

    def close(self) -> None:
        """Stop every process (server, then roscore) and remove the ROS_HOME."""
        for proc in reversed(self.procs):
            if proc.stdin is not None:
                with contextlib.suppress(OSError):
                    proc.stdin.close()
            self._stop(proc)
        shutil.rmtree(self.tmp, ignore_errors=True)


def _ros1_missing() -> str | None:
    if not (Path(ROSCORE).exists() and Path(SYSTEM_PYTHON).exists()):
        return f"{ROSCORE} or {SYSTEM_PYTHON} is missing"
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import rospy, std_srvs.srv"],
        capture_output=True,
        check=False,
        env={**os.environ, "PYTHONPATH": ""},
    )
    return "rospy / std_srvs do not import in /usr/bin/python3" if probe.returncode else None


def _print_ratio(label: str, runs: list[dict[str, tuple[float, float]]]) -> None:
    """Print medians over runs, and each run's ratios (visnav / raw, median and p99)."""
    vm = statistics.median(r["visnav"][0] for r in runs)
    vp = statistics.median(r["visnav"][1] for r in runs)
    rm = statistics.median(r["raw"][0] for r in runs)
    rp = statistics.median(r["raw"][1] for r in runs)
    per_run = ", ".join(
        f"{r['visnav'][0] / r['raw'][0]:.2f}/{r['visnav'][1] / r['raw'][1]:.2f}" for r in runs
    )
    print(f"{label} visnav call: median {vm:.3f} ms, p99 {vp:.3f} ms")
    print(f"{label} raw Zenoh get: median {rm:.3f} ms, p99 {rp:.3f} ms")
    print(
        f"{label} ratio visnav / raw: median {vm / rm:.2f}x, p99 {vp / rp:.2f}x "
        f"(goal <= 1.3x; each run's median/p99: {per_run})"
    )


def main() -> None:
    """Run every benchmark REPEATS times and print medians."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=int, default=N_CALLS, help="calls per run")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="runs of each benchmark")
    parser.add_argument("--no-rospy", action="store_true", help="skip the ROS 1 comparison")
    parser.add_argument(
        "--block",
        type=int,
        default=1,
        help="visnav and raw calls alternate in blocks of this many (1: every call paired)",
    )
    args = parser.parse_args()
    n, repeats, block = args.calls, args.repeats, args.block
    print("load average (1, 5, 15 min) at the start: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    local = [bench_in_process(n) for _ in range(repeats)]
    lm = statistics.median(m for m, _ in local)
    lp = statistics.median(p for _, p in local)
    print(f"in-process SetBool round trip: median {lm:.3f} ms, p99 {lp:.3f} ms")
    two = [bench_in_process_zenoh(n, block) for _ in range(repeats)]
    _print_ratio("two contexts in one process (Zenoh)", two)
    missing = "--no-rospy" if args.no_rospy else _ros1_missing()
    ros1 = None if missing else Ros1()
    cross: list[dict[str, tuple[float, float]]] = []
    rospy_runs: list[dict[str, tuple[float, float]]] = []
    try:
        if ros1 is not None:
            ros1.start()
        for _ in range(repeats):  # visnav and rospy runs interleaved
            cross.append(bench_cross_process(n, block))
            if ros1 is not None:
                rospy_runs.append(ros1.calls(n))
    finally:
        if ros1 is not None:
            ros1.close()
    vm = statistics.median(c["visnav"][0] for c in cross)
    vp = statistics.median(c["visnav"][1] for c in cross)
    _print_ratio("cross-process", cross)
    if missing:
        print(f"rospy comparison skipped: {missing}")
    else:
        for name, label in (("plain", "ServiceProxy"), ("persistent", "ServiceProxy persistent")):
            pm = statistics.median(r[name][0] for r in rospy_runs)
            pp = statistics.median(r[name][1] for r in rospy_runs)
            print(
                f"rospy {label} -> rospy service: median {pm:.3f} ms, p99 {pp:.3f} ms; "
                f"visnav / rospy: median {vm / pm:.2f}x, p99 {vp / pp:.2f}x (goal <= 0.5x)"
            )
    for kind in ("local", "zenoh"):
        runs = [bench_node_creation(kind) for _ in range(repeats)]
        without = statistics.median(r["without"] for r in runs)
        with_ = statistics.median(r["with"] for r in runs)
        print(
            f"node creation ({kind}): {without:.3f} ms without, {with_:.3f} ms with the six "
            f"parameter services (+{with_ - without:.3f} ms)"
        )
    print("load average (1, 5, 15 min) at the end: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--serve":
        serve(float(sys.argv[2]))
    else:
        main()
