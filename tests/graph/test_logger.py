"""Tests of the node logger's rclpy filters (once, throttle_duration_sec, skip_first)."""

from __future__ import annotations

import logging

import pytest

from visnav.graph import Context, Node
from visnav.graph.clock import Clock
from visnav.graph.errors import LoggerError
from visnav.graph.logger import NodeLogger


@pytest.fixture
def logger(caplog: pytest.LogCaptureFixture) -> NodeLogger:
    caplog.set_level(logging.DEBUG, logger="visnav.node")
    return NodeLogger("/test/logger")


def _messages(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name.startswith("visnav.node")]


def test_plain_calls_always_log(logger: NodeLogger, caplog: pytest.LogCaptureFixture) -> None:
    for i in range(3):
        assert logger.info(f"hello {i}") is True
    assert _messages(caplog) == [f"[/test/logger] hello {i}" for i in range(3)]


def test_once_logs_the_first_call_of_each_call_site(
    logger: NodeLogger, caplog: pytest.LogCaptureFixture
) -> None:
    logged = [logger.warning(f"a {i}", once=True) for i in range(4)]
    other = [logger.warning(f"b {i}", once=True) for i in range(2)]  # another call site
    assert logged == [True, False, False, False]
    assert other == [True, False]
    assert _messages(caplog) == ["[/test/logger] a 0", "[/test/logger] b 0"]


def test_helper_logging_for_callers_is_one_call_site(logger: NodeLogger) -> None:
    def report(text: str) -> bool:
        return logger.error(text, once=True)

    assert report("first") is True
    assert report("second kind") is False  # rclpy keys by the logger call, not the text


def test_throttle_follows_the_given_clock(
    logger: NodeLogger, caplog: pytest.LogCaptureFixture
) -> None:
    clock = Clock()
    clock.enable_sim_time()
    logged = []
    for t_ms in (0, 400, 999, 1000, 1500, 2100, 2200):
        clock.set_sim_time_ns(t_ms * 1_000_000)
        logged.append(
            logger.info(f"t={t_ms}", throttle_duration_sec=1.0, throttle_time_source_type=clock)
        )
    assert logged == [True, False, False, True, False, True, False]
    assert _messages(caplog) == [f"[/test/logger] t={t}" for t in (0, 1000, 2100)]


def test_throttle_default_clock_is_steady(logger: NodeLogger) -> None:
    results = [logger.debug("x", throttle_duration_sec=3600.0) for _ in range(3)]
    assert results == [True, False, False]


def test_skip_first_drops_only_the_first(logger: NodeLogger) -> None:
    assert [logger.info("x", skip_first=True) for _ in range(3)] == [False, True, True]


def test_filters_combine_in_rclpy_order(logger: NodeLogger) -> None:
    # skip_first then once: the first is skipped, the second logged, then nothing.
    assert [logger.info("x", skip_first=True, once=True) for _ in range(4)] == [
        False,
        True,
        False,
        False,
    ]


def test_disabled_level_logs_nothing_and_leaves_filters_untouched(
    logger: NodeLogger, caplog: pytest.LogCaptureFixture
) -> None:
    def call() -> bool:
        return logger.info("x", once=True)

    caplog.set_level(logging.WARNING, logger="visnav.node")
    assert logger.is_enabled_for(logging.INFO) is False
    assert call() is False  # the level is off: the once filter is not used up
    caplog.set_level(logging.DEBUG, logger="visnav.node")
    assert [call(), call()] == [True, False]


def test_a_call_site_keeps_its_filters(logger: NodeLogger) -> None:
    def call(*, once: bool) -> bool:
        return logger.info("x", once=once, skip_first=True)

    call(once=True)
    with pytest.raises(LoggerError, match="changed its level, filters"):
        call(once=False)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_throttle_duration_is_refused(logger: NodeLogger, bad: float) -> None:
    with pytest.raises(LoggerError, match="throttle_duration_sec is"):
        logger.warning("x", throttle_duration_sec=bad)


def test_time_source_without_duration_is_refused(logger: NodeLogger) -> None:
    with pytest.raises(LoggerError, match="without throttle_duration_sec"):
        logger.warning("x", throttle_time_source_type=Clock())


def test_error_logs_the_traceback(logger: NodeLogger, caplog: pytest.LogCaptureFixture) -> None:
    exc = RuntimeError("boom")
    try:
        raise exc
    except RuntimeError:
        logged = logger.error("failed", exc_info=exc, once=True)
    assert logged is True
    assert "RuntimeError: boom" in caplog.text


def test_node_logger_is_per_node(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="visnav.node")
    with Context(transport="local") as ctx:
        a = Node("a", namespace="/ns", context=ctx)
        b = Node("b", namespace="/ns", context=ctx)
        for node in (a, b, a):
            node.get_logger().warning("hi", once=True)
    assert _messages(caplog) == ["[/ns/a] hi", "[/ns/b] hi"]
    assert {r.name for r in caplog.records} == {"visnav.node.ns.a", "visnav.node.ns.b"}
