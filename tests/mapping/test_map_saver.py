"""The map_saver node: map_saver's arguments, one map -> NAME.pgm + NAME.yaml, then it ends.

Also map_server's ROS 1 command line (``map_server MAP.yaml``) and ``visnav map save``'s
``map:=TOPIC``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from visnav.cli.main import main
from visnav.graph import Context, Node
from visnav.graph.errors import ParameterError
from visnav.graph.qos import qos_profile_latched
from visnav.launch.description import NodeSpec
from visnav.mapping.map_io import MapFileError, MapMetadata, OccupancyMap, load_map, read_pgm
from visnav.mapping.map_saver_node import (
    MapSaverArgs,
    MapSaverArgsError,
    MapSaverNode,
    parse_map_saver_args,
)
from visnav.mapping.map_server_node import MapServerNode, map_server_args
from visnav.msgs.types import OccupancyGrid
from visnav.node_registry import resolve_node_class
from visnav.outpaths import OutputPathError
from visnav.tf.transforms import quaternion_from_yaw

# one cell of each class map_saver tells apart: free 0..25, unknown 26..64 and -1, occ >= 65
GRID = np.array([[0, 25, 26, 64], [65, 100, -1, 70]], dtype=np.int8)


def _grid(yaw: float = 0.0) -> OccupancyGrid:
    meta = MapMetadata(image=Path("x"), resolution=0.05, origin=(-1.5, 2.0, 0.0))
    msg = OccupancyMap(GRID, meta).to_msg(frame_id="map")
    msg.info.origin.orientation = quaternion_from_yaw(yaw)
    return msg


# ---------------------------------------------------------------------- arguments


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        ([], MapSaverArgs()),
        (["-f", "/tmp/m"], MapSaverArgs(file="/tmp/m")),
        (
            ["--occ", "70", "-f", "x", "--free", "10", "map:=/slam/map"],
            MapSaverArgs(file="x", occ=70, free=10, remaps=(("map", "/slam/map"),)),
        ),
        (["--occ", "100", "--free", "0"], MapSaverArgs(occ=100, free=0)),
        (["--occ", "1", "--free", "0"], MapSaverArgs(occ=1, free=0)),
    ],
)
def test_map_saver_arguments(args: list[str], expected: MapSaverArgs) -> None:
    assert parse_map_saver_args(args) == expected


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--occ", "0"], r"--occ 0: expected 1\.\.100"),
        (["--occ", "101"], r"--occ 101"),
        (["--free", "-1"], r"--free -1: expected 0\.\.100"),
        (["--free", "65"], r"--free 65 --occ 65: the free threshold must be below"),
        (["--occ", "65.5"], r"--occ '65.5': expected a whole number"),
        (["--occ", "abc"], r"expected a whole number"),
        (["-f"], r"-f needs a value"),
        (["-f", " "], r"-f ' ': expected a file name"),
        (["-h"], r"Usage: map_saver \[-f NAME\]"),
        (["--format", "png"], r"unknown argument '--format'"),
        (["_occ:=70"], r"no private parameters"),
        (["__name:=saver"], r"special ROS arguments"),
        (["map:="], r"no target topic"),
    ],
)
def test_map_saver_bad_arguments(args: list[str], match: str) -> None:
    with pytest.raises(MapSaverArgsError, match=match):
        parse_map_saver_args(args)


def test_map_server_arguments() -> None:
    assert map_server_args(["/maps/a.yaml"]) == ({"yaml_filename": "/maps/a.yaml"}, ())
    assert map_server_args(["map:=/static", "a.yaml"]) == (
        {"yaml_filename": "a.yaml"},
        (("map", "/static"),),
    )
    with pytest.raises(MapFileError, match="deprecated IMAGE RESOLUTION"):
        map_server_args(["a.pgm", "0.05"])
    with pytest.raises(MapFileError, match="expected one map YAML"):
        map_server_args([])
    with pytest.raises(MapFileError, match="_frame_id:=odom"):
        map_server_args(["a.yaml", "_frame_id:=odom"])


# ---------------------------------------------------------------------- the node


def _publish(ctx: Context, topic: str, grid: OccupancyGrid) -> Node:
    node = Node("slam", context=ctx)
    node.create_publisher(OccupancyGrid, topic, qos_profile_latched).publish(grid)
    return node


def test_map_saver_writes_map_savers_files_and_ends(tmp_path: Path) -> None:
    assert resolve_node_class("map_saver") is MapSaverNode
    base = tmp_path / "maps" / "office"  # a missing directory is created
    args = parse_map_saver_args(["-f", str(base)])
    with Context(transport="local") as ctx:
        _publish(ctx, "/map", _grid(yaw=0.25))  # latched: before the saver starts
        saver = MapSaverNode(context=ctx, parameter_overrides=args.params())
        assert saver.map_topic == "/map"
        assert ctx.spin_until(lambda: saver.finished, timeout_s=5.0)
        assert saver not in ctx.nodes  # it ended; the other node goes on
    assert saver.saved == (base.with_suffix(".yaml"), base.with_suffix(".pgm"))
    pixels, res = read_pgm(base.with_suffix(".pgm"))
    assert res == 0.05
    # image row 0 is the map's top (grid row 1): 65, 100 -> 0; -1 -> 205; 70 -> 0
    np.testing.assert_array_equal(pixels, [[0, 0, 205, 0], [254, 254, 205, 205]])
    text = base.with_suffix(".yaml").read_text()
    assert "image: office.pgm\n" in text
    assert "occupied_thresh: 0.65\nfree_thresh: 0.196\n" in text  # fixed, as ROS 1 writes
    loaded = load_map(base.with_suffix(".yaml"))
    assert loaded.metadata.origin[:2] == (-1.5, 2.0)
    assert math.isclose(loaded.metadata.origin[2], 0.25, abs_tol=1e-6)
    expected = np.where(GRID <= 25, 0, np.where(GRID >= 65, 100, -1)).astype(np.int8)
    expected[GRID < 0] = -1
    np.testing.assert_array_equal(loaded.data, expected)


def test_map_saver_thresholds_and_remap(tmp_path: Path) -> None:
    args = parse_map_saver_args(["-f", str(tmp_path / "m"), "--occ", "71", "--free", "0",
                                 "map:=/slam/map"])  # fmt: skip
    with Context(transport="local") as ctx:
        _publish(ctx, "/slam/map", _grid())
        saver = MapSaverNode(
            context=ctx, parameter_overrides=args.params(), remappings=dict(args.remaps)
        )
        assert saver.map_topic == "/slam/map"
        assert ctx.spin_until(lambda: saver.finished, timeout_s=5.0)
    pixels, _ = read_pgm(tmp_path / "m.pgm")
    # --free 0: 25 is not free any more; --occ 71: 65 and 70 are not occupied
    np.testing.assert_array_equal(pixels, [[205, 0, 205, 205], [254, 205, 205, 205]])


def test_map_saver_timeout_ends_without_files(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    with Context(transport="local") as ctx:
        Node("other", context=ctx)
        saver = MapSaverNode(
            context=ctx,
            parameter_overrides={"file": str(tmp_path / "m"), "save_map_timeout": 0.3},
        )
        assert ctx.spin_until(lambda: saver.finished, timeout_s=5.0)
    assert saver.saved is None
    assert not list(tmp_path.iterdir())
    assert "no nav_msgs/OccupancyGrid on /map within 0.3 s" in caplog.text


def test_map_saver_refuses_bad_parameters_at_start(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with Context(transport="local") as ctx:
        with pytest.raises(OutputPathError, match="is a file, not a directory"):
            MapSaverNode(context=ctx, parameter_overrides={"file": str(blocker / "m")})
        with pytest.raises((MapSaverArgsError, ParameterError), match="--free 70 --occ 65"):
            MapSaverNode(context=ctx, parameter_overrides={"threshold_free": 70})
        assert ctx.nodes == []


def test_map_server_serves_what_map_saver_wrote(tmp_path: Path) -> None:
    with Context(transport="local") as ctx:
        pub = _publish(ctx, "/map", _grid())
        saver = MapSaverNode(context=ctx, parameter_overrides={"file": str(tmp_path / "m")})
        assert ctx.spin_until(lambda: saver.finished, timeout_s=5.0)
        pub.destroy_node()
        params, remaps = map_server_args([str(tmp_path / "m.yaml"), "map:=/static_map_topic"])
        MapServerNode(context=ctx, parameter_overrides=params, remappings=dict(remaps))
        got: list[OccupancyGrid] = []
        Node("late", context=ctx).create_subscription(
            OccupancyGrid, "/static_map_topic", got.append, qos_profile_latched
        )
        assert ctx.spin_until(lambda: bool(got), timeout_s=5.0)
    assert (got[0].info.width, got[0].info.height) == (4, 2)


@pytest.mark.slow
def test_map_saver_process_exits_after_saving(tmp_path: Path, domain: int) -> None:
    """Alone in its process (a launch's ``process: own``), map_saver exits 0 once saved."""
    spec = NodeSpec(
        executable="map_saver",
        name="map_saver",
        params=parse_map_saver_args(["-f", str(tmp_path / "m")]).params(),
        process="own",
    )
    spec_file = tmp_path / "spec.json"
    spec_file.write_text(
        json.dumps({"label": "map_saver", "domain": domain, "nodes": [spec.to_json()]})
    )
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    with Context(domain) as ctx:
        _publish(ctx, "/map", _grid())
        proc = subprocess.Popen(
            [sys.executable, "-m", "visnav.launch.runner", str(spec_file)],
            env=env,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            ctx.spin_until(lambda: proc.poll() is not None, timeout_s=60.0)
        finally:
            if proc.poll() is None:
                proc.kill()
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert (tmp_path / "m.pgm").is_file()
    assert "wrote" in err


def test_visnav_map_save_takes_the_map_remapping(tmp_path: Path) -> None:
    code = main(["map", "save", "-f", str(tmp_path / "m"), "--timeout", "0.2", "bogus:=/x"])
    assert code == 1
    assert not (tmp_path / "m.yaml").exists()


@pytest.mark.slow
def test_visnav_map_save_with_map_remapping_from_another_process(
    tmp_path: Path, domain: int
) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    with Context(domain) as ctx:
        _publish(ctx, "/slam/map", _grid())
        proc = subprocess.Popen(
            [sys.executable, "-m", "visnav.cli.main", "map", "save", "-f", "~/m", "--occ",
             "71", "map:=/slam/map", "--timeout", "30"],
            env={**env, "HOME": str(tmp_path)}, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            ctx.spin_until(lambda: proc.poll() is not None, timeout_s=60.0)
        finally:
            if proc.poll() is None:
                proc.kill()
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "Waiting for the map on /slam/map" in out
    pixels, _ = read_pgm(tmp_path / "m.pgm")  # ~ expanded, --occ 71 applied
    np.testing.assert_array_equal(pixels, [[205, 0, 205, 205], [254, 254, 205, 205]])


def test_yaml_launch_args_of_map_server_and_map_saver(tmp_path: Path) -> None:
    from visnav.launch import load_launch
    from visnav.launch.errors import LaunchParseError

    launch = tmp_path / "maps.launch.yaml"
    launch.write_text(
        "launch:\n"
        "  - node: {exec: map_server, args: /maps/office.yaml, params: {frame_id: world}}\n"
        "  - node: {exec: map_saver, args: '-f ~/m --occ 70', remap: {map: /slam/map}}\n"
    )
    server, saver = load_launch(launch).nodes
    assert dict(server.params) == {"yaml_filename": "/maps/office.yaml", "frame_id": "world"}
    assert dict(saver.params) == {"file": "~/m", "threshold_occupied": 70, "threshold_free": 25}
    assert saver.remaps == (("map", "/slam/map"),)
    launch.write_text("launch:\n  - node: {exec: map_saver, args: '-f m map:=/x'}\n")
    with pytest.raises(LaunchParseError, match=r"map:=/x is a remapping; .*remap: \{map: /x\}"):
        load_launch(launch)
    launch.write_text("launch:\n  - node: {exec: map_server, args: 'a.pgm 0.05'}\n")
    with pytest.raises(LaunchParseError, match="deprecated IMAGE RESOLUTION"):
        load_launch(launch)
