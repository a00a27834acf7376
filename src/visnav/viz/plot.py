"""Scalar time series of message fields in the viewer (rqt_plot's job).

A field is named as rqt_plot names it: the topic then the field path,
``/odom/twist/twist/linear/x``; ``/imu/linear_acceleration/x:y:z`` plots three fields;
``/scan/ranges[0]`` indexes an array. The topic is the longest prefix of the name that
is a topic of the graph (rqt_plot resolves the same way). Each field becomes a
``Scalars`` entity ``plot/<topic>/<field>`` on the ``ros_time`` timeline (the header
stamp, else the receive time), shown in one time-series view.
"""

from __future__ import annotations

import re
import time
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from visnav.graph.node import Node
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import time_to_ns
from visnav.viz._rerun import rr
from visnav.viz.errors import VizError

__all__ = ["PlotField", "PlotFeed", "field_value", "resolve_fields"]

_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


@dataclass(frozen=True)
class PlotField:
    """One plotted field: its topic and the path inside the message."""

    topic: str
    path: tuple[str, ...]
    """Field names, an index as ``"[3]"``."""

    @property
    def entity(self) -> str:
        """The Rerun entity of the series."""
        parts = [rr.escape_entity_path_part(p) for p in self.topic.split("/") if p]
        parts += [rr.escape_entity_path_part(p) for p in self.path]
        return "/".join(["plot", *parts])

    @property
    def name(self) -> str:
        """rqt_plot's spelling of the field."""
        text = self.topic
        for part in self.path:
            text += part if part.startswith("[") else f"/{part}"
        return text


def _split_path(text: str, spec: str) -> tuple[str, ...]:
    out: list[str] = []
    for part in (p for p in text.split("/") if p):
        m = _PART.match(part)
        if m is None:
            msg = f"plot field {spec!r}: {part!r} is not a field name (name or name[INDEX])"
            raise VizError(msg)
        out.append(m.group(1))
        if m.group(2) is not None:
            out.append(f"[{m.group(2)}]")
    return tuple(out)


def resolve_fields(spec: str, topics: Collection[str]) -> list[PlotField]:
    """Split an rqt_plot name into fields of one of ``topics`` (longest topic prefix).

    Raises:
        VizError: no topic is a prefix (the message lists the topics), no field given,
            or a malformed field name.
    """
    name = spec if spec.startswith("/") else "/" + spec
    head, _, tail = name.rpartition("/")
    alternatives = tail.split(":") if ":" in tail else [tail]
    base = head + "/" + alternatives[0]
    best = max((t for t in topics if base.startswith(t.rstrip("/") + "/")), key=len, default=None)
    if best is None:
        shown = ", ".join(sorted(topics)[:15]) or "none"
        msg = (
            f"plot field {spec!r}: no topic of the graph is a prefix of it (topics: {shown}); "
            "write it as /TOPIC/FIELD/..., e.g. /odom/twist/twist/linear/x"
        )
        raise VizError(msg)
    prefix = head[len(best.rstrip("/")) :]
    fields = []
    for alt in alternatives:
        path = _split_path(f"{prefix}/{alt}", spec)
        if not path:
            msg = f"plot field {spec!r}: no field after topic {best}: add one, e.g. {best}/x"
            raise VizError(msg)
        fields.append(PlotField(best, path))
    return fields


def field_value(msg: Any, path: Sequence[str]) -> list[float]:
    """The numbers at ``path`` in ``msg`` (a number, a bool, or an array of numbers).

    Raises:
        VizError: a missing field, an index out of range, or a value that is not numeric.
    """
    value = msg
    for part in path:
        if part.startswith("["):
            index = int(part[1:-1])
            try:
                value = value[index]
            except (IndexError, TypeError, KeyError):
                msg_ = f"index {index} is out of range or the field is not an array"
                raise VizError(msg_) from None
        else:
            if not hasattr(value, part):
                fields = [f for f in getattr(value, "__dataclass_fields__", {}) if f]
                msg_ = f"no field {part!r} (fields here: {', '.join(fields) or 'none'})"
                raise VizError(msg_)
            value = getattr(value, part)
    if isinstance(value, (bool, int, float, np.integer, np.floating)):
        return [float(value)]
    array = np.asarray(value)
    if array.dtype.kind in "biuf" and array.ndim == 1:
        return [float(v) for v in array]
    msg_ = f"the value is a {type(value).__name__}, not a number: name a numeric field below it"
    raise VizError(msg_)


class PlotFeed:
    """Subscribes to the topics of ``fields`` and logs their values as scalar series.

    Args:
        recording: the ``rerun.RecordingStream``.
        node: the node that subscribes.
        specs: rqt_plot field names.
        timeline: the timeline of the stamps.
    """

    def __init__(
        self, recording: Any, node: Node, specs: Sequence[str], *, timeline: str = "ros_time"
    ) -> None:
        self.recording = recording
        self.node = node
        self.specs = list(specs)
        self.timeline = timeline
        self.fields: list[PlotField] = []
        self.counts: dict[str, int] = {}
        self.errors: dict[str, str] = {}
        self._subs: dict[str, Any] = {}

    def blueprint(self) -> Any:
        """A blueprint with one time-series view of every series."""
        import rerun.blueprint as rrb  # noqa: PLC0415 (the optional SDK)

        return rrb.Blueprint(rrb.TimeSeriesView(origin="/plot", name="plot"), collapse_panels=True)

    def resolve(self, *, wait_s: float = 5.0) -> list[PlotField]:
        """Wait up to ``wait_s`` for the topics, resolve every spec, subscribe.

        Raises:
            VizError: a spec that names no topic of the graph or a bad field.
        """
        deadline = time.monotonic() + wait_s
        while True:
            types = dict(self.node.get_topic_names_and_types())
            try:
                resolved = [f for spec in self.specs for f in resolve_fields(spec, types)]
                break
            except VizError:
                if time.monotonic() >= deadline:
                    raise
                self.node.context.spin_once(0.2)
        self.fields = resolved
        for topic in dict.fromkeys(f.topic for f in resolved):
            type_names = types[topic]
            if len(type_names) != 1:
                msg = f"topic {topic} has several types {type_names}: cannot plot it"
                raise VizError(msg)
            self._subscribe(topic, type_names[0])
        self.recording.send_blueprint(self.blueprint())
        return resolved

    def _subscribe(self, topic: str, type_name: str) -> None:
        fields = [f for f in self.fields if f.topic == topic]

        def on_msg(msg: Any) -> None:
            header = getattr(msg, "header", None)
            t = time_to_ns(header.stamp) if header is not None else 0
            if t <= 0:
                t = self.node.get_clock().now_ns()
            self.recording.set_time(self.timeline, timestamp=np.datetime64(t, "ns"))
            for field in fields:
                try:
                    values = field_value(msg, field.path)
                except VizError as exc:
                    if field.name not in self.errors:
                        self.errors[field.name] = str(exc)
                        self.node.get_logger().warning(f"plot {field.name}: {exc}")
                    continue
                self.recording.log(field.entity, rr.Scalars(values))
                self.counts[field.name] = self.counts.get(field.name, 0) + 1

        self._subs[topic] = self.node.create_subscription(
            get_message_class(type_name), topic, on_msg, 10
        )

    def close(self) -> None:
        """Unsubscribe."""
        for sub in self._subs.values():
            self.node.destroy_subscription(sub)
        self._subs.clear()
