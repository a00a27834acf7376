"""``--expect EXPECT.yaml``: what the system should look like (schema in ``docs/doctor.md``).

Example::

    fixed_frame: odom               # the frame consumers transform data into
    use_sim_time: true              # nodes run on /clock
    topics:
      /camera/image_raw: {type: sensor_msgs/msg/Image, rate: 30, frame_id: camera_optical_frame,
                          encoding: rgb8}
      /camera/camera_info: {hfov: 1.396}
      /depth_camera/depth/image_raw: {depth_unit: m}   # what the consumer expects
    tf_chains:
      - [odom, camera_optical_frame]
    planner:
      horizon: 7.5
      inputs: [/depth_camera/points, /odom]

Every key is optional. Unknown keys and wrong value types raise :class:`ExpectError`
naming the file, the key path, the value and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

from visnav.doctor.errors import ExpectError
from visnav.safe_yaml import load_yaml_file

__all__ = [
    "Expectations",
    "KnownColor",
    "PlannerExpectation",
    "TopicExpectation",
    "load_expectations",
]

_DEPTH_UNITS = ("m", "mm")


@dataclass(frozen=True)
class KnownColor:
    """A region of the image whose true colour is known (for the RGB/BGR swap check).

    Attributes:
        region: ``(x0, y0, x1, y1)`` as fractions of the width and height.
        rgb: the colour it shows, 0-255 in R, G, B order.
    """

    region: tuple[float, float, float, float]
    rgb: tuple[float, float, float]


@dataclass(frozen=True)
class TopicExpectation:
    """What one topic should carry (every field optional).

    Attributes:
        name: topic name.
        type: ROS 2 type name.
        rate: declared rate in Hz.
        rate_tolerance: allowed relative rate error (default 0.15).
        frame_id: the header frame_id.
        encoding: image encoding.
        hfov: horizontal field of view in radians (camera_info / image topics).
        depth_unit: what the consumer of a depth image expects: ``m`` (32FC1 metres)
            or ``mm`` (16UC1 millimetres).
        clip_far: sensor range in metres (depth, cloud, scan).
        optional: a missing topic is a warning, not an error.
        known_color: a region of known colour (RGB/BGR check).
        rectify: a consumer rectifies this camera (distortion must be known).
    """

    name: str
    type: str | None = None
    rate: float | None = None
    rate_tolerance: float = 0.15
    frame_id: str | None = None
    encoding: str | None = None
    hfov: float | None = None
    depth_unit: str | None = None
    clip_far: float | None = None
    optional: bool = False
    known_color: KnownColor | None = None
    rectify: bool = False


@dataclass(frozen=True)
class PlannerExpectation:
    """The planner's inputs and reach.

    Attributes:
        horizon: how far ahead the planner plans, metres.
        inputs: topics the planner subscribes to; each must be published.
        sensors: cloud / scan / depth topics that must cover the region ahead
            (default: the inputs of those types).
        base_frame: the vehicle frame whose +x is "ahead" (default: the odometry child frame).
    """

    horizon: float | None = None
    inputs: tuple[str, ...] = ()
    sensors: tuple[str, ...] = ()
    base_frame: str | None = None


@dataclass(frozen=True)
class Expectations:
    """Everything ``--expect`` declares.

    Attributes:
        topics: per topic expectations.
        tf_chains: ``(target, source)`` frame pairs that must resolve.
        fixed_frame: the frame consumers transform data into (planning / fixed frame).
        use_sim_time: True if nodes run on ``/clock``.
        planner: planner inputs and horizon.
        source: the file the expectations came from.
    """

    topics: Mapping[str, TopicExpectation] = field(default_factory=dict)
    tf_chains: tuple[tuple[str, str], ...] = ()
    fixed_frame: str | None = None
    use_sim_time: bool | None = None
    planner: PlannerExpectation | None = None
    source: str = "<expect>"

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str = "<expect>") -> Expectations:
        """Validate and convert a parsed YAML mapping.

        Raises:
            ExpectError: an unknown key or a value of the wrong type.
        """
        p = _Parser(source)
        p.keys(data, "", ("topics", "tf_chains", "fixed_frame", "use_sim_time", "planner"))
        topics = {}
        raw_topics = p.mapping(data.get("topics", {}), "topics")
        for name, spec in raw_topics.items():
            topic = p.topic_name(name, "topics")
            topics[topic] = p.topic(topic, spec)
        chains = []
        for i, chain in enumerate(p.sequence(data.get("tf_chains", []), "tf_chains")):
            where = f"tf_chains[{i}]"
            pair = p.sequence(chain, where)
            if len(pair) != 2:
                p.fail(where, chain, "a pair [target_frame, source_frame]")
            chains.append((p.frame(pair[0], where), p.frame(pair[1], where)))
        fixed = data.get("fixed_frame")
        planner = None
        if data.get("planner") is not None:
            planner = p.planner(data["planner"])
        return cls(
            topics=topics,
            tf_chains=tuple(chains),
            fixed_frame=None if fixed is None else p.frame(fixed, "fixed_frame"),
            use_sim_time=p.opt_bool(data.get("use_sim_time"), "use_sim_time"),
            planner=planner,
            source=source,
        )


class _Parser:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, value: Any, expected: str) -> NoReturn:
        msg = f"{self.source}: {where or 'the document'} is {value!r}: expected {expected}"
        raise ExpectError(msg)

    def keys(self, data: Any, where: str, allowed: tuple[str, ...]) -> None:
        if not isinstance(data, Mapping):
            self.fail(where, data, "a mapping")
        for key in data:
            if key not in allowed:
                path = f"{where}.{key}" if where else str(key)
                msg = (
                    f"{self.source}: unknown key '{path}': expected one of {', '.join(allowed)} "
                    "(see docs/doctor.md)"
                )
                raise ExpectError(msg)

    def mapping(self, value: Any, where: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            self.fail(where, value, "a mapping")
        return value

    def sequence(self, value: Any, where: str) -> list[Any]:
        if not isinstance(value, list | tuple):
            self.fail(where, value, "a list")
        return list(value)

    def number(self, value: Any, where: str, *, positive: bool = True) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(where, value, "a number")
        out = float(value)
        if not math.isfinite(out) or (positive and out <= 0):
            self.fail(where, value, "a finite number > 0")
        return out

    def opt_number(self, value: Any, where: str) -> float | None:
        return None if value is None else self.number(value, where)

    def opt_bool(self, value: Any, where: str) -> bool | None:
        if value is None:
            return None
        if not isinstance(value, bool):
            self.fail(where, value, "true or false")
        return bool(value)

    def text(self, value: Any, where: str) -> str:
        if not isinstance(value, str) or not value:
            self.fail(where, value, "a non-empty string")
        return str(value)

    def topic_name(self, value: Any, where: str) -> str:
        name = self.text(value, where)
        if not name.startswith("/"):
            self.fail(f"{where}.{name}", name, "a fully qualified topic name starting with '/'")
        return name

    def frame(self, value: Any, where: str) -> str:
        frame = self.text(value, where)
        if frame.startswith("/"):
            self.fail(where, frame, f"a frame id without a leading '/' ('{frame.lstrip('/')}')")
        return frame

    def topic(self, name: str, spec: Any) -> TopicExpectation:
        where = f"topics.{name}"
        if spec is None:
            return TopicExpectation(name)
        allowed = tuple(f for f in TopicExpectation.__dataclass_fields__ if f != "name")
        self.keys(spec, where, allowed)
        unit = spec.get("depth_unit")
        if unit is not None and unit not in _DEPTH_UNITS:
            self.fail(f"{where}.depth_unit", unit, "'m' (32FC1 metres) or 'mm' (16UC1)")
        hfov = self.opt_number(spec.get("hfov"), f"{where}.hfov")
        if hfov is not None and hfov >= math.pi:
            self.fail(f"{where}.hfov", hfov, "radians in (0, pi)")
        known = None
        if spec.get("known_color") is not None:
            known = self.known_color(spec["known_color"], f"{where}.known_color")
        tol = spec.get("rate_tolerance", 0.15)
        return TopicExpectation(
            name=name,
            type=None if spec.get("type") is None else self.text(spec["type"], f"{where}.type"),
            rate=self.opt_number(spec.get("rate"), f"{where}.rate"),
            rate_tolerance=self.number(tol, f"{where}.rate_tolerance"),
            frame_id=None
            if spec.get("frame_id") is None
            else self.frame(spec["frame_id"], f"{where}.frame_id"),
            encoding=None
            if spec.get("encoding") is None
            else self.text(spec["encoding"], f"{where}.encoding"),
            hfov=hfov,
            depth_unit=unit,
            clip_far=self.opt_number(spec.get("clip_far"), f"{where}.clip_far"),
            optional=bool(self.opt_bool(spec.get("optional"), f"{where}.optional")),
            known_color=known,
            rectify=bool(self.opt_bool(spec.get("rectify"), f"{where}.rectify")),
        )

    def known_color(self, spec: Any, where: str) -> KnownColor:
        self.keys(spec, where, ("region", "rgb"))
        region = self.sequence(spec.get("region"), f"{where}.region")
        rgb = self.sequence(spec.get("rgb"), f"{where}.rgb")
        if len(region) != 4 or not all(isinstance(v, int | float) and 0 <= v <= 1 for v in region):
            self.fail(f"{where}.region", region, "[x0, y0, x1, y1] fractions in [0, 1]")
        if region[2] <= region[0] or region[3] <= region[1]:
            self.fail(f"{where}.region", region, "x1 > x0 and y1 > y0")
        if len(rgb) != 3 or not all(isinstance(v, int | float) and 0 <= v <= 255 for v in rgb):
            self.fail(f"{where}.rgb", rgb, "[r, g, b] in 0-255")
        x0, y0, x1, y1 = (float(v) for v in region)
        r, g, b = (float(v) for v in rgb)
        return KnownColor((x0, y0, x1, y1), (r, g, b))

    def planner(self, spec: Any) -> PlannerExpectation:
        self.keys(spec, "planner", ("horizon", "inputs", "sensors", "base_frame"))
        inputs = self.sequence(spec.get("inputs", []), "planner.inputs")
        sensors = self.sequence(spec.get("sensors", []), "planner.sensors")
        base = spec.get("base_frame")
        return PlannerExpectation(
            horizon=self.opt_number(spec.get("horizon"), "planner.horizon"),
            inputs=tuple(self.topic_name(t, "planner.inputs") for t in inputs),
            sensors=tuple(self.topic_name(t, "planner.sensors") for t in sensors),
            base_frame=None if base is None else self.frame(base, "planner.base_frame"),
        )


def load_expectations(path: str | Path) -> Expectations:
    """Read an ``--expect`` YAML file.

    Raises:
        ExpectError: the file is missing, not YAML, or does not follow the schema.
    """
    p = Path(path)
    data = load_yaml_file(p, what="the --expect file", error=ExpectError)
    return Expectations.from_dict(data or {}, source=str(p))
