"""Damaged bags whose messages are intact: every reader falls back to scanning and says so.

The repros of issue 13: a ROS 1 bag cut by one byte, garbage in a ROS 1 index, garbage in an
MCAP summary, a chunk that fails its CRC; ``bag reindex`` repairs all of them, and ``bag
convert`` never leaves a partial output.
"""

from __future__ import annotations

import logging
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from visnav.bag import BagReader, BagWriter, CorruptBagError, bag_info, convert_bag, read_bag
from visnav.bag.recovery import RecoveredMessage, ScanReport, scan_mcap, scan_ros1
from visnav.bag.storage import detect_layout
from visnav.cli.main import main
from visnav.msgs import Image, String, make, serialize

N = 441


def _bag(path: Path, fmt: str, compression: str = "none", n: int = N) -> Path:
    with BagWriter(path, fmt=fmt, compression=compression, chunk_size=2000) as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        for i in range(n):
            w.write(t, 1_000_000_000 + i * 1000, serialize(String(data=f"m{i}")))
    return w.path


def _storage(bag: Path) -> Path:
    return detect_layout(bag).files[0]


def _ros1_index_pos(data: bytes) -> int:
    (hlen,) = struct.unpack_from("<I", data, 13)
    header = data[17 : 17 + hlen]
    at = header.index(b"index_pos=") + len(b"index_pos=")
    return int(struct.unpack_from("<Q", header, at)[0])


def _mcap_summary_start(data: bytes) -> int:
    footer = len(data) - 8 - 29  # footer record: op, length, summary start, summary offset, crc
    assert data[footer] == 0x02
    return int(struct.unpack_from("<Q", data, footer + 9)[0])


def _mcap_chunks(data: bytes) -> list[int]:
    pos, out = 8, []
    while data[pos] != 0x0F:
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if data[pos] == 0x06:
            out.append(pos)
        pos += 9 + length
    return out


def _cut_one_byte(bag: Path) -> None:
    bag.write_bytes(bag.read_bytes()[:-1])


def _garbage_ros1_index(bag: Path) -> None:
    data = bytearray(bag.read_bytes())
    start = _ros1_index_pos(bytes(data)) + 20
    data[start:] = np.random.default_rng(1).integers(0, 256, len(data) - start, np.uint8).tobytes()
    bag.write_bytes(bytes(data))


def _garbage_mcap_summary(bag: Path) -> None:
    f = _storage(bag)
    data = bytearray(f.read_bytes())
    start, end = _mcap_summary_start(bytes(data)), len(data) - 8 - 29
    data[start:end] = bytes((b * 7 + 13) & 0xFF for b in data[start:end])
    f.write_bytes(bytes(data))


@pytest.mark.parametrize(
    ("fmt", "damage"),
    [("ros1", _cut_one_byte), ("ros1", _garbage_ros1_index), ("mcap", _garbage_mcap_summary)],
    ids=["ros1-cut-1-byte", "ros1-garbage-index", "mcap-garbage-summary"],
)
def test_damaged_index_reads_by_scanning_and_reindex_repairs(
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    capsys: pytest.CaptureFixture[str],
    fmt: str,
    damage: object,
) -> None:
    bag = _bag(tmp_path / ("b.bag" if fmt == "ros1" else "b"), fmt)
    want = [f"m{i}" for i in range(N)]
    damage(bag)  # type: ignore[operator]
    with caplog.at_level(logging.WARNING, logger="visnav.bag"):
        info = bag_info(bag)
    assert info.message_count == N
    assert not info.complete
    assert "does not decode" in info.recovery
    warning = caplog.records[-1].getMessage()
    assert str(bag) in warning
    assert f"recovered {N} messages" in warning
    assert [m.msg.data for m in read_bag(bag)] == want
    with BagReader(bag) as reader:
        assert reader.recovery
    # the CLI verbs read it (the warning goes to the log, the figures to stdout)
    assert main(["bag", "info", str(bag)]) == 0
    assert f"Messages:          {N}" in capsys.readouterr().out
    assert main(["bag", "reindex", str(bag)]) == 0
    capsys.readouterr()
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="visnav.bag"):
        repaired = bag_info(bag)
        assert [m.msg.data for m in read_bag(bag)] == want
    assert repaired.complete
    assert repaired.message_count == N
    assert not caplog.records  # read through its new index, no warning


def test_recover_false_refuses_a_damaged_index(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "b.bag", "ros1")
    _garbage_ros1_index(bag)
    with pytest.raises(CorruptBagError, match=r"b\.bag"):
        BagReader(bag, recover=False)


