"""The ``visnav bag`` verbs as processes: graceful stop, cross-process play, convert, reindex."""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from visnav.bag import BagWriter, bag_info, read_bag
from visnav.bag.errors import RecordError
from visnav.cli import bag as cli_bag
from visnav.cli.main import main
from visnav.graph import Context, Node
from visnav.msgs import String, serialize


def _spawn(domain: int, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "bag", *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_record_stops_cleanly_on_sigterm(tmp_path: Path, domain: int) -> None:
    out = tmp_path / "rec"
    proc = _spawn(domain, "record", "-a", "-o", str(out))
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("Recording to")
        with Context(domain) as ctx:
            pub = Node("talker", context=ctx).create_publisher(String, "/chatter", 10)
            deadline = time.monotonic() + 5.0
            while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            time.sleep(0.1)
            for i in range(5):
                pub.publish(String(data=str(i)))
            time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        stdout, _ = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0
    assert "Recorded 5 messages on 1 topics" in stdout
    info = bag_info(out)
    assert info.complete
    assert [m.msg.data for m in read_bag(out)] == ["0", "1", "2", "3", "4"]


def test_play_reaches_another_process(tmp_path: Path, domain: int) -> None:
    with BagWriter(tmp_path / "b") as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        for i in range(10):
            w.write(t, 1_000_000_000 + i * 20_000_000, serialize(String(data=str(i))))
    with Context(domain) as ctx:
        got: list[str] = []
        Node("listener", context=ctx).create_subscription(
            String, "/echo", lambda m: got.append(m.data), 100
        )
        proc = _spawn(domain, "play", str(w.path), "--remap", "/chatter:=/echo", "--delay", "0.3")
        try:
            ctx.spin_until(lambda: len(got) == 10, 8.0)
            stdout, stderr = proc.communicate(timeout=10)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 0, stderr
    assert got == [str(i) for i in range(10)]
    assert "Published 10 messages on 1 topics" in stdout


def test_convert_and_reindex_verbs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with BagWriter(tmp_path / "b") as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        for i in range(3):
            w.write(t, 10 + i, serialize(String(data=str(i))))
    out = tmp_path / "b1"
    assert main(["bag", "convert", str(w.path), str(out), "--format", "ros1"]) == 0
    assert "Wrote 3 messages on 1 topics to" in capsys.readouterr().out
    assert [m.msg.data for m in read_bag(out.with_suffix(".bag"))] == ["0", "1", "2"]
    assert main(["bag", "reindex", str(out.with_suffix(".bag"))]) == 0
    assert "3 messages" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["-a", "/x"], "give the topics to record, or -a"),
        (["/x", "-x", "/y"], "-x/--exclude '/y' needs -a"),
        (["-a", "--buffsize", "0"], "--buffsize is 0.0 MiB: expected 1 to 1048576"),
    ],
)
def test_record_option_errors_are_record_errors(args: list[str], text: str) -> None:
    parser = argparse.ArgumentParser()
    cli_bag.add_arguments(parser)
    ns = parser.parse_args(["record", *args])
    with pytest.raises(RecordError, match=re.escape(text)):
        ns.func(ns)
