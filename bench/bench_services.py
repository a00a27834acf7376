"""Service benchmarks: round trip in and across processes, node creation with parameter services.

Run: ``python bench/bench_services.py``. Prints medians and p99 of the round trip of a
``std_srvs/srv/SetBool`` call:

* in process (client and server in one context, the executor spinning in this thread);
* across processes: a visnav client calling a visnav server in a child process, against
  the reference measured in the same run, a raw Zenoh ``get`` to a bare queryable in the
  same child that replies the same bytes (the ratio is visnav / raw; goal <= 1.3);

and the cost of creating a node with and without its six parameter services, in a
local-only context and with Zenoh. Each run uses its own private domain.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import threading
import time
from typing import Any

N_CALLS = 2000
N_NODES = 200
REPEATS = 3
_RAW_KEY = "raw_bench/queryable"


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


def bench_cross_process(n: int = N_CALLS) -> dict[str, tuple[float, float]]:
    """visnav call vs raw Zenoh get against a child process, interleaved in blocks."""
    import zenoh

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

            def raw_call() -> None:
                done = threading.Event()
                got: list[Any] = []
                session.get(
                    raw_key,
                    zenoh.handlers.Callback(got.append, done.set, indirect=False),
                    payload=payload,
                    timeout=10.0,
                )
                done.wait(10.0)
                if not got or got[0].ok is None:
                    msg = "raw get got no reply"
                    raise RuntimeError(msg)

            for _ in range(100):  # warm up both paths
                client.call(request, timeout_sec=10.0)
                raw_call()
            visnav: list[float] = []
            raw: list[float] = []
            block = 100
            for _ in range(n // block):
                for _ in range(block):
                    t = time.perf_counter()
                    client.call(request, timeout_sec=10.0)
                    visnav.append(time.perf_counter() - t)
                for _ in range(block):
                    t = time.perf_counter()
                    raw_call()
                    raw.append(time.perf_counter() - t)
        return {"visnav": _stats(visnav), "raw": _stats(raw)}
    finally:
        child.kill()
        child.wait(10)


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


def main() -> None:
    """Run every benchmark REPEATS times and print medians."""
    local = [bench_in_process() for _ in range(REPEATS)]
    lm = statistics.median(m for m, _ in local)
    lp = statistics.median(p for _, p in local)
    print(f"in-process SetBool round trip: median {lm:.3f} ms, p99 {lp:.3f} ms")
    cross = [bench_cross_process() for _ in range(REPEATS)]
    vm = statistics.median(c["visnav"][0] for c in cross)
    vp = statistics.median(c["visnav"][1] for c in cross)
    rm = statistics.median(c["raw"][0] for c in cross)
    rp = statistics.median(c["raw"][1] for c in cross)
    print(f"cross-process visnav call: median {vm:.3f} ms, p99 {vp:.3f} ms")
    print(f"cross-process raw Zenoh get: median {rm:.3f} ms, p99 {rp:.3f} ms")
    print(f"ratio visnav / raw: median {vm / rm:.2f}x, p99 {vp / rp:.2f}x (goal <= 1.3x)")
    for kind in ("local", "zenoh"):
        runs = [bench_node_creation(kind) for _ in range(REPEATS)]
        without = statistics.median(r["without"] for r in runs)
        with_ = statistics.median(r["with"] for r in runs)
        print(
            f"node creation ({kind}): {without:.3f} ms without, {with_:.3f} ms with the six "
            f"parameter services (+{with_ - without:.3f} ms)"
        )


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--serve":
        serve(float(sys.argv[2]))
    else:
        main()