@pytest.mark.parametrize("compression", ["none", "zstd", "lz4"])
def test_mcap_chunks_carry_crcs_and_a_corrupt_chunk_is_skipped(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, compression: str
) -> None:
    bag = _bag(tmp_path / "c", "mcap", compression)
    f = _storage(bag)
    data = bytearray(f.read_bytes())
    chunks = _mcap_chunks(bytes(data))
    assert len(chunks) >= 4
    crcs = [struct.unpack_from("<QQQI", data, c + 9)[3] for c in chunks]
    assert all(crcs), crcs  # real CRCs, not the 0 of "not computed"
    # flip one byte inside the records of the third chunk
    victim = chunks[2]
    (kind_len,) = struct.unpack_from("<I", data, victim + 9 + 28)
    data[victim + 9 + 32 + kind_len + 8 + 20] ^= 0x5A
    f.write_bytes(bytes(data))
    # the index-based read reports the chunk; it never hands out damaged bytes
    with pytest.raises(CorruptBagError, match="reindex"):
        list(read_bag(bag))
    # recovery skips it: every other message is there, and it is said
    report = ScanReport()
    scanned = [x for x in scan_mcap(f, report) if isinstance(x, RecoveredMessage)]
    assert len(report.skipped) == 1
    assert f"chunk at byte {victim}" in report.skipped[0]
    lost = N - len(scanned)
    assert 0 < lost < N // 3
    with caplog.at_level(logging.WARNING, logger="visnav.bag"):
        info = bag_info(bag)
    assert info.message_count == N - lost
    assert "damaged chunk" in info.recovery
    assert any("damaged chunk" in r.getMessage() for r in caplog.records)
    result = convert_bag(bag, tmp_path / "out", scan=True)
    assert result.message_count == N - lost
    assert "damaged chunk" in result.recovery
    # and bag reindex rewrites it without the damaged chunk
    assert main(["bag", "reindex", str(bag)]) == 0
    got = [m.msg.data for m in read_bag(bag)]
    assert len(got) == N - lost
    assert set(got) < {f"m{i}" for i in range(N)}
    assert bag_info(bag).complete


