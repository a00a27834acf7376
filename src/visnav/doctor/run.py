"""Run doctor: observe (live graph or bag), run every check, return the report."""

from __future__ import annotations

from pathlib import Path

from visnav.doctor.bag_source import observe_bag
from visnav.doctor.builder import SamplingPolicy
from visnav.doctor.catalogue import CATALOGUE
from visnav.doctor.checks import run_checks
from visnav.doctor.context import CheckContext
from visnav.doctor.errors import DoctorError
from visnav.doctor.expect import Expectations
from visnav.doctor.findings import Report
from visnav.doctor.live import observe_live
from visnav.doctor.observation import Observation
from visnav.graph.context import Context

__all__ = ["diagnose", "doctor_bag", "doctor_live"]


def diagnose(
    observation: Observation,
    *,
    expect: Expectations | None = None,
    fixed_frame: str | None = None,
) -> Report:
    """Run every check on an observation.

    Args:
        observation: from :func:`~visnav.doctor.live.observe_live`,
            :func:`~visnav.doctor.bag_source.observe_bag` or built by hand.
        expect: declarations from ``--expect``.
        fixed_frame: the frame consumers transform data into (``--fixed-frame``).

    Returns:
        The report (``report.has_errors`` decides the exit code).
    """
    ctx = CheckContext(observation, expect=expect, fixed_frame=fixed_frame)
    findings = list(run_checks(ctx))
    skipped = {}
    if observation.graph is None:
        skipped = {
            cid: "needs the live graph (a bag records no subscriptions)"
            for cid, info in CATALOGUE.items()
            if info.needs_graph
        }
    messages = sum(t.count for t in observation.topics.values())
    summary: dict[str, object] = {
        "duration_s": round(observation.duration_s, 3),
        "topics": len(observation.topics),
        "messages": messages,
        "tf_transforms": len(observation.tf),
    }
    if observation.graph is not None:
        summary["nodes"] = len(observation.graph.nodes)
    if ctx.fixed_frame:
        summary["fixed_frame"] = ctx.fixed_frame
    return Report.build(findings, source=observation.label, summary=summary, skipped=skipped)


def doctor_live(
    *,
    context: Context | None = None,
    domain: str | int | None = None,
    duration_s: float = 5.0,
    expect: Expectations | None = None,
    fixed_frame: str | None = None,
    policy: SamplingPolicy | None = None,
) -> Report:
    """Listen to a live graph for ``duration_s`` seconds and diagnose it.

    Raises:
        DoctorError: the graph has no topic at all (nothing runs in this domain): there is
            nothing to diagnose, and "no findings" would read as a healthy system.
    """
    obs = observe_live(context=context, domain=domain, duration_s=duration_s, policy=policy)
    if not obs.topics and (obs.graph is None or not obs.graph.topics()):
        where = obs.label.removeprefix("live graph, ")
        msg = (
            f"no topics in graph {where}: is anything running, in this VISNAV_DOMAIN? "
            "Fix: start the system, or look in its domain (VISNAV_DOMAIN=N visnav doctor, "
            "or visnav --domain N doctor)"
        )
        raise DoctorError(msg)
    return diagnose(obs, expect=expect, fixed_frame=fixed_frame)


def doctor_bag(
    path: str | Path,
    *,
    duration_s: float | None = None,
    expect: Expectations | None = None,
    fixed_frame: str | None = None,
    policy: SamplingPolicy | None = None,
) -> Report:
    """Read a bag and diagnose it."""
    obs = observe_bag(path, duration_s=duration_s, policy=policy)
    return diagnose(obs, expect=expect, fixed_frame=fixed_frame)
