"""Topic checks: expected topics, dangling subscriptions (namespace slips), QoS, types."""

from __future__ import annotations

import difflib
from collections.abc import Iterator

from visnav.doctor.checks.rates import is_periodic
from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.graph.graph_cache import EndpointInfo
from visnav.graph.introspect import endpoint_qos
from visnav.graph.qos import check_qos_compatibility

__all__ = ["check_expected_topics", "check_graph_topics", "check_undecodable", "namespace_variants"]

# Infrastructure topics: their endpoints are not compared (or have their own checks).
INFRA_TOPICS = frozenset({"/rosout", "/parameter_events", "/clock", "/tf", "/tf_static"})


def _path(topic: str) -> list[str]:
    return [p for p in topic.split("/") if p]


def namespace_variants(topic: str, candidates: set[str]) -> list[str]:
    """Names of ``candidates`` that are ``topic`` under another namespace.

    ``/camera/depth/points`` and ``/drone/camera/depth/points`` are variants of each other:
    one name ends with the whole of the other.
    """
    mine = _path(topic)
    out = []
    for other in sorted(candidates):
        theirs = _path(other)
        if other == topic or not mine or not theirs:
            continue
        short, long_ = (mine, theirs) if len(mine) < len(theirs) else (theirs, mine)
        if len(short) < len(long_) and long_[-len(short) :] == short:
            out.append(other)
    return out


def _similar(topic: str, candidates: set[str]) -> list[str]:
    return difflib.get_close_matches(topic, sorted(candidates - {topic}), n=3, cutoff=0.6)


def _of_types(ctx: CheckContext, names: set[str], types: set[str]) -> set[str]:
    """The topics of ``names`` that carry one of ``types`` (all of them if ``types`` is empty).

    A suggested remap must lead to the subscriber's own type: a CameraInfo subscription
    remapped to an Image topic would fail with a type mismatch.
    """
    if not types:
        return names
    return {n for n in names if _observed_types(ctx, n) & types}


def _observed_types(ctx: CheckContext, topic: str) -> set[str]:
    types = {e.type_name for e in ctx.endpoints(topic, "publisher") if e.type_name}
    data = ctx.obs.topics.get(topic)
    if data is not None:
        types.add(data.type_name)
    return types


def _is_published(ctx: CheckContext, topic: str) -> bool:
    data = ctx.obs.topics.get(topic)
    if ctx.has_graph:
        return bool(ctx.endpoints(topic, "publisher")) or (data is not None and data.count > 0)
    return data is not None


def check_expected_topics(ctx: CheckContext) -> Iterator[Finding]:
    """``topics.expected_missing`` and ``topics.expected_type`` (from ``--expect``)."""
    if ctx.expect is None:
        return
    published = {t for t in ctx.all_topic_names() if _is_published(ctx, t)}
    for name, exp in ctx.expect.topics.items():
        if not _is_published(ctx, name):
            candidates = _of_types(ctx, published, {exp.type} if exp.type else set())
            variants = namespace_variants(name, candidates)
            similar = [s for s in _similar(name, candidates) if s not in variants]
            evidence: dict[str, object] = {"topic": name, "expected_type": exp.type or "any"}
            if variants:
                evidence["exists_under_other_namespace"] = variants
            if similar:
                evidence["similar_topics"] = similar
            fix = (
                f"start the node that publishes {name}"
                if not variants
                else f"the data are published as {variants[0]}: remap {name}:={variants[0]} "
                "or fix the publisher's namespace"
            )
            yield Finding(
                Severity.WARNING if exp.optional else Severity.ERROR,
                "topics.expected_missing",
                f"expected topic {name} is not published"
                + (f" (but {variants[0]} is)" if variants else ""),
                evidence,
                fix,
                name,
            )
            continue
        types = _observed_types(ctx, name)
        if exp.type and types and exp.type not in types:
            yield Finding(
                Severity.ERROR,
                "topics.expected_type",
                f"{name} carries {', '.join(sorted(types))}, expected {exp.type}",
                {"topic": name, "expected_type": exp.type, "observed_types": sorted(types)},
                f"publish {exp.type} on {name} (or correct the type in the expect file)",
                name,
            )


def _nodes(eps: list[EndpointInfo]) -> list[str]:
    return sorted({e.node_fqn for e in eps})


def _namespace_fix(topic: str, other: str, subs: list[EndpointInfo]) -> str:
    node = subs[0].node_fqn if subs else "the subscriber"
    if len(_path(other)) > len(_path(topic)):
        ns = other[: len(other) - len(topic)]
        return (
            f"the publisher lives in namespace {ns} while {node} subscribes to the absolute "
            f"name {topic}: remap {topic}:={other} on {node}, or start {node} in namespace "
            f"{ns} with a relative topic name"
        )
    ns = topic[: len(topic) - len(other)]
    rel = other.lstrip("/")
    return (
        f"{node} runs in namespace {ns} and resolved the relative name '{rel}' to {topic}, "
        f"but {other} is published at the root: subscribe to the absolute name {other} "
        f"or remap {rel}:={other}"
    )


