"""Navigation benchmarks: global plan, local planner cycle, costmap update from a scan.

Run: ``python bench/bench_nav.py``. Prints medians of repeated runs:

* global plan on a 400 x 400-cell costmap (rooms, doors, clutter, inflated), corner to
  corner, Dijkstra and A*, eikonal and graph potentials (target <= 20 ms), and the ratio
  to ``scipy.sparse.csgraph.dijkstra`` on the same 8-connected grid graph (graph build
  excluded from the reference);
* local planner cycle: DWA (3 x 20 samples, 1.7 s rollouts) and regulated pure pursuit
  on a 5 x 5 m rolling costmap with obstacles (target <= 10 ms);
* costmap update from a 640-beam scan through TF: the 20 x 20 m global costmap
  (static + obstacle + inflation) and the 5 x 5 m rolling local costmap (target <= 5 ms),
  also with the map in it (the car's, moved by ``map -> odom`` every update; ratio to
  the one without).
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from visnav.mapping import (
    Footprint,
    InflationLayer,
    LayeredCostmap,
    ObservationSource,
    ObstacleLayer,
    StaticLayer,
)
from visnav.msgs import (
    Header,
    LaserScan,
    MapMetaData,
    OccupancyGrid,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    make,
    ns_to_time,
)
from visnav.planning import (
    DWAPlanner,
    GlobalPlanner,
    GlobalPlannerParams,
    RegulatedPurePursuit,
)
from visnav.tf import Buffer


def median_ms(fn: Callable[[], Any], *, repeat: int = 30, warmup: int = 3) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3


def office_grid(n: int = 400, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    g = np.zeros((n, n), np.int8)
    g[:2, :] = g[-2:, :] = g[:, :2] = g[:, -2:] = 100
    step = n // 5
    for k in range(1, 5):
        g[k * step : k * step + 3, :] = 100
        g[:, k * step : k * step + 3] = 100
        for j in range(5):
            g[k * step : k * step + 3, j * step + 30 : j * step + 52] = 0
            g[j * step + 30 : j * step + 52, k * step : k * step + 3] = 0
    for _ in range(150):
        x, y = rng.integers(5, n - 10, 2)
        g[y : y + 5, x : x + 5] = 100
    g[3:30, 3:30] = 0
    g[n - 30 : n - 3, n - 30 : n - 3] = 0
    return g


def map_msg(grid: np.ndarray, res: float = 0.05) -> OccupancyGrid:
    h, w = grid.shape
    msg = make(OccupancyGrid, info=make(MapMetaData, resolution=res, width=w, height=h))
    msg.info.origin.orientation.w = 1.0
    msg.header.frame_id = "map"
    msg.data = grid.reshape(-1)
    return msg


def global_costmap(
    grid: np.ndarray, tf: Buffer | None = None
) -> tuple[LayeredCostmap, ObstacleLayer]:
    fp = Footprint.from_params(robot_radius=0.25)
    lc = LayeredCostmap("map", resolution=0.05, track_unknown_space=True, footprint=fp)
    static = StaticLayer()
    lc.add_layer(static)
    src = ObservationSource("scan", data_type="LaserScan", clearing=True)
    obs = ObstacleLayer(sources=[src], tf=tf)
    lc.add_layer(obs)
    lc.add_layer(InflationLayer())
    static.set_map(map_msg(grid))
    lc.update_map(1.0, 1.0, 0.0)
    return lc, obs


def graph_reference(weights: np.ndarray, start: tuple[int, int]) -> Callable[[], Any]:
    h, w = weights.shape
    idx = np.arange(h * w).reshape(h, w)
    rows, cols, vals = [], [], []
    finite = np.isfinite(weights)
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)):
        ys0, ys1 = max(0, -dy), h - max(0, dy)
        xs0, xs1 = max(0, -dx), w - max(0, dx)
        src = idx[ys0:ys1, xs0:xs1]
        dst = idx[ys0 + dy : ys1 + dy, xs0 + dx : xs1 + dx]
        wt = weights[ys0 + dy : ys1 + dy, xs0 + dx : xs1 + dx] * math.hypot(dx, dy)
        ok = finite[ys0 + dy : ys1 + dy, xs0 + dx : xs1 + dx] & finite[ys0:ys1, xs0:xs1]
        if dx and dy:
            ok &= finite[ys0 + dy : ys1 + dy, xs0:xs1] & finite[ys0:ys1, xs0 + dx : xs1 + dx]
        rows.append(src[ok])
        cols.append(dst[ok])
        vals.append(wt[ok])
    graph = coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(h * w, h * w)
    ).tocsr()
    s = start[1] * w + start[0]
    return lambda: dijkstra(graph, indices=s)


def bench_global() -> None:
    lc, _ = global_costmap(office_grid())
    cm = lc.costmap
    start, goal = (0.6, 0.6), (19.4, 19.4, 0.0)
    print(f"global plan, {cm.size_x} x {cm.size_y} cells, corner to corner:")
    graph_ms = None
    for name, params in (
        ("Dijkstra, eikonal (default)", GlobalPlannerParams()),
        ("A*, eikonal", GlobalPlannerParams(use_dijkstra=False)),
        ("Dijkstra, 8-connected graph", GlobalPlannerParams(use_quadratic=False)),
        ("A*, 8-connected graph", GlobalPlannerParams(use_quadratic=False, use_dijkstra=False)),
    ):
        planner = GlobalPlanner(params)
        result = planner.make_plan(cm, start, goal)
        assert result.ok, result.reason
        ms = median_ms(lambda p=planner: p.make_plan(cm, start, goal), repeat=20)
        if params == GlobalPlannerParams(use_quadratic=False):
            graph_ms = ms
        print(
            f"  {name:30s} {ms:7.2f} ms  (expanded {result.expanded:6d} cells, "
            f"path {result.length:.2f} m)   target <= 20 ms"
        )
    weights = GlobalPlanner(GlobalPlannerParams(use_quadratic=False)).weights(cm)
    s_cell = cm.world_to_map(*start)
    assert s_cell is not None
    ref = graph_reference(weights, s_cell)
    ref_ms = median_ms(ref, repeat=10, warmup=1)
    assert graph_ms is not None
    print(
        f"  reference scipy csgraph.dijkstra (whole map, graph prebuilt) {ref_ms:.2f} ms; "
        f"visnav graph Dijkstra / reference = {graph_ms / ref_ms:.2f}x"
    )


def local_costmap() -> LayeredCostmap:
    fp = Footprint.from_params(robot_radius=0.25)
    lc = LayeredCostmap(
        "odom", width=5.0, height=5.0, resolution=0.05, rolling_window=True, footprint=fp
    )
    obs = ObstacleLayer(sources=[ObservationSource("scan")])
    lc.add_layer(obs)
    lc.add_layer(InflationLayer())
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0.8, 2.4, 40), rng.uniform(-2.4, 2.4, 40), np.full(40, 0.2)])
    pts = pts[np.abs(pts[:, 1]) > 0.6]
    obs.add_points("scan", pts, np.eye(4), stamp_ns=0, now_ns=0)
    lc.update_map(0.0, 0.0, 0.0)
    return lc


def bench_local() -> None:
    lc = local_costmap()
    xs = np.arange(0.0, 6.0, 0.025)
    plan = np.column_stack([xs, 0.3 * np.sin(xs), np.zeros_like(xs)])
    print("local planner cycle, 5 x 5 m rolling costmap:")
    for name, ctl in (
        ("DWA (3 x 20 samples)", DWAPlanner()),
        ("regulated pure pursuit", RegulatedPurePursuit()),
    ):
        ctl.set_plan(plan)
        r = ctl.compute_velocity(
            (0.0, 0.0, 0.0), (0.3, 0.0), lc.costmap, lc.footprint, (0.0, 0.0, 0.0)
        )
        assert r.ok, r.reason

        def cycle(c: Any = ctl) -> None:
            c.set_plan(plan)
            c.compute_velocity(
                (0.0, 0.0, 0.0), (0.3, 0.0), lc.costmap, lc.footprint, (0.0, 0.0, 0.0)
            )

        ms = median_ms(cycle, repeat=100)
        print(f"  {name:30s} {ms:7.2f} ms   target <= 10 ms")


def scan_msg(stamp: int, n: int = 640) -> LaserScan:
    fov = 1.5184
    rng = np.random.default_rng(stamp)
    ranges = rng.uniform(0.8, 6.0, n).astype(np.float32)
    ranges[rng.random(n) < 0.05] = np.nan
    return make(
        LaserScan,
        header=Header(stamp=ns_to_time(stamp), frame_id="laser"),
        angle_min=-fov / 2,
        angle_max=fov / 2,
        angle_increment=fov / (n - 1),
        range_min=0.45,
        range_max=10.0,
        ranges=ranges,
    )


def bench_costmap_update() -> None:
    tf = Buffer()
    tf.set_transform_static(
        TransformStamped(
            header=Header(stamp=ns_to_time(0), frame_id="map"),
            child_frame_id="laser",
            transform=Transform(
                translation=Vector3(x=10.0, y=10.0, z=0.3),
                rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        ),
        "bench",
    )
    lc, obs = global_costmap(office_grid(), tf)
    print(
        "costmap update from a 640-beam scan (TF lookup, projection, ray tracing, marking, inflation):"
    )
    k = [0]

    def global_update() -> None:
        k[0] += 1
        obs.add_scan("scan", scan_msg(k[0]), k[0])
        lc.update_map(10.0, 10.0, 0.0, now_ns=k[0])

    ms = median_ms(global_update, repeat=50)
    print(f"  global 400 x 400 cells, static + obstacle + inflation {ms:7.2f} ms   target <= 5 ms")
    tf2 = Buffer()
    tf2.set_transform_static(
        TransformStamped(
            header=Header(stamp=ns_to_time(0), frame_id="odom"),
            child_frame_id="laser",
            transform=Transform(
                translation=Vector3(x=0.0, y=0.0, z=0.3),
                rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        ),
        "bench",
    )
    fp = Footprint.from_params(robot_radius=0.25)
    local = LayeredCostmap(
        "odom", width=5.0, height=5.0, resolution=0.05, rolling_window=True, footprint=fp
    )
    lobs = ObstacleLayer(
        sources=[ObservationSource("scan", data_type="LaserScan", clearing=True)], tf=tf2
    )
    local.add_layer(lobs)
    local.add_layer(InflationLayer())

    def local_update() -> None:
        k[0] += 1
        lobs.add_scan("scan", scan_msg(k[0]), k[0])
        local.update_map(0.01 * (k[0] % 50), 0.0, 0.0, now_ns=k[0])

    ms = median_ms(local_update, repeat=50)
    print(f"  local 100 x 100 cells rolling, obstacle + inflation   {ms:7.2f} ms   target <= 5 ms")
    # the car's local costmap since session 6: the map under the obstacle layer, moved by
    # map -> odom at every update (what CostmapROS does before each update)
    with_map = LayeredCostmap(
        "odom", width=5.0, height=5.0, resolution=0.05, rolling_window=True, footprint=fp
    )
    static = StaticLayer()
    with_map.add_layer(static)
    mobs = ObstacleLayer(
        sources=[ObservationSource("scan", data_type="LaserScan", clearing=True)], tf=tf2
    )
    with_map.add_layer(mobs)
    with_map.add_layer(InflationLayer())
    static.set_map(map_msg(office_grid()), transform=(-10.0, -10.0, 0.0))

    def map_update() -> None:
        k[0] += 1
        mobs.add_scan("scan", scan_msg(k[0]), k[0])
        static.set_map_transform(-10.0 + 0.001 * (k[0] % 7), -10.0, 0.0005 * (k[0] % 5))
        with_map.update_map(0.01 * (k[0] % 50), 0.0, 0.0, now_ns=k[0])

    ms_map = median_ms(map_update, repeat=50)
    print(
        f"  local 100 x 100 rolling, static + obstacle + inflation {ms_map:6.2f} ms"
        f"   {ms_map / ms:.2f}x obstacle + inflation"
    )


def main() -> None:
    bench_global()
    bench_local()
    bench_costmap_update()


if __name__ == "__main__":
    main()
