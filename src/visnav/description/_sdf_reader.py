"""Typed, located access to SDF-style elements of ``<gazebo>`` blocks (internal)."""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence

from visnav.description.gazebo_specs import GaussianNoise, RosNodeNames, normalize_namespace
from visnav.description.urdf import Origin, RobotDescriptionError, XmlDoc

__all__ = ["SdfReader", "has_any", "plugin_node"]

_LOG = logging.getLogger("visnav.description.gazebo")


class SdfReader:
    """Typed access to SDF-style child elements with located errors and warnings."""

    def __init__(self, doc: XmlDoc) -> None:
        self.doc = doc
        self.warnings: list[str] = []

    def warn(self, element: ET.Element, text: str) -> None:
        """Record ``"file:line: <tag>: text"`` about ``element`` (where it was written).

        Kept in :attr:`warnings`; :func:`visnav.description.robot.load_robot` logs one
        grouped summary of them (:mod:`visnav.description.warning_summary`), which puts
        an ignored ``<sensor>`` / ``<plugin>`` ("... is ignored", "nothing is
        published") first.
        """
        message = f"{self.doc.where(element)}: <{element.tag}>: {text}"
        self.warnings.append(message)
        _LOG.debug("%s", message)  # the loader logs one summary of them all

    def error(self, element: ET.Element, what: str, fix: str) -> RobotDescriptionError:
        return self.doc.error(element, what, fix)

    @staticmethod
    def child(element: ET.Element, names: str | Sequence[str]) -> ET.Element | None:
        for name in (names,) if isinstance(names, str) else names:
            found = element.find(name)
            if found is not None:
                return found
        return None

    def text(self, element: ET.Element, names: str | Sequence[str]) -> str | None:
        found = self.child(element, names)
        if found is None:
            return None
        return (found.text or "").strip()

    def number(
        self,
        element: ET.Element,
        names: str | Sequence[str],
        default: float,
        *,
        owner: str,
        minimum: float | None = None,
        strict: bool = False,
    ) -> float:
        found = self.child(element, names)
        if found is None:
            return default
        raw = (found.text or "").strip()
        try:
            value = float(raw)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise self.error(
                found,
                f"{owner}<{found.tag}>{raw}</{found.tag}> is not a finite number",
                f"write a number in <{found.tag}>",
            )
        if minimum is not None and (value < minimum or (strict and value == minimum)):
            bound = f"> {minimum:g}" if strict else f">= {minimum:g}"
            raise self.error(
                found,
                f"{owner}<{found.tag}> = {value:g} is out of range (expected {bound})",
                f"set <{found.tag}> {bound}",
            )
        return value

    def integer(self, element: ET.Element, name: str, default: int, *, owner: str) -> int:
        found = element.find(name)
        if found is None:
            return default
        raw = (found.text or "").strip()
        try:
            value = int(raw)
        except ValueError:
            raise self.error(
                found,
                f"{owner}<{name}>{raw}</{name}> is not an integer",
                f"write a positive integer in <{name}>",
            ) from None
        if value <= 0:
            raise self.error(
                found,
                f"{owner}<{name}> = {value} must be positive",
                f"set <{name}> to the image size in pixels, e.g. 640",
            )
        return value

    def boolean(
        self, element: ET.Element, names: str | Sequence[str], default: bool, *, owner: str
    ) -> bool:
        found = self.child(element, names)
        if found is None:
            return default
        raw = (found.text or "").strip().lower()
        if raw in ("true", "1"):
            return True
        if raw in ("false", "0"):
            return False
        raise self.error(
            found,
            f"{owner}<{found.tag}>{raw}</{found.tag}> is not a boolean",
            "write true or false",
        )

    def vector(
        self,
        element: ET.Element,
        names: str | Sequence[str],
        default: tuple[float, ...],
        *,
        owner: str,
    ) -> tuple[float, ...]:
        found = self.child(element, names)
        if found is None:
            return default
        raw = (found.text or "").split()
        try:
            values = tuple(float(v) for v in raw)
        except ValueError:
            values = ()
        if len(values) != len(default):
            raise self.error(
                found,
                f"{owner}<{found.tag}> {' '.join(raw)!r} is not {len(default)} numbers",
                f"write {len(default)} space-separated numbers",
            )
        return values

    def pose(self, element: ET.Element, *, owner: str) -> Origin:
        found = element.find("pose")
        if found is None:
            return Origin()
        rel = found.get("relative_to")
        if rel:
            self.warn(
                found,
                f"{owner}pose relative_to={rel!r} is not supported; the pose is "
                "taken relative to the sensor's link",
            )
        values = self.vector(element, "pose", (0.0,) * 6, owner=owner)
        return Origin((values[0], values[1], values[2]), (values[3], values[4], values[5]))

    def noise(
        self, element: ET.Element | None, *, owner: str, kind: str | None = None
    ) -> GaussianNoise:
        if element is None:
            return GaussianNoise()
        kind = (kind or element.get("type") or self.text(element, "type") or "gaussian").lower()
        if kind == "none":
            return GaussianNoise()
        if kind not in ("gaussian", "gaussian_quantized"):
            self.warn(element, f"{owner}noise type {kind!r} is not supported; no noise is added")
            return GaussianNoise()
        if kind == "gaussian_quantized":
            self.warn(element, f"{owner}gaussian_quantized noise is applied without quantization")
        return GaussianNoise(
            mean=self.number(element, "mean", 0.0, owner=owner),
            stddev=self.number(element, "stddev", 0.0, owner=owner, minimum=0.0),
            bias_mean=self.number(element, "bias_mean", 0.0, owner=owner),
            bias_stddev=self.number(element, "bias_stddev", 0.0, owner=owner, minimum=0.0),
        )

    def sensor_plugin(
        self, sensor: ET.Element, filenames: Sequence[str], *, owner: str, what: str, add: str
    ) -> ET.Element | None:
        """The sensor's first gazebo_ros plugin of ``filenames``, or None.

        None is warned (Gazebo then publishes nothing on ROS topics), and so are other
        plugins and a second one of ``filenames``.
        """
        plugins = sensor.findall("plugin")
        ours = [p for p in plugins if (p.get("filename") or "") in filenames]
        for extra in plugins:
            if extra not in ours:
                self.warn(
                    extra,
                    f"{owner}plugin {extra.get('filename')!r} is not supported and is ignored",
                )
        if len(ours) > 1:
            self.warn(ours[1], f"{owner}only the first {what} plugin is used")
        if not ours:
            self.warn(
                sensor,
                f"{owner}no gazebo_ros {what} plugin: like Gazebo, nothing is published on ROS "
                f"topics (add {add})",
            )
            return None
        return ours[0]

    def unknown(self, element: ET.Element, known: Sequence[str], *, owner: str, what: str) -> None:
        for child in element:
            if child.tag not in known:
                self.warn(child, f"{owner}<{child.tag}> in {what} is not supported and is ignored")


