"""Helpers of the doctor tests: the clean synthetic car stream, fault injection, assertions."""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable
from types import SimpleNamespace
from typing import Any

import pytest

from visnav.doctor import Expectations, Finding, Report, Severity, diagnose
from visnav.doctor.observation import GraphSnapshot
from visnav.doctor.synthetic import CarStreamConfig, StreamEvent, car_stream, events_to_observation
from visnav.graph.graph_cache import EndpointInfo, NodeInfo

Events = list[StreamEvent]


def stream(**cfg: Any) -> Events:
    """The clean car stream (3 s, 64x48 images by default)."""
    return list(car_stream(CarStreamConfig(**cfg)))


def mutate(events: Iterable[StreamEvent], topic: str, fn: Callable[[Any, int], Any]) -> Events:
    """Replace each message of ``topic`` by ``fn(copy of msg, index)`` (None drops it)."""
    out: Events = []
    i = 0
    for ev in events:
        if ev.topic != topic:
            out.append(ev)
            continue
        msg = fn(copy.deepcopy(ev.msg), i)
        i += 1
        if msg is not None:
            out.append(ev._replace(msg=msg))
    return out


def retime(
    events: Iterable[StreamEvent], topic: str, fn: Callable[[int, int], int | None]
) -> Events:
    """Change the receive time of ``topic``'s messages: ``fn(receive_ns, index)`` (None drops)."""
    out: Events = []
    i = 0
    for ev in events:
        if ev.topic == topic:
            rx = fn(ev.receive_ns, i)
            i += 1
            if rx is None:
                continue
            out.append(ev._replace(receive_ns=rx))
        else:
            out.append(ev)
    return sorted(out, key=lambda e: e.receive_ns)


def drop(events: Iterable[StreamEvent], *topics: str) -> Events:
    return [e for e in events if e.topic not in topics]


def run(
    events: Iterable[StreamEvent],
    *,
    expect: dict[str, Any] | Expectations | None = None,
    fixed_frame: str | None = None,
    graph: GraphSnapshot | None = None,
    robot_description: str | None = None,
) -> Report:
    evs = list(events)
    if robot_description is not None:
        from visnav.msgs import String

        evs.insert(
            0,
            StreamEvent(
                "/robot_description",
                "std_msgs/msg/String",
                evs[0].receive_ns,
                String(data=robot_description),
            ),
        )
    obs = events_to_observation(evs, source="live" if graph else "bag", graph=graph)
    exp = Expectations.from_dict(expect) if isinstance(expect, dict) else expect
    return diagnose(obs, expect=exp, fixed_frame=fixed_frame)


def one(
    report: Report,
    check_id: str,
    *,
    subject: str | None = None,
    severity: Severity | None = None,
    **evidence: Any,
) -> Finding:
    """Assert ``report`` has a finding of ``check_id`` (with that evidence); return it."""
    found = report.find(check_id, subject)
    assert found, f"no {check_id} finding for {subject!r}:\n{report.format()}"
    for f in found:
        if severity is not None and f.severity is not severity:
            continue
        if all(f.evidence.get(k) == v for k, v in evidence.items()):
            return f
    raise AssertionError(
        f"{check_id} findings do not match severity={severity} evidence={evidence}:\n"
        + "\n".join(f"{f.severity} {f.evidence}" for f in found)
    )


def none_of(report: Report, *check_ids: str) -> None:
    for cid in check_ids:
        assert not report.find(cid), f"unexpected {cid}:\n{report.format()}"


def no_errors(report: Report) -> None:
    errors = report.by_severity(Severity.ERROR)
    assert not errors, report.format()


def endpoint(
    kind: str,
    topic: str,
    type_name: str,
    node: str,
    *,
    namespace: str = "/",
    reliability: str = "reliable",
    durability: str = "volatile",
    entity: int = 1,
) -> EndpointInfo:
    return EndpointInfo(
        kind, topic, type_name, node, namespace, reliability, durability, 10, "z1", 1, entity
    )


def graph(*endpoints: EndpointInfo) -> GraphSnapshot:
    nodes = {(e.node_name, e.node_namespace) for e in endpoints}
    return GraphSnapshot(tuple(NodeInfo(n, ns, "z1", 1) for n, ns in sorted(nodes)), endpoints)


def car_graph(*extra: EndpointInfo) -> GraphSnapshot:
    """Publishers of the clean car stream plus ``extra`` endpoints."""
    types = {e.topic: e.type_name for e in stream(duration_s=0.1)}
    pubs = [
        endpoint("publisher", t, ty, "sim", entity=i)
        for i, (t, ty) in enumerate(sorted(types.items()))
    ]
    return graph(*pubs, *extra)


@pytest.fixture
def dr() -> SimpleNamespace:
    """The helpers above (conftest helpers are shared through a fixture)."""
    return SimpleNamespace(
        stream=stream,
        mutate=mutate,
        retime=retime,
        drop=drop,
        run=run,
        one=one,
        none_of=none_of,
        no_errors=no_errors,
        endpoint=endpoint,
        graph=graph,
        car_graph=car_graph,
        S=Severity,
    )


@pytest.fixture(scope="session")
def clean_events() -> Events:
    return stream()
