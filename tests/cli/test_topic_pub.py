"""``visnav topic pub``: waiting for matching subscriptions as ``ros2 topic pub`` does.

``-1``/``--times`` wait for one subscription of the message type (``-w N`` for N) with no
time limit unless ``--max-wait-time-secs S`` is given; when S passes the CLI exits 1 with
one stderr line naming the topic and the count it saw.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.cli.main import main
from visnav.cli.topic import (
    SubscriptionWaitTimeoutError,
    _non_negative_int,
    _positive_float,
    matching_subscription_count,
    wait_for_matching_subscriptions,
)
from visnav.graph import Context, Node
from visnav.msgs import String, Twist


def _start_pub(domain: int, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "topic", "pub", *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.slow
@pytest.mark.ci
def test_pub_once_waits_for_a_subscriber_that_starts_6_s_later(domain: int) -> None:
    proc = _start_pub(domain, "-1", "/late", "std_msgs/msg/String", "{data: late hello}")
    try:
        started = time.monotonic()
        while time.monotonic() - started < 6.5:  # the old limit was 5 s, then it published
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.1)
        got: list[Any] = []
        with Context(domain) as ctx:
            node = Node("late_listener", context=ctx)
            node.create_subscription(String, "/late", got.append, 10)
            assert ctx.spin_until(lambda: bool(got), 30.0), "the one message never arrived"
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert [m.data for m in got] == ["late hello"]
    assert "waiting for 1 matching subscription(s) on '/late' (std_msgs/msg/String)" in out
    assert "publishing #1" in out


@pytest.mark.slow
def test_pub_gives_up_after_max_wait_time_secs_with_one_stderr_line(domain: int) -> None:
    proc = _start_pub(
        domain, "-1", "/nobody", "std_msgs/msg/String", "{data: x}", "--max-wait-time-secs", "1"
    )
    try:
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 1
    assert err.strip().splitlines() == [
        "error: topic '/nobody': 0 of 1 matching subscription(s) (std_msgs/msg/String) after "
        "waiting 1 s (--max-wait-time-secs); start the subscriber first, wait longer, or lower "
        "--wait-matching-subscriptions"
    ]
    assert "publishing" not in out


def test_only_subscriptions_of_the_message_type_are_counted(domain: int) -> None:
    got: list[Any] = []
    with Context(domain) as pub_ctx, Context(domain) as int_ctx, Context(domain) as str_ctx:
        pub = Node("talker", context=pub_ctx).create_publisher(String, "/mixed", 10)
        Node("ints", context=int_ctx).create_subscription(Twist, "/mixed", lambda _m: None, 10)
        assert pub_ctx.spin_until(lambda: pub.get_subscription_count() == 1, 20.0)
        assert matching_subscription_count(pub) == 0  # a Twist subscription never receives
        with pytest.raises(SubscriptionWaitTimeoutError, match=r"'/mixed': 0 of 1 matching"):
            wait_for_matching_subscriptions(pub, 1, max_wait_s=0.3)
        Node("strings", context=str_ctx).create_subscription(String, "/mixed", got.append, 10)
        assert wait_for_matching_subscriptions(pub, 1, max_wait_s=20.0) == 1
        pub.publish(String(data="now"))  # at once: the sample must not be skipped
        assert str_ctx.spin_until(lambda: bool(got), 10.0)
    assert [m.data for m in got] == ["now"]


def test_wait_for_zero_subscriptions_returns_at_once() -> None:
    with Context(transport="local") as ctx:
        pub = Node("n", context=ctx).create_publisher(String, "/t", 10)
        started = time.monotonic()
        assert wait_for_matching_subscriptions(pub, 0, max_wait_s=5.0) == 0
        assert time.monotonic() - started < 0.5


def test_max_wait_without_anything_to_wait_for_is_refused(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = main(
        ["topic", "pub", "-w", "0", "/t", "std_msgs/msg/String", "--max-wait-time-secs", "2"]
    )
    err = capsys.readouterr().err
    assert code == 1
    assert err.strip().splitlines() == [
        "error: --max-wait-time-secs 2: nothing to wait for; add --wait-matching-subscriptions "
        "N, --once or --times N, or drop the option"
    ]


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--max-wait-time-secs", "0"], "argument --max-wait-time-secs: '0' is not a positive"),
        (["--max-wait-time-secs", "nan"], "'nan' is not a positive number"),
        (
            ["--wait-matching-subscriptions=-1"],
            "argument -w/--wait-matching-subscriptions: '-1' is not a whole number",
        ),
        (["-r", "0"], "argument -r/--rate: '0' is not a positive number"),
        (["-1", "-t", "3"], "argument -t/--times: not allowed with argument -1/--once"),
        (["--keep-alive", "x"], "argument --keep-alive: 'x' is not a positive number"),
    ],
)
def test_bad_pub_options_are_refused_by_the_parser(
    capsys: pytest.CaptureFixture[str], args: list[str], match: str
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["topic", "pub", "/t", "std_msgs/msg/String", *args])
    assert info.value.code == 2
    assert match in capsys.readouterr().err


_NUMBERS = st.sampled_from(["inf", "-inf", "1e309", "nan", "0", "-0", "0x1", "1_0", "9" * 5000])


@settings(deadline=None)
@given(st.one_of(st.text(max_size=30), _NUMBERS))
def test_number_options_give_a_number_or_argparse_error(text: str) -> None:
    for parse in (_positive_float, _non_negative_int):
        try:
            value = parse(text)
        except argparse.ArgumentTypeError as exc:
            message = str(exc)
        else:
            message = ""
            assert value >= 0
            assert value > 0 or parse is _non_negative_int
            assert value < float("inf")
        assert not message or repr(text) in message
