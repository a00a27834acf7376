"""The checks, one module per category; :func:`run_checks` runs them all on a context."""

from __future__ import annotations

from collections.abc import Iterator

from visnav.doctor.checks.camera_info import check_camera_info
from visnav.doctor.checks.description import check_declared_sensors
from visnav.doctor.checks.frames import check_frame_conventions, check_frame_ids, check_odometry
from visnav.doctor.checks.images import check_images
from visnav.doctor.checks.planner import check_planner, planner_input_topics
from visnav.doctor.checks.rates import check_no_messages, check_rates
from visnav.doctor.checks.timing import check_sim_time, check_stamps
from visnav.doctor.checks.topics import (
    check_expected_topics,
    check_graph_topics,
    check_undecodable,
)
from visnav.doctor.checks.transforms import check_tf_chains, check_tf_structure, check_tf_timing
from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding

__all__ = ["run_checks"]


def run_checks(ctx: CheckContext) -> Iterator[Finding]:
    """Run every check on ``ctx`` (graph checks yield nothing without a graph)."""
    planner_inputs = planner_input_topics(ctx)
    yield from check_expected_topics(ctx)
    yield from check_graph_topics(ctx, skip=planner_inputs)
    yield from check_undecodable(ctx)
    yield from check_declared_sensors(ctx)
    yield from check_no_messages(ctx, skip=planner_inputs)
    yield from check_rates(ctx)
    yield from check_images(ctx)
    yield from check_camera_info(ctx)
    yield from check_tf_structure(ctx)
    yield from check_tf_timing(ctx)
    yield from check_tf_chains(ctx)
    yield from check_sim_time(ctx)
    yield from check_stamps(ctx)
    yield from check_frame_conventions(ctx)
    yield from check_odometry(ctx)
    yield from check_frame_ids(ctx)
    yield from check_planner(ctx)
