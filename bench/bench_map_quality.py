"""How close a saved map's walls are to the world's: occupied cells against the true geometry.

Run: ``python bench/bench_map_quality.py MAP.yaml [MAP.yaml ...] [--world office]``
(e.g. every map of a sweep: ``/tmp/bench-car-*/jobs/runs/default/*/map.yaml``).

For each map (map_server's format, from ``visnav run car`` or ``visnav map save``) every
occupied cell's centre is measured against the world's collision shapes
(:func:`visnav.sim.world_geometry.obstacle_distance`, 0.3 m above the floor: the depth
scan's height band). Printed per map: occupied cells, the median / 90th / 99th percentile
of their distance to the nearest wall (cm), the share farther than 10 cm (two cells), and
the coverage: of the true wall cells (the world's own 0.05 m occupancy grid, the
reference) next to a cell the map observed, the share the map marks occupied within one
cell. Last, the medians over all maps.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np
from scipy.ndimage import binary_dilation

from visnav.description.world import load_world
from visnav.mapping.map_io import load_map
from visnav.sim.world_geometry import obstacle_distance, true_occupancy_grid

SCAN_HEIGHT_M = 0.3
FAR_M = 0.10


def map_quality(path: Path, world_name: str) -> dict[str, float]:
    """Wall distances and coverage of one saved map (module docstring)."""
    world = load_world(world_name, seed=0)
    m = load_map(path)
    ox, oy, _ = m.metadata.origin
    res = m.metadata.resolution
    occ = m.data >= 65
    rows, cols = np.nonzero(occ)
    pts = np.stack(
        [ox + (cols + 0.5) * res, oy + (rows + 0.5) * res, np.full(len(rows), SCAN_HEIGHT_M)], 1
    )
    dist = np.maximum(obstacle_distance(world, pts), 0.0) if len(pts) else np.zeros(1)
    truth, (tx0, ty0) = true_occupancy_grid(world, res)
    tr, tc = np.nonzero(truth)
    mc = np.floor((tx0 + (tc + 0.5) * res - ox) / res).astype(int)
    mr = np.floor((ty0 + (tr + 0.5) * res - oy) / res).astype(int)
    inside = (mc >= 0) & (mc < occ.shape[1]) & (mr >= 0) & (mr < occ.shape[0])
    mr, mc = mr[inside], mc[inside]
    seen = binary_dilation(m.data >= 0)[mr, mc]
    marked = binary_dilation(occ)[mr, mc]
    return {
        "occupied": float(len(rows)),
        "median_cm": float(np.median(dist) * 100),
        "p90_cm": float(np.percentile(dist, 90) * 100),
        "p99_cm": float(np.percentile(dist, 99) * 100),
        "far_pct": float(np.mean(dist > FAR_M) * 100),
        "coverage_pct": float(marked[seen].mean() * 100) if seen.any() else 0.0,
    }


def main() -> None:
    """Print each map's figures and the medians."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+", type=Path, help="map.yaml files")
    ap.add_argument("--world", default="office", help="the world the maps are of (office)")
    args = ap.parse_args()
    rows = []
    print(
        f"{'map':60s} {'cells':>6s} {'med':>5s} {'p90':>5s} {'p99':>5s} {'>10cm':>6s} {'cover':>6s}"
    )
    for path in args.maps:
        q = map_quality(path, args.world)
        rows.append(q)
        name = str(path)[-60:]
        print(
            f"{name:60s} {q['occupied']:6.0f} {q['median_cm']:5.1f} {q['p90_cm']:5.1f} "
            f"{q['p99_cm']:5.1f} {q['far_pct']:5.1f}% {q['coverage_pct']:5.1f}%"
        )
    if len(rows) > 1:
        med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
        print(
            f"{'median of ' + str(len(rows)) + ' maps':60s} {med['occupied']:6.0f} "
            f"{med['median_cm']:5.1f} {med['p90_cm']:5.1f} {med['p99_cm']:5.1f} "
            f"{med['far_pct']:5.1f}% {med['coverage_pct']:5.1f}%"
        )


if __name__ == "__main__":
    main()
