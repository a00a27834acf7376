"""Map files: map_saver's writing, map_server's reading rules, bad files, fuzzing."""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.mapping.map_io import (
    MapFileError,
    MapMetadata,
    OccupancyMap,
    load_map,
    pixels_to_grid,
    read_map_yaml,
    read_pgm,
    save_map,
)

GRID = np.array(
    [
        [0, 0, 100, -1],  # row 0: the bottom of the map, at the origin
        [25, 26, 64, 65],
        [-1, -1, 0, 100],
    ],
    dtype=np.int8,
)


def _grid_msg(data: np.ndarray = GRID, origin: tuple[float, float, float] = (-1.5, 2.0, 0.3)):  # type: ignore[no-untyped-def]
    meta = MapMetadata(image=Path("x.pgm"), resolution=0.05, origin=origin)
    return OccupancyMap(data, meta).to_msg()


def _write_yaml(path: Path, **fields: object) -> Path:
    base: dict[str, object] = {
        "image": "map.pgm",
        "resolution": 0.05,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    base.update(fields)
    lines = [f"{k}: {v}" for k, v in base.items() if v is not None]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_save_writes_map_saver_files(tmp_path: Path) -> None:
    yaml_path, pgm_path = save_map(_grid_msg(), tmp_path / "map")
    assert yaml_path.name == "map.yaml"
    assert yaml_path.read_text() == (
        "image: map.pgm\nresolution: 0.050000\norigin: [-1.500000, 2.000000, 0.300000]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n\n"
    )
    blob = pgm_path.read_bytes()
    header = b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n4 3\n255\n"
    assert blob.startswith(header)
    pixels = np.frombuffer(blob[len(header) :], dtype=np.uint8).reshape(3, 4)
    # the image's first row is the map's top row; 0..25 free (254), >= 65 occupied (0)
    np.testing.assert_array_equal(
        pixels,
        [[205, 205, 254, 0], [254, 205, 205, 0], [254, 254, 0, 205]],
    )


def test_round_trip_by_map_server_rules(tmp_path: Path) -> None:
    yaml_path, _ = save_map(_grid_msg(), tmp_path / "map")
    loaded = load_map(yaml_path)
    # map_server reads 254 -> occ 0.0039 < 0.196 -> 0; 0 -> occ 1 > 0.65 -> 100;
    # 205 -> occ 0.196 (not < free_thresh, not > occupied_thresh) -> -1
    expected = np.where(GRID < 0, -1, np.where(GRID <= 25, 0, np.where(GRID >= 65, 100, -1)))
    np.testing.assert_array_equal(loaded.data, expected)
    assert loaded.metadata.origin == (-1.5, 2.0, 0.3)
    msg = loaded.to_msg()
    assert (msg.info.width, msg.info.height) == (4, 3)
    assert msg.info.origin.orientation.z == pytest.approx(math.sin(0.15))
    assert loaded.counts() == {"free": 4, "occupied": 3, "unknown": 5}


def test_scale_raw_and_negate_follow_map_server(tmp_path: Path) -> None:
    pixels = np.array([[0, 100, 150, 200, 254, 255]], dtype=np.uint8)
    meta = MapMetadata(image=tmp_path, resolution=0.1, origin=(0.0, 0.0, 0.0))
    occ = (255 - pixels.astype(float)) / 255  # 1.0, 0.608, 0.412, 0.216, 0.004, 0
    np.testing.assert_array_equal(pixels_to_grid(pixels, meta), [[100, -1, -1, -1, 0, 0]])
    scaled = pixels_to_grid(pixels, MapMetadata(**{**meta.__dict__, "mode": "scale"}))
    ratio = (occ - 0.196) / (0.65 - 0.196)
    expected = [100, int(99 * ratio[0, 1]), int(99 * ratio[0, 2]), int(99 * ratio[0, 3]), 0, 0]
    np.testing.assert_array_equal(scaled, [expected])
    raw = pixels_to_grid(pixels, MapMetadata(**{**meta.__dict__, "mode": "raw"}))
    np.testing.assert_array_equal(raw, [[0, 100, -106, -56, -2, -1]])  # uint8 read as int8
    negated = pixels_to_grid(pixels, MapMetadata(**{**meta.__dict__, "negate": True}))
    np.testing.assert_array_equal(negated, [[0, -1, -1, 100, 100, 100]])  # occ = pixel / 255


def test_png_with_alpha_in_scale_mode(tmp_path: Path) -> None:
    bgra = np.zeros((2, 2, 4), dtype=np.uint8)
    bgra[..., :3] = 150  # occ 0.41: between the thresholds
    bgra[..., 3] = 255
    bgra[0, 0, 3] = 0  # transparent: unknown in scale mode
    cv2.imwrite(str(tmp_path / "m.png"), bgra)
    yaml_path = _write_yaml(tmp_path / "m.yaml", image="m.png", mode="scale")
    loaded = load_map(yaml_path)
    ratio = ((255 - 150) / 255 - 0.196) / (0.65 - 0.196)
    # image row 0 is the map's top: the transparent pixel is the map's (row 1, col 0)
    np.testing.assert_array_equal(loaded.data, [[int(99 * ratio)] * 2, [-1, int(99 * ratio)]])


def test_ascii_pgm_and_absolute_image(tmp_path: Path) -> None:
    pgm = tmp_path / "sub" / "a.pgm"
    pgm.parent.mkdir()
    pgm.write_text("P2\n# a comment\n2 1\n15\n0 15\n")
    pixels, res = read_pgm(pgm)
    np.testing.assert_array_equal(pixels, [[0, 255]])
    assert res is None
    loaded = load_map(_write_yaml(tmp_path / "a.yaml", image=str(pgm)))
    np.testing.assert_array_equal(loaded.data, [[100, 0]])


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"resolution": 0}, "resolution: 0 m/cell"),
        ({"resolution": -0.05}, "resolution: -0.05"),
        ({"origin": "[1, 2]"}, r"origin: \[1, 2\] is not 3 numbers"),
        ({"origin": "[1, 2, a]"}, "origin: .* is not 3 numbers"),
        ({"negate": 2}, "negate: 2 is not 0 or 1"),
        ({"occupied_thresh": 0.1}, "free_thresh/occupied_thresh: 0.196 / 0.1 are out of order"),
        ({"free_thresh": -0.1}, "out of order"),
        ({"mode": "fancy"}, "mode: 'fancy' is not a map mode"),
        ({"image": None}, "image: is missing"),
        ({"resolution": None}, "resolution: is missing"),
        ({"image": "nope.pgm"}, "nope.pgm: image: does not exist"),
    ],
)
def test_bad_yaml_fields_are_one_line_errors(
    tmp_path: Path, fields: dict[str, object], match: str
) -> None:
    save_map(_grid_msg(), tmp_path / "map")
    path = _write_yaml(tmp_path / "bad.yaml", **fields)
    with pytest.raises(MapFileError, match=match) as info:
        load_map(path)
    assert "\n" not in str(info.value)
    assert "bad.yaml" in str(info.value) or "nope.pgm" in str(info.value)


