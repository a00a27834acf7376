"""Killed recordings: a real ``visnav bag record`` killed with SIGKILL, and cut files."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from visnav.bag import BagReader, BagWriter, bag_info, read_bag, reindex_bag
from visnav.bag.storage import detect_layout
from visnav.graph import Context, Node
from visnav.msgs import String, serialize


@pytest.mark.parametrize(
    "fmt", ["mcap", pytest.param("ros1", marks=[pytest.mark.slow, pytest.mark.ci])]
)
def test_sigkilled_recorder_leaves_a_readable_bag(tmp_path: Path, domain: int, fmt: str) -> None:
    out = tmp_path / "killed"
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    cmd = [sys.executable, "-m", "visnav.cli.main", "bag", "record", "/chatter", "-o", str(out)]
    proc = subprocess.Popen(
        [*cmd, "--format", fmt, "--compression", "lz4"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("Recording to")
        with Context(domain) as ctx:
            pub = Node("talker", context=ctx).create_publisher(String, "/chatter", 100)
            deadline = time.monotonic() + 5.0
            while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            assert pub.get_subscription_count() == 1
            time.sleep(0.1)
            sent: list[tuple[float, str]] = []
            end = time.monotonic() + 1.15
            i = 0
            while time.monotonic() < end:
                pub.publish(String(data=f"m{i}"))
                sent.append((time.monotonic(), f"m{i}"))
                i += 1
                time.sleep(0.01)
            proc.kill()  # SIGKILL: no chance to close the bag
            killed_at = time.monotonic()
            proc.wait(5)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    bag = out.with_suffix(".bag") if fmt == "ros1" else out
    layout = detect_layout(bag)
    assert not layout.complete
    info = bag_info(bag)  # works on the unclosed bag
    assert not info.complete
    got = [m.msg.data for m in read_bag(bag)]
    names = [d for _, d in sent]
    assert got, "nothing recovered"
    k = names.index(got[0])
    assert got == names[k : k + len(got)], "recovered messages are not a contiguous run"
    assert k <= 5
    # Flushes every 0.5 s: everything published more than 1 s before the kill is in the file.
    must_have = [d for t, d in sent if t < killed_at - 1.0]
    assert set(must_have) <= set(got)
    assert info.message_count == len(got)
    res = reindex_bag(bag)
    assert detect_layout(bag).complete
    assert res.message_count == len(got)
    assert [m.msg.data for m in read_bag(bag)] == got


@pytest.mark.parametrize(("fmt", "compression"), [("mcap", "zstd"), ("ros1", "bz2")])
def test_every_cut_reads_a_prefix(tmp_path: Path, fmt: str, compression: str) -> None:
    """Cut an unclosed bag at every byte: reading yields a prefix of what was flushed."""
    w = BagWriter(tmp_path / "cut", fmt=fmt, compression=compression, chunk_size=200)
    t = w.add_topic("/chatter", "std_msgs/msg/String")
    for i in range(24):
        w.write(t, 1000 + i, serialize(String(data=f"m{i}")))
        if i % 6 == 5:
            w.flush()
    w.flush()
    f = detect_layout(w.path).files[0]
    data = f.read_bytes()
    want = [f"m{i}" for i in range(24)]
    copy = tmp_path / ("copy.bag" if fmt == "ros1" else "copy.mcap")
    seen_lengths = set()
    header_end = 4117 if fmt == "ros1" else 16  # a ROS 1 bag starts with a 4 KiB header record
    for cut in [*range(len(data), header_end, -3), 100, 20]:
        copy.write_bytes(data[:cut])
        got = [m.msg.data for m in read_bag(copy)]
        assert got == want[: len(got)]
        seen_lengths.add(len(got))
    assert {0, 24} <= seen_lengths
    assert len(seen_lengths) >= 4  # several chunk boundaries
    w.close()


def test_recovered_directory_without_metadata(tmp_path: Path) -> None:
    w = BagWriter(tmp_path / "bag")
    t = w.add_topic("/chatter", "std_msgs/msg/String")
    for i in range(3):
        w.write(t, 10 + i, serialize(String(data=str(i))))
    w.flush()
    copy = tmp_path / "copy"
    shutil.copytree(w.path, copy)
    (copy / "metadata.yaml").unlink()
    w.close()
    with BagReader(copy) as reader:
        assert not reader.complete
        assert [m.msg.data for m in reader.messages()] == ["0", "1", "2"]