def test_ros1_corrupt_chunk_is_skipped_by_the_scan(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "c.bag", "ros1", "bz2")
    data = bytearray(bag.read_bytes())
    chunks = []  # (record start, data start, data length) of each chunk record
    pos = 13
    while pos < _ros1_index_pos(bytes(data)):
        (hlen,) = struct.unpack_from("<I", data, pos)
        (dlen,) = struct.unpack_from("<I", data, pos + 4 + hlen)
        if b"op=\x05" in data[pos + 4 : pos + 4 + hlen]:
            chunks.append((pos, pos + 8 + hlen, dlen))
        pos += 8 + hlen + dlen
    assert len(chunks) >= 4
    where, start, length = chunks[2]
    data[start + length // 2 : start + length // 2 + 16] = b"\x00" * 16
    bag.write_bytes(bytes(data))
    report = ScanReport()
    got = [x for x in scan_ros1(bag, report) if isinstance(x, RecoveredMessage)]
    assert len(report.skipped) == 1
    assert f"chunk at byte {where}" in report.skipped[0]
    assert N // 2 < len(got) < N
    with pytest.raises(CorruptBagError):
        list(scan_ros1(bag))  # strict scans still raise


def _image_bag(path: Path, *, bad_at: int) -> Path:
    with BagWriter(path) as w:
        t = w.add_topic("/cam/image", "sensor_msgs/msg/Image")
        for i in range(10):
            img = make(
                Image, height=2, width=2, encoding="mono8", step=2, data=np.zeros(4, np.uint8)
            )
            raw = bytes(serialize(img))
            if i == bad_at:
                raw = raw[:4] + b"\xff" * (len(raw) - 4)  # a damaged payload
            w.write(t, 1000 + i, raw)
    return w.path


def test_convert_corrupt_payload_is_one_line_and_leaves_no_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = _image_bag(tmp_path / "src", bad_at=6)
    out = tmp_path / "out.bag"
    assert main(["bag", "convert", str(src), str(out), "--format", "ros1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("error: converting ")
    assert "'/cam/image'" in err[0]
    assert "message #6" in err[0]
    assert "t=1006 ns" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]  # no partial output, no temp
    with pytest.raises(CorruptBagError, match="/cam/image"):
        convert_bag(src, out, fmt="ros1")
    assert not out.exists()


def test_convert_ros1_corrupt_payload_to_mcap_is_one_line_and_leaves_no_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A ROS 1 message whose bytes do not decode (string length 1e6) stops a CDR conversion."""
    src = _bag(tmp_path / "src.bag", "ros1", n=20)
    data = bytearray(src.read_bytes())
    at = data.index(struct.pack("<I", 2) + b"m7")
    data[at : at + 4] = struct.pack("<I", 1_000_000)
    src.write_bytes(bytes(data))
    out = tmp_path / "out"
    assert main(["bag", "convert", str(src), str(out), "--format", "mcap"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"error: bag '{src}': a message on '/chatter' at t=1000007000 ns")
    assert "not valid ROS 1 std_msgs/msg/String" in err[0]
    assert "--topics" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src.bag"]  # no partial output
    # ROS 1 -> ROS 1 copies the bytes as they are (rosbag does not decode them either)
    assert main(["bag", "convert", str(src), str(tmp_path / "copy.bag"), "--format", "ros1"]) == 0


def test_play_skips_and_counts_a_message_that_does_not_decode(
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    capsys: pytest.CaptureFixture[str],
    domain: int,  # the CLI's playback goes into a private VISNAV_DOMAIN
) -> None:
    from visnav.bag import BagPlayer
    from visnav.graph import Context, Node

    src = _bag(tmp_path / "src.bag", "ros1", n=20)
    data = bytearray(src.read_bytes())
    for i in (7, 9):
        at = data.index(struct.pack("<I", 2) + f"m{i}".encode())
        data[at : at + 4] = struct.pack("<I", 1_000_000)
    src.write_bytes(bytes(data))
    got: list[str] = []
    with Context(transport="local") as ctx, caplog.at_level(logging.WARNING, logger="visnav.bag"):
        Node("sub", context=ctx).create_subscription(
            String, "/chatter", lambda m: got.append(m.data), 100
        )
        player = BagPlayer(ctx, src, rate=100.0)
        player.start()
        assert ctx.spin_until(lambda: player.done, 10.0)
        ctx.spin_some()
        player.wait()
    assert got == [f"m{i}" for i in range(20) if i not in (7, 9)]
    assert player.stats.undecodable == {"/chatter": 2}
    said = [r.getMessage() for r in caplog.records if "skipping it" in r.getMessage()]
    assert len(said) == 1  # once per topic
    assert "'/chatter' at t=1000007000" in said[0]
    # the CLI plays on and says how many it skipped
    assert main(["bag", "play", str(src), "-r", "100"]) == 0
    err = capsys.readouterr().err
    assert "skipped 2 message(s) on '/chatter' that do not decode" in err


def test_convert_appears_only_when_complete(tmp_path: Path) -> None:
    """The output path exists only after success (a temporary name is used meanwhile)."""
    src = _bag(tmp_path / "src", "mcap", n=30)
    seen: list[list[str]] = []

    def spy(*_a: object) -> None:
        seen.append(sorted(p.name for p in tmp_path.iterdir()))

    import visnav.bag.convert as conv

    orig = conv._convert

    def wrapped(*args: object, **kwargs: object) -> conv.ConvertResult:
        result = orig(*args, **kwargs)  # type: ignore[arg-type]
        spy()
        return result

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(conv, "_convert", wrapped)
        res = convert_bag(src, tmp_path / "dst.bag", fmt="ros1")
    assert "dst.bag" not in seen[0]
    assert any(name.startswith(".dst.bag.") and name.endswith(".partial") for name in seen[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dst.bag", "src"]
    assert res.path == tmp_path / "dst.bag"
    assert [m.msg.data for m in read_bag(res.path)] == [f"m{i}" for i in range(30)]


def test_calibrate_images_from_an_unclosed_bag(tmp_path: Path) -> None:
    """``calibrate --bag`` reads through the same reader as ``bag info``/``play``."""
    from visnav.perception.calibration_sources import images_from_bag

    src = _image_bag(tmp_path / "src", bad_at=-1)
    cut = tmp_path / "cut.mcap"
    data = _storage(src).read_bytes()
    cut.write_bytes(data[: _mcap_summary_start(data) - 20])  # unclosed: no summary, no footer
    assert not detect_layout(cut).complete
    frames = list(images_from_bag(cut, "/cam/image"))
    assert len(frames) == 10
    assert frames[0][1].shape == (2, 2)


def test_reindex_restores_the_original_when_it_fails(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "r.bag", "ros1", n=20)
    before = bag.read_bytes()
    backup = tmp_path / "r.orig.bag"
    shutil.copy(bag, backup)
    assert main(["bag", "reindex", str(bag)]) == 1  # the backup name is taken
    assert bag.read_bytes() == before