def check_graph_topics(
    ctx: CheckContext, *, skip: frozenset[str] = frozenset()
) -> Iterator[Finding]:
    """Dangling subscriptions and publishers, namespace slips, QoS and type mismatches.

    Args:
        ctx: the check context.
        skip: topics other checks report (planner inputs), left out of
            ``topics.no_publisher``.
    """
    if not ctx.has_graph:
        return
    topics = sorted({e.topic for e in ctx.endpoints()})
    published = {t for t in topics if ctx.endpoints(t, "publisher")}
    unread: list[str] = []
    for topic in topics:
        pubs = ctx.endpoints(topic, "publisher")
        subs = ctx.endpoints(topic, "subscription")
        yield from _types(topic, pubs, subs)
        yield from _qos(topic, pubs, subs)
        if pubs and not subs and topic not in INFRA_TOPICS and "robot_description" not in topic:
            unread.append(topic)
        if subs and not pubs and topic not in INFRA_TOPICS:
            sub_types = {s.type_name for s in subs}
            variants = [
                v
                for v in namespace_variants(topic, published)
                if {e.type_name for e in ctx.endpoints(v, "publisher")} & sub_types
            ]
            if variants:
                other = variants[0]
                yield Finding(
                    Severity.ERROR,
                    "topics.namespace_mismatch",
                    f"subscriber waiting on {topic} while {other} exists",
                    {
                        "subscribed_topic": topic,
                        "subscribers": _nodes(subs),
                        "subscriber_namespaces": sorted({s.node_namespace for s in subs}),
                        "existing_topic": other,
                        "publishers": _nodes(ctx.endpoints(other, "publisher")),
                        "type": sorted(sub_types),
                    },
                    _namespace_fix(topic, other, subs),
                    topic,
                )
            elif topic not in skip:
                similar = _similar(topic, _of_types(ctx, published, sub_types))
                # an event input (a goal, an initial pose) has a publisher only while a
                # tool sends one (RViz's buttons, `visnav goal`, `visnav topic pub`)
                event = not similar and not any(is_periodic(ctx, topic, t) for t in sub_types)
                yield Finding(
                    Severity.INFO if event else Severity.WARNING,
                    "topics.no_publisher",
                    f"{topic} has subscribers but no publisher",
                    {
                        "topic": topic,
                        "subscribers": _nodes(subs),
                        "type": sorted(sub_types),
                        **({"similar_published_topics": similar} if similar else {}),
                    },
                    (
                        f"nothing to fix if {topic} carries events that a tool sends when "
                        "needed; otherwise start the node that publishes it"
                        if event
                        else f"start the node that publishes {topic}"
                        + (f", or remap the subscription to {similar[0]}" if similar else "")
                    ),
                    topic,
                )
    if unread:
        yield Finding(
            Severity.INFO,
            "topics.no_subscriber",
            f"{len(unread)} topic(s) published with no subscriber",
            {"topics": unread},
            "nothing to fix if they are only recorded or shown; otherwise check the consumer's "
            "topic names",
            "",
        )


def _types(topic: str, pubs: list[EndpointInfo], subs: list[EndpointInfo]) -> Iterator[Finding]:
    by_type: dict[str, list[str]] = {}
    for e in pubs + subs:
        by_type.setdefault(e.type_name, []).append(f"{e.kind} {e.node_fqn}")
    if len(by_type) > 1:
        yield Finding(
            Severity.ERROR,
            "topics.type_mismatch",
            f"{topic} is used with {len(by_type)} types: {', '.join(sorted(by_type))}",
            {"topic": topic, "endpoints_by_type": {k: sorted(v) for k, v in by_type.items()}},
            "make every publisher and subscription of the topic use one message type",
            topic,
        )


def _qos(topic: str, pubs: list[EndpointInfo], subs: list[EndpointInfo]) -> Iterator[Finding]:
    for sub in subs:
        for pub in pubs:
            if pub.type_name != sub.type_name:
                continue
            pq, sq = endpoint_qos(pub), endpoint_qos(sub)
            ok, reason = check_qos_compatibility(pq, sq)
            if ok:
                continue
            yield Finding(
                Severity.ERROR,
                "topics.qos_incompatible",
                f"{pub.node_fqn} cannot feed {sub.node_fqn} on {topic}: incompatible QoS",
                {
                    "topic": topic,
                    "publisher": pub.node_fqn,
                    "publisher_qos": pq.short(),
                    "subscriber": sub.node_fqn,
                    "subscriber_qos": sq.short(),
                    "reason": reason.split(";")[0],
                },
                reason.split(";", 1)[-1].strip(),
                topic,
            )


def check_undecodable(ctx: CheckContext) -> Iterator[Finding]:
    """``topics.undecodable``: topics doctor could not decode."""
    for topic, type_name in sorted(ctx.obs.undecodable.items()):
        yield Finding(
            Severity.INFO,
            "topics.undecodable",
            f"{topic} ({type_name}) was not checked: visnav does not know the type",
            {"topic": topic, "type": type_name},
            "nothing to fix; doctor checks standard message types only",
            topic,
        )
