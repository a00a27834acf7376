"""The map_server node and ``visnav map save|info`` (map_saver) across real processes."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from visnav.cli.main import main
from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.mapping.map_io import MapFileError, MapMetadata, OccupancyMap, load_map, save_map
from visnav.mapping.map_server_node import MapServerNode
from visnav.msgs.types import MapMetaData, OccupancyGrid
from visnav.node_registry import resolve_node_class

GRID = np.array([[0, 0, 100], [-1, 100, 0]], dtype=np.int8)


def _saved(tmp_path: Path) -> Path:
    meta = MapMetadata(image=Path("x"), resolution=0.1, origin=(1.0, -2.0, 0.0))
    yaml_path, _ = save_map(OccupancyMap(GRID, meta).to_msg(), tmp_path / "saved")
    return yaml_path


def test_map_server_publishes_latched_map(tmp_path: Path, domain: int) -> None:
    yaml_path = _saved(tmp_path)
    assert resolve_node_class("map_server") is MapServerNode
    with Context(domain) as ctx:
        MapServerNode(context=ctx, parameter_overrides={"yaml_filename": str(yaml_path)})
        got: list[OccupancyGrid] = []
        meta: list[MapMetaData] = []
        late = Node("late", context=ctx)  # subscribes after the one publication: latched
        qos = qos_profile_latched
        late.create_subscription(OccupancyGrid, "/map", got.append, qos)
        late.create_subscription(MapMetaData, "/map_metadata", meta.append, qos)
        assert ctx.spin_until(lambda: bool(got) and bool(meta), 5.0)
    grid = got[0]
    assert grid.header.frame_id == "map"
    assert (grid.info.width, grid.info.height, grid.info.resolution) == (3, 2, 0.1)
    assert grid.info.origin.position.x == 1.0
    np.testing.assert_array_equal(np.asarray(grid.data).reshape(2, 3), GRID)
    assert meta[0].width == 3


def test_map_server_without_a_file_is_an_error(tmp_path: Path, domain: int) -> None:
    with Context(domain) as ctx:
        with pytest.raises(MapFileError, match="parameter yaml_filename is empty"):
            MapServerNode(context=ctx)
        with pytest.raises(MapFileError, match=r"missing\.yaml"):
            MapServerNode(
                context=ctx, parameter_overrides={"yaml_filename": str(tmp_path / "missing.yaml")}
            )


def test_map_info_prints_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["map", "info", str(_saved(tmp_path))]) == 0
    out = capsys.readouterr().out
    assert "size:         3 x 2 cells (0.3 x 0.2 m)" in out
    assert "resolution:   0.1 m/cell" in out
    assert "origin:       [1, -2, 0]" in out
    assert "free:         3 (50.0 %)" in out
    assert "occupied:     2 (33.3 %)" in out
    assert "unknown:      1 (16.7 %)" in out


def test_map_save_from_another_process(tmp_path: Path, domain: int) -> None:
    yaml_path = _saved(tmp_path)
    out = tmp_path / "out" / "office"
    out.parent.mkdir()
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    with Context(domain) as ctx:
        MapServerNode(context=ctx, parameter_overrides={"yaml_filename": str(yaml_path)})
        proc = subprocess.Popen(
            [sys.executable, "-m", "visnav.cli.main", "map", "save", "-f", str(out),
             "--timeout", "30"],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 60
            while proc.poll() is None and time.monotonic() < deadline:
                ctx.spin_once(0.05)
            stdout, stderr = proc.communicate(timeout=10)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 0, stderr
    assert "Received a 3 X 2 map @ 0.100 m/pix" in stdout
    saved = load_map(out.with_suffix(".yaml"))
    np.testing.assert_array_equal(saved.data, GRID)
    assert out.with_suffix(".pgm").read_bytes() == yaml_path.with_suffix(".pgm").read_bytes()


def test_map_save_times_out_with_a_clear_error(
    tmp_path: Path, domain: int, capsys: pytest.CaptureFixture[str]
) -> None:
    del domain
    code = main(["map", "save", "-f", str(tmp_path / "m"), "--timeout", "0.5"])
    err = capsys.readouterr().err
    assert code != 0
    assert "no nav_msgs/OccupancyGrid on /map within 0.5 s" in err