def test_yaml_and_pgm_that_disagree(tmp_path: Path) -> None:
    yaml_path, pgm_path = save_map(_grid_msg(), tmp_path / "map")
    _write_yaml(yaml_path, resolution=0.1)
    with pytest.raises(MapFileError, match=r"map.yaml: resolution: 0.1 m/cell but map.pgm was "):
        load_map(yaml_path)
    save_map(_grid_msg(), tmp_path / "map")
    pgm_path.write_bytes(pgm_path.read_bytes()[:-3])  # truncated data
    with pytest.raises(MapFileError, match=r"map.pgm: PGM data: 9 bytes for a 4x3 header"):
        load_map(yaml_path)


def test_missing_yaml_and_bad_save_input(tmp_path: Path) -> None:
    with pytest.raises(MapFileError, match=r"nothing\.yaml"):
        read_map_yaml(tmp_path / "nothing.yaml")
    msg = _grid_msg()
    msg.info.width = 5
    with pytest.raises(MapFileError, match="5x3 but holds 12 cells"):
        save_map(msg, tmp_path / "m")
    with pytest.raises(MapFileError, match="free=70 occupied=65"):
        save_map(_grid_msg(), tmp_path / "m", free=70)


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(yaml_text=st.text(max_size=200), image=st.binary(max_size=120))
def test_fuzz_reader_raises_only_map_errors(tmp_path: Path, yaml_text: str, image: bytes) -> None:
    (tmp_path / "map.pgm").write_bytes(image)
    path = tmp_path / "f.yaml"
    path.write_text(yaml_text, encoding="utf-8", errors="replace")
    with contextlib.suppress(VisnavError):
        load_map(path)


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    header=st.lists(
        st.sampled_from(["P5", "P2", "4", "3", "255", "0", "-1", "# c", "x", "99999"]), max_size=6
    ),
    body=st.binary(max_size=40),
    resolution=st.sampled_from(["0.05", "0", "1e400", "nan", "[1]", "'a'"]),
    origin=st.sampled_from(["[0, 0, 0]", "[1, 2]", "[.inf, 0, 0]", "3", "[true, 0, 0]"]),
)
def test_fuzz_structured_map_files(
    tmp_path: Path, header: list[str], body: bytes, resolution: str, origin: str
) -> None:
    (tmp_path / "map.pgm").write_bytes("\n".join(header).encode() + b"\n" + body)
    path = _write_yaml(tmp_path / "s.yaml", resolution=resolution, origin=origin)
    try:
        loaded = load_map(path)
    except VisnavError:
        return
    assert loaded.data.dtype == np.int8
    assert loaded.metadata.resolution > 0