def plugin_node(reader: SdfReader, plugin: ET.Element, *, owner: str) -> RosNodeNames:
    """The gazebo_ros::Node of a ROS 2 plugin: name attribute, <ros> namespace and remaps."""
    name = plugin.get("name") or ""
    ros = plugin.find("ros")
    if ros is None:
        return RosNodeNames(name=name)
    namespace = "/"
    remaps: list[tuple[str | None, str, str]] = []
    rules: list[tuple[ET.Element, str]] = []
    for child in ros:
        text = (child.text or "").strip()
        if child.tag == "namespace":
            namespace = text or "/"
        elif child.tag in ("remapping", "argument"):
            for token in text.split():
                if token in ("--ros-args", "--remap", "-r"):
                    continue
                rules.append((child, token))
        elif child.tag in ("parameter", "qos"):
            reader.warn(child, f"{owner}<ros><{child.tag}> is not supported and is ignored")
        else:
            reader.warn(child, f"{owner}<ros><{child.tag}> is not supported and is ignored")
    node_name = name
    for element, token in rules:
        if ":=" not in token:
            reader.warn(element, f"{owner}argument {token!r} is not a remapping and is ignored")
            continue
        src, dst = token.split(":=", 1)
        node: str | None = None
        if ":" in src:
            node, src = src.split(":", 1)
        if not src or not dst:
            raise reader.error(
                element,
                f"{owner}remapping {token!r} is incomplete",
                "write from:=to, e.g. <remapping>image_raw:=image</remapping>",
            )
        if src == "__ns":
            namespace = dst
        elif src in ("__node", "__name"):
            node_name = dst
        else:
            remaps.append((node, src, dst))
    return RosNodeNames(
        name=node_name, namespace=normalize_namespace(namespace), remappings=tuple(remaps)
    )


def has_any(element: ET.Element, names: Sequence[str]) -> bool:
    return any(element.find(n) is not None for n in names)
