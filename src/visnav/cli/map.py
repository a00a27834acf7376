"""``visnav map``: save a live ``/map`` (map_saver) and describe a saved map (map_server).

* ``visnav map save [-f NAME] [--topic /map] [--occ 65] [--free 25] [--timeout S]
  [map:=TOPIC]``: like ``rosrun map_server map_saver -f NAME [map:=TOPIC]``, waits for
  one ``nav_msgs/OccupancyGrid`` on the topic (transient local, so a latched map arrives
  at once) and writes ``NAME.yaml`` and ``NAME.pgm``
  (:func:`visnav.mapping.map_io.save_map`; ``~`` in NAME is expanded). map_saver waits
  forever; ``--timeout`` gives up with an error.
* ``visnav map info PATH.yaml``: loads the map as map_server does and prints its size,
  resolution, origin, mode and free / occupied / unknown cell counts.
* ``visnav map info PATH.npz``: a saved SLAM map (the slam node's ``database_path``,
  :mod:`visnav.slam.map_file`): keyframes, map points, loops, time span, the extent of
  the camera trajectory and the intrinsics.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from visnav.cli._common import cli_node
from visnav.graph.qos import qos_profile_latched
from visnav.mapping.map_io import MapFileError, load_map, save_map
from visnav.msgs.types import OccupancyGrid
from visnav.outpaths import check_output_file

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``map`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True

    p = sub.add_parser("save", help="write NAME.yaml + NAME.pgm from a live map (map_saver)")
    p.add_argument("-f", "--file", default="map", help="output path without extension (map)")
    p.add_argument("--topic", default="/map", help="nav_msgs/OccupancyGrid topic (/map)")
    p.add_argument("--occ", type=int, default=65, help="cells >= this are occupied (65)")
    p.add_argument("--free", type=int, default=25, help="cells 0..this are free (25)")
    p.add_argument("--timeout", type=float, default=None, help="give up after S seconds")
    p.add_argument(
        "remap", nargs="*", metavar="map:=TOPIC", help="map_saver's remapping (same as --topic)"
    )
    p.set_defaults(func=cmd_save)

    p = sub.add_parser("info", help="describe a map YAML (map_server) or a SLAM map .npz")
    p.add_argument("path", help="map YAML (map_server format) or SLAM map .npz")
    p.set_defaults(func=cmd_info)


def cmd_save(args: argparse.Namespace) -> int:
    """``map save``."""
    if not 0 <= args.free < args.occ <= 100:
        msg = (
            f"map save: --free {args.free} --occ {args.occ}: expected "
            "0 <= free < occ <= 100. Fix: e.g. --free 25 --occ 65 (map_saver's defaults)"
        )
        raise MapFileError(msg)
    if args.timeout is not None and not (math.isfinite(args.timeout) and args.timeout > 0):
        msg = f"map save: --timeout {args.timeout}: expected a positive number of seconds"
        raise MapFileError(msg)
    for item in args.remap:
        name, sep, target = item.partition(":=")
        if not sep or name.lstrip("/") != "map" or not target.strip():
            msg = (
                f"map save: argument {item!r}: expected map:=TOPIC (map_saver's remapping of "
                "its input) or an option: -f NAME, --occ N, --free N, --topic TOPIC"
            )
            raise MapFileError(msg)
        args.topic = target
    base = Path(args.file).expanduser()
    for suffix in (".yaml", ".pgm"):
        check_output_file(base.with_name(base.name + suffix), what=f"the map {suffix[1:]}")
    received: list[OccupancyGrid] = []
    with cli_node(args) as node:
        node.create_subscription(OccupancyGrid, args.topic, received.append, qos_profile_latched)
        print(f"Waiting for the map on {args.topic}", flush=True)
        end = None if args.timeout is None else time.monotonic() + args.timeout
        while not received:
            if end is not None and time.monotonic() > end:
                msg = (
                    f"map save: no nav_msgs/OccupancyGrid on {args.topic} within "
                    f"{args.timeout:g} s. Fix: start the mapper (or map_server), or pass "
                    "--topic with the map's topic"
                )
                raise MapFileError(msg)
            node.context.spin_once(0.1)
    grid = received[0]
    info = grid.info
    print(f"Received a {info.width} X {info.height} map @ {info.resolution:.3f} m/pix")
    yaml_path, pgm_path = save_map(grid, base, occupied=args.occ, free=args.free)
    print(f"Wrote {pgm_path} and {yaml_path}")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``map info``."""
    if Path(args.path).suffix == ".npz":
        return _slam_info(args.path)
    loaded = load_map(args.path)
    meta = loaded.metadata
    height, width = loaded.data.shape
    x, y, yaw = meta.origin
    counts = loaded.counts()
    total = width * height
    print(f"map:          {args.path}")
    print(f"image:        {meta.image}")
    print(f"size:         {width} x {height} cells ({width * meta.resolution:g} x "
          f"{height * meta.resolution:g} m)")  # fmt: skip
    print(f"resolution:   {meta.resolution:g} m/cell")
    print(f"origin:       [{x:g}, {y:g}, {yaw:g}]")
    thresholds = f"occupied_thresh: {meta.occupied_thresh:g}  free_thresh: {meta.free_thresh:g}"
    print(f"mode:         {meta.mode}  negate: {int(meta.negate)}  {thresholds}")
    for key in ("free", "occupied", "unknown"):
        share = 100.0 * counts[key] / total
        print(f"{key + ':':13} {counts[key]} ({share:.1f} %)")
    return 0


def _slam_info(path: str) -> int:
    """``map info FILE.npz``: a saved SLAM map."""
    from visnav.slam.map_file import load_slam_map, summarize_slam_map  # lazy: cv2

    saved = load_slam_map(path)
    info = summarize_slam_map(saved)
    fx, fy, cx, cy, width, height = info["camera"]
    print(f"SLAM map:     {path} (format version {saved.version})")
    print(f"keyframes:    {info['keyframes']} (of {info['keyframes_total']} with culled ones), "
          f"{info['with_odometry']} with an odometry pose")  # fmt: skip
    print(f"map points:   {info['points']} ({info['points_cloud']} seen by >= 2 keyframes: "
          f"the PLY), {info['observations']} observations")  # fmt: skip
    print(f"loops:        {info['loops']}")
    if info["start_s"] is None:
        print("time span:    no keyframes")
        return 0
    print(f"time span:    {info['start_s']:.3f} .. {info['end_s']:.3f} s "
          f"({info['duration_s']:.3f} s)")  # fmt: skip
    lo, hi = info["extent_min"], info["extent_max"]
    box = "  ".join(
        f"{a} {low:.3f} .. {high:.3f}" for a, low, high in zip("xyz", lo, hi, strict=True)
    )
    print(f"camera path:  {box} m; {info['path_length_m']:.3f} m between keyframes")
    print(f"camera:       {width:d} x {height:d}, fx {fx:g} fy {fy:g} cx {cx:g} cy {cy:g}")
    return 0
