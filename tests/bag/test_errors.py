"""Bad input: one clear error each (library exception + one ``error:`` line in the CLI)."""

from __future__ import annotations

from pathlib import Path

import pytest

from visnav.bag import (
    BagError,
    BagExistsError,
    BagNotFoundError,
    BagRecorder,
    BagWriter,
    CorruptBagError,
    TopicNotInBagError,
    UnknownStorageError,
    bag_info,
    convert_bag,
    read_bag,
)
from visnav.bag.storage import detect_layout
from visnav.cli.main import main
from visnav.errors import VisnavError
from visnav.graph import Context
from visnav.msgs import String, serialize


def _bag(path: Path, fmt: str = "mcap", compression: str = "none", n: int = 50) -> Path:
    with BagWriter(path, fmt=fmt, compression=compression) as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        for i in range(n):
            w.write(t, 10 + i, serialize(String(data=f"message number {i}" * 3)))
    return w.path


def _cli_error(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    assert main(list(args)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("error: ")
    return err[0]


def test_missing_path(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(BagNotFoundError, match="does not exist"):
        bag_info(tmp_path / "nope")
    _bag(tmp_path / "run", fmt="ros1")
    line = _cli_error(capsys, "bag", "info", str(tmp_path / "run"))
    assert "did you mean" in line
    assert "run.bag" in line


def test_not_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello, not a bag" * 10)
    with pytest.raises(UnknownStorageError, match="not a bag"):
        list(read_bag(junk))
    (tmp_path / "emptydir").mkdir()
    with pytest.raises(UnknownStorageError, match=r"no metadata.yaml, \.mcap or \.db3"):
        bag_info(tmp_path / "emptydir")
    line = _cli_error(capsys, "bag", "info", str(junk))
    assert "junk.mcap" in line


def test_wrong_suffix_and_unknown_storage_id(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "b")
    wrong = tmp_path / "b.bag"
    wrong.write_bytes((bag / "b_0.mcap").read_bytes())
    with pytest.raises(
        UnknownStorageError, match=r"holds a mcap bag .* rename it to end in \.mcap"
    ):
        detect_layout(wrong)
    meta = bag / "metadata.yaml"
    meta.write_text(
        meta.read_text().replace("storage_identifier: mcap", "storage_identifier: hdf5")
    )
    with pytest.raises(UnknownStorageError, match="storage_identifier 'hdf5' is unknown"):
        bag_info(bag)


@pytest.mark.parametrize(
    ("fmt", "compression"), [("mcap", "zstd"), ("mcap", "none"), ("ros1", "lz4")]
)
def test_corrupt_chunk(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str, compression: str
) -> None:
    bag = _bag(tmp_path / "c", fmt, compression)
    f = detect_layout(bag).files[0]
    data = bytearray(f.read_bytes())
    # the middle of the first chunk's data (MCAP: after magic, header, chunk head; ROS 1: after
    # the 4 KiB bag header record)
    first_chunk = 8 + 9 + 24 + 9 + 40 if fmt == "mcap" else 13 + 4096 + 100
    mid = first_chunk + 200
    data[mid : mid + 40] = b"\xff" * 40
    f.write_bytes(bytes(data))
    # the damaged chunk (here the only one) is reported and skipped, not fatal
    info = bag_info(bag)
    assert not info.complete
    assert "damaged chunk" in info.recovery
    assert info.message_count == 0
    assert main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "damaged chunk" in out
    assert str(f) in out


def test_truncated_header_is_an_error(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "t", "ros1")
    bag.write_bytes(bag.read_bytes()[:6])
    with pytest.raises(UnknownStorageError):
        bag_info(bag)
    empty = tmp_path / "e.mcap"
    empty.write_bytes(b"\x89MCAP0\r\n")
    info = bag_info(empty)  # the magic alone: a recording killed at once holds nothing
    assert (info.complete, info.message_count) == (False, 0)


def test_topic_not_in_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = _bag(tmp_path / "b")
    with pytest.raises(TopicNotInBagError, match="did you mean /chatter"):
        list(read_bag(bag, ["/chater"]))
    line = _cli_error(capsys, "bag", "convert", str(bag), str(tmp_path / "o"), "--topics", "/chat")
    assert "did you mean /chatter" in line
    assert not (tmp_path / "o").exists()


def test_bad_format_compression_and_existing_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(UnknownStorageError, match="expected one of mcap, ros1, sqlite3"):
        BagWriter(tmp_path / "x", fmt="hdf5")
    with pytest.raises(UnknownStorageError, match="not available for ros1 bags"):
        BagWriter(tmp_path / "x", fmt="ros1", compression="zstd")
    bag = _bag(tmp_path / "b")
    with pytest.raises(BagExistsError, match="exists already"):
        convert_bag(bag, bag)
    line = _cli_error(
        capsys,
        "bag",
        "convert",
        str(bag),
        str(tmp_path / "r"),
        "--format",
        "ros1",
        "--compression",
        "zstd",
    )
    assert "zstd" in line
    with Context(transport="local") as ctx, pytest.raises(BagExistsError):
        BagRecorder(ctx, None, bag).start()
    line = _cli_error(capsys, "bag", "record", "-o", str(tmp_path / "n"))
    assert "-a" in line


def test_time_out_of_range(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "r", fmt="ros1") as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        with pytest.raises(BagError, match="outside what a ros1 bag stores"):
            w.write(t, 2**32 * 10**9, serialize(String(data="x")))
        with pytest.raises(BagError, match="outside"):
            w.write(t, -1, serialize(String(data="x")))


def test_errors_derive_from_visnav_error() -> None:
    for cls in (
        BagNotFoundError,
        UnknownStorageError,
        CorruptBagError,
        TopicNotInBagError,
        BagExistsError,
    ):
        assert issubclass(cls, BagError)
        assert issubclass(cls, VisnavError)


@pytest.mark.parametrize(
    ("fmt", "compression"),
    [("mcap", "none"), ("mcap", "lz4"), ("ros1", "bz2"), ("sqlite3", "none")],
)
def test_random_damage_gives_bag_errors_only(tmp_path: Path, fmt: str, compression: str) -> None:
    """Random overwrites and cuts: reading either works or raises a BagError, nothing else."""
    import random

    bag = _bag(tmp_path / "f", fmt, compression, n=30)
    f = detect_layout(bag).files[0]
    orig = f.read_bytes()
    rng = random.Random(7)
    outcomes = set()
    for _ in range(40):
        data = bytearray(orig)
        for _ in range(rng.randint(1, 3)):
            p = rng.randrange(len(data))
            data[p : p + 8] = rng.randbytes(8)
        if rng.random() < 0.3:
            data = data[: rng.randrange(len(data))]
        f.write_bytes(bytes(data))
        try:
            info = bag_info(bag)
            list(read_bag(bag))
            outcomes.add("read" if info.complete else "recovered")
        except BagError:
            outcomes.add("error")
    assert outcomes & {"error", "recovered"} or fmt == "sqlite3"
