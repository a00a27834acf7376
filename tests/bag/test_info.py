"""``bag info`` numbers on bags with known contents, and the CLI's text/JSON output."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from visnav.bag import BagWriter, bag_info, format_info
from visnav.cli.main import main
from visnav.msgs import String, serialize

S = 1_000_000_000


@pytest.fixture(params=["mcap", "ros1", "sqlite3"])
def known_bag(tmp_path: Path, request: pytest.FixtureRequest) -> Path:
    """/a: 11 messages at 10 Hz from t=100 s; /b: 3 messages at 0.5 Hz from t=101 s."""
    with BagWriter(tmp_path / "known", fmt=request.param) as w:
        a = w.add_topic("/a", "std_msgs/msg/String")
        b = w.add_topic("/b", "std_msgs/msg/String")
        for i in range(11):
            w.write(a, 100 * S + i * S // 10, serialize(String(data="x" * i)))
        for i in range(3):
            w.write(b, 101 * S + 2 * i * S, serialize(String(data="yy")))
    return w.path


def test_info_numbers(known_bag: Path) -> None:
    info = bag_info(known_bag)
    assert info.complete
    assert info.message_count == 14
    assert info.start_ns == 100 * S
    assert info.end_ns == 105 * S
    assert info.duration_ns == 5 * S
    a, b = info.topic("/a"), info.topic("/b")
    assert (a.type_name, a.count, b.count) == ("std_msgs/msg/String", 11, 3)
    assert a.frequency_hz == pytest.approx(10.0)
    assert b.frequency_hz == pytest.approx(0.5)
    assert (a.first_ns, a.last_ns) == (100 * S, 101 * S)
    # CDR String: 4 encapsulation + 4 length + text + NUL, padded; ROS 1: 4 length + text.
    if info.storage == "ros1":
        assert a.size_bytes == sum(4 + i for i in range(11))
    else:
        assert a.size_bytes == sum(len(serialize(String(data="x" * i))) for i in range(11))
    assert info.size_bytes > a.size_bytes + b.size_bytes


def test_info_text_and_json(known_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = format_info(bag_info(known_bag))
    assert "Duration:          5.000s" in text
    assert "Messages:          14" in text
    assert "Topic: /a | Type: std_msgs/msg/String | Count: 11 | Frequency:    10.00 Hz" in text
    assert main(["bag", "info", str(known_bag), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["topics"]["/b"]["count"] == 3
    assert data["duration_s"] == 5.0


def test_info_empty_bag(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "empty") as w:
        w.add_topic("/a", "std_msgs/msg/String")
    info = bag_info(w.path)
    assert (info.message_count, info.duration_ns, info.topic("/a").count) == (0, 0, 0)
    assert "Messages:          0" in format_info(info)
