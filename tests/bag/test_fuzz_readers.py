"""Fuzzing the bag readers: mutated bytes of small valid bags raise visnav's errors only.

Each example overwrites, inserts, deletes and/or cuts bytes of a small valid bag (ROS 1 and
MCAP, each compression) and runs what the CLI verbs run: ``bag info``, reading and decoding
every message, a scan-only read (what ``bag reindex`` reads) and the tolerant scanners.
Whatever happens, only :class:`visnav.errors.VisnavError` may escape, never a traceback.
15 examples per format keep the default run short; ``VISNAV_FUZZ_EXAMPLES=400`` fuzzes deeper.
"""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.bag import BagReader, BagWriter, bag_info
from visnav.bag.recovery import ScanReport, scan_mcap, scan_ros1
from visnav.errors import VisnavError
from visnav.msgs import CameraInfo, Image, String, make, serialize

_CASES = [
    ("ros1", "none"),
    ("ros1", "bz2"),
    ("ros1", "lz4"),
    ("mcap", "none"),
    ("mcap", "zstd"),
    ("mcap", "lz4"),
]


def _valid_bag(path: Path, fmt: str, compression: str) -> bytes:
    """A small bag: three types, several chunks; return its storage file's bytes."""
    with BagWriter(path, fmt=fmt, compression=compression, chunk_size=600) as w:
        chatter = w.add_topic("/chatter", "std_msgs/msg/String")
        image = w.add_topic("/image", "sensor_msgs/msg/Image")
        info = w.add_topic("/info", "sensor_msgs/msg/CameraInfo")
        for i in range(12):
            w.write(chatter, 1000 + i, serialize(String(data=f"m{i}")))
            if i % 3 == 0:
                img = make(
                    Image,
                    height=2,
                    width=3,
                    encoding="mono8",
                    step=3,
                    data=np.arange(6, dtype=np.uint8),
                )
                w.write(image, 1000 + i, serialize(img))
                w.write(info, 1000 + i, serialize(make(CameraInfo, width=3, height=2)))
    storage = path if fmt == "ros1" else path / f"{path.name}_0.mcap"
    return storage.read_bytes()


@pytest.fixture(scope="module")
def originals(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], bytes]:
    root = tmp_path_factory.mktemp("fuzz_src")
    return {
        (fmt, comp): _valid_bag(
            root / (f"{fmt}_{comp}.bag" if fmt == "ros1" else f"{fmt}_{comp}"), fmt, comp
        )
        for fmt, comp in _CASES
    }


_edit = st.one_of(
    st.tuples(st.just("set"), st.floats(0, 1), st.binary(min_size=1, max_size=8)),
    st.tuples(st.just("insert"), st.floats(0, 1), st.binary(min_size=1, max_size=8)),
    st.tuples(st.just("delete"), st.floats(0, 1), st.integers(1, 16)),
    st.tuples(st.just("cut"), st.floats(0, 1), st.none()),
)


def _mutate(data: bytes, edits: list[tuple[str, float, bytes | int | None]]) -> bytes:
    out = bytearray(data)
    for kind, where, arg in edits:
        pos = min(int(where * len(out)), max(len(out) - 1, 0))
        if kind == "set" and isinstance(arg, bytes):
            out[pos : pos + len(arg)] = arg
        elif kind == "insert" and isinstance(arg, bytes):
            out[pos:pos] = arg
        elif kind == "delete" and isinstance(arg, int):
            del out[pos : pos + arg]
        elif kind == "cut":
            del out[pos:]
    return bytes(out)


def _exercise(path: Path, is_ros1: bool) -> None:
    """What the CLI verbs do with a bag; only visnav errors may come out."""
    with contextlib.suppress(VisnavError):
        bag_info(path)
    try:
        with BagReader(path) as reader:
            for raw in reader.raw_messages():
                with contextlib.suppress(VisnavError):
                    reader.decode(raw)
    except VisnavError:
        pass
    try:
        with BagReader(path, scan=True) as reader:
            for _ in reader.raw_messages():
                pass
    except VisnavError:
        pass
    storage = path if is_ros1 else next(path.glob("*.mcap"))
    scan = scan_ros1 if is_ros1 else scan_mcap
    try:
        for _ in scan(storage, ScanReport()):
            pass
    except VisnavError:  # not a bag at all (its magic bytes were hit)
        pass


@pytest.mark.parametrize(("fmt", "compression"), _CASES)
@settings(
    max_examples=int(os.environ.get("VISNAV_FUZZ_EXAMPLES", "15")),
    deadline=None,
    derandomize=True,  # the same examples every run (a seed, like every random source here)
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(edits=st.lists(_edit, min_size=1, max_size=4))
def test_mutated_bags_raise_visnav_errors_only(
    tmp_path: Path,
    originals: dict[tuple[str, str], bytes],
    fmt: str,
    compression: str,
    edits: list[tuple[str, float, bytes | int | None]],
) -> None:
    data = _mutate(originals[(fmt, compression)], edits)
    logging.getLogger("visnav.bag").setLevel(logging.ERROR)  # recovery warnings are expected
    if fmt == "ros1":
        path = tmp_path / "f.bag"
        path.write_bytes(data)
    else:
        path = tmp_path / "f"
        path.mkdir(exist_ok=True)
        for old in path.iterdir():
            old.unlink()
        (path / "f_0.mcap").write_bytes(data)
    _exercise(path, fmt == "ros1")


def test_the_originals_read_whole(originals: dict[tuple[str, str], bytes], tmp_path: Path) -> None:
    """The fuzz inputs are valid bags to start from (so mutations test damage, not junk)."""
    for (fmt, comp), data in originals.items():
        path = tmp_path / (f"{fmt}_{comp}.bag" if fmt == "ros1" else f"{fmt}_{comp}")
        if fmt == "ros1":
            path.write_bytes(data)
        else:
            path.mkdir()
            (path / f"{path.name}_0.mcap").write_bytes(data)
        info = bag_info(path)
        assert info.complete
        assert info.message_count == 20
