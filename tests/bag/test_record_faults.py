"""Recorder faults from the user's side: bad -x, a full disk (EFBIG), .bag names, drop counts."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from visnav.bag import BagRecorder, BagWriter, bag_info, read_bag
from visnav.bag.errors import RecordError, UnknownStorageError
from visnav.bag.metadata import read_drops
from visnav.bag.storage import detect_layout
from visnav.cli.main import main
from visnav.graph import Context, Node
from visnav.msgs import String


def _one_error_line(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    assert main(list(args)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("error: ")
    return err[0]


def test_bad_exclude_regex_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], domain: int
) -> None:
    out = tmp_path / "x"
    line = _one_error_line(capsys, "bag", "record", "-a", "-x", "(", "-o", str(out))
    assert "'('" in line
    assert "regular expression" in line
    assert not out.exists()  # refused before anything was opened
    with pytest.raises(RecordError, match="not a regular expression"):
        BagRecorder(Context(transport="local"), None, out, exclude="[a-")


def test_bag_name_means_ros1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], domain: int
) -> None:
    """`-o X.bag` records a ROS 1 file that every reader opens; mcap + .bag is refused."""
    out = tmp_path / "X.bag"
    assert main(["bag", "record", "-a", "-o", str(out), "--duration", "0.3"]) == 0
    assert out.is_file()
    assert detect_layout(out).storage == "ros1"
    assert bag_info(out).message_count == 0
    assert main(["doctor", "--bag", str(out)]) in (0, 1)
    assert "Is a directory" not in capsys.readouterr().err
    line = _one_error_line(
        capsys, "bag", "record", "-a", "-o", str(tmp_path / "Y.bag"), "--format", "mcap"
    )
    assert "a .bag name means a ROS 1 bag file" in line
    assert "--format ros1" in line
    assert not (tmp_path / "Y.bag").exists()
    with pytest.raises(UnknownStorageError, match=r"\.bag name"):
        BagWriter(tmp_path / "Z.bag", fmt="mcap")


def test_rosbag2_directory_named_bag_reads(tmp_path: Path) -> None:
    """A directory named *.bag (written by older visnav) still reads through its index."""
    bag = tmp_path / "old"
    with BagWriter(bag) as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        w.write(t, 5, b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00")
    renamed = tmp_path / "old.bag"
    bag.rename(renamed)
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp_path)
        from visnav.bag import BagReader

        with BagReader("old.bag") as reader:
            assert reader.complete
            assert [m.msg.data for m in reader.messages()] == ["hi"]


@pytest.mark.parametrize("fmt", ["mcap", "ros1"])
def test_write_failure_is_one_line_and_bag_stays_readable(
    tmp_path: Path, domain: int, fmt: str
) -> None:
    """A file size limit (EFBIG) mid-recording: one error line, exit 1, a readable bag."""
    out = tmp_path / ("full.bag" if fmt == "ros1" else "full")
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    # `visnav bag record` with a 1 MB file size limit (ulimit -f): writes fail with EFBIG
    code = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, 1_000_000))\n"
        "from visnav.cli.main import main\n"
        "sys.exit(main(sys.argv[1:]))"
    )
    cmd = [sys.executable, "-c", code, "bag", "record", "/chatter", "-o", str(out)]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("Recording to")
        with Context(domain) as ctx:
            pub = Node("talker", context=ctx).create_publisher(String, "/chatter", 100)
            deadline = time.monotonic() + 5.0
            while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            payload = "x" * 2000
            i = 0
            end = time.monotonic() + 15.0
            while proc.poll() is None and time.monotonic() < end:
                pub.publish(String(data=f"{i:06d}{payload}"))
                i += 1
                if i % 2 == 0:  # ~400 KB/s: a few flushes reach the file before the limit
                    time.sleep(0.01)
        code = proc.wait(10)
        stderr = proc.communicate()[1].strip().splitlines()
        err = [line for line in stderr if not line.startswith("[INFO]")]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    assert code == 1, err
    assert len(err) == 1, err
    assert err[0].startswith("error: writing bag")
    assert "EFBIG" in err[0]
    assert str(out) in err[0]
    got = [m.msg.data[:6] for m in read_bag(out)]
    assert len(got) > 20
    assert got == sorted(got)  # a run of what was published, in order


def test_drops_are_counted_stored_and_shown(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A writer buffer far too small for a burst: drops counted per topic, kept in the bag."""
    for fmt in ("mcap", "ros1"):
        with Context(transport="local") as ctx:
            pub = Node("talker", context=ctx).create_publisher(String, "/burst", 10)
            rec = BagRecorder(ctx, ["/burst"], tmp_path / f"d_{fmt}", fmt=fmt, buffer_bytes=1 << 20)
            rec.start()
            assert ctx.spin_until(lambda rec=rec: "/burst" in rec.topics, 2.0)
            big = "y" * (300 << 10)
            for _ in range(40):  # 12 MB at once: the 1 MiB buffer must overflow
                pub.publish(String(data=big))
            ctx.spin_until(lambda: False, 1.0)
            drops = rec.drops()
            path = rec.stop()
        assert drops.get("/burst", 0) > 0
        kept = rec.topics["/burst"].count
        assert kept + drops["/burst"] == 40
        assert read_drops(detect_layout(path)) == drops
        info = bag_info(path)
        assert info.drops == drops
        assert info.topic("/burst").count == kept
        assert main(["bag", "info", str(path)]) == 0
        assert f"Recorder drops:    {drops['/burst']} (/burst: {drops['/burst']})" in (
            capsys.readouterr().out
        )


def test_subscription_queue_overflow_is_counted(tmp_path: Path) -> None:
    """Messages keep-last drops before the executor runs are counted as the topic's drops."""
    with Context(transport="local") as ctx:
        pub = Node("talker", context=ctx).create_publisher(String, "/x", 10)
        rec = BagRecorder(ctx, ["/x"], tmp_path / "q")
        rec.start()
        assert ctx.spin_until(lambda: "/x" in rec.topics, 2.0)
        assert rec.topics["/x"].qos.endswith("keep_last(1000)")
        for i in range(1200):  # no spinning meanwhile: the 1000-deep queue overflows by 200
            pub.publish(String(data=str(i)))
        ctx.spin_until(lambda: rec.message_count >= 1000, 5.0)
        path = rec.stop()
    assert rec.drops() == {"/x": 200}
    assert [m.msg.data for m in read_bag(path)] == [str(i) for i in range(200, 1200)]
    assert bag_info(path).drops == {"/x": 200}


def test_stop_writes_what_is_still_queued(tmp_path: Path) -> None:
    """Messages received but not yet handled when stop() is called are written, not lost."""
    with Context(transport="local") as ctx:
        pub = Node("talker", context=ctx).create_publisher(String, "/late", 10)
        rec = BagRecorder(ctx, ["/late"], tmp_path / "s")
        rec.start()
        assert ctx.spin_until(lambda: "/late" in rec.topics, 2.0)
        for i in range(50):
            pub.publish(String(data=str(i)))
        path = rec.stop()  # no spin in between
    assert [m.msg.data for m in read_bag(path)] == [str(i) for i in range(50)]
    assert rec.drops() == {}
