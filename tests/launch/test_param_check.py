"""An unknown parameter's warning names the parameter that does the job (meaning, then spelling)."""

from __future__ import annotations

import logging

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.launch.param_check import meaning, report_unknown_parameters, unknown_parameters

DECLARED = [
    "frame_name",
    "odometry_topic",
    "base_frame",
    "cloud_topic",
    "publish_frequency",
    "max_depth",
    "global_frame",
    "grid_map.odom_topic",
    "scan_topic",
]


@pytest.mark.parametrize(
    ("given_name", "expected"),
    [
        ("frameName", "frame_name"),  # gazebo_ros ROS 1 camelCase vs ROS 2 snake_case
        ("publishFrequency", "publish_frequency"),
        ("maxDepth", "max_depth"),
        ("odom_topic", "odometry_topic"),  # ROS's odom / odometry
        ("base_frame_id", "base_frame"),  # amcl's base_frame_id
        ("topics.cloud", "cloud_topic"),  # a topic as a nested key
        ("topics/scan", "scan_topic"),
        ("grid_map.odometry_topic", "grid_map.odom_topic"),
        ("global_fame", "global_frame"),  # spelling when no meaning matches
        ("completely_unrelated", None),
    ],
)
def test_suggestion(given_name: str, expected: str | None) -> None:
    assert unknown_parameters({given_name: 1}, DECLARED) == [(given_name, expected)]


def test_declared_and_use_sim_time_are_known() -> None:
    assert unknown_parameters({"frame_name": 1, "use_sim_time": True}, DECLARED) == []


def test_two_declared_with_one_meaning_fall_back_to_spelling() -> None:
    # frame_id and frame_name mean the same: spelling decides between them
    got = unknown_parameters({"frameId": "x"}, ["frame_id", "frame_name", "rate"])
    assert got == [("frameId", "frame_id")]


def test_the_warning_line(caplog: pytest.LogCaptureFixture) -> None:
    class _Node:
        parameters = dict.fromkeys(DECLARED, 0)

        def get_fully_qualified_name(self) -> str:
            return "/camera"

    with caplog.at_level(logging.WARNING, logger="visnav.launch"):
        lines = report_unknown_parameters(
            _Node(), {"frameName": "cam"}, where="a.launch:3", executable="x"
        )
    assert lines == [
        "a.launch:3: node /camera [x] has no parameter 'frameName'; did you mean 'frame_name'? "
        "(the value 'cam' is not applied)"
    ]
    assert caplog.records[0].levelno == logging.WARNING


_words = st.lists(st.sampled_from(["frame", "base", "scan", "topic", "rate", "map"]), min_size=1)


@given(_words)
def test_meaning_ignores_spelling(words: list[str]) -> None:
    snake = "_".join(words)
    camel = words[0] + "".join(w.capitalize() for w in words[1:])
    dotted = ".".join(words)
    assert meaning(snake) == meaning(camel) == meaning(dotted) == frozenset(words)
