"""RViz config files (``.rviz``) read for what the viewer shows: fixed frame, displays, topics.

RViz keeps its displays in ``Visualization Manager: Displays:``, each a ``Class``
(``rviz/LaserScan`` in ROS 1, ``rviz_default_plugins/LaserScan`` in ROS 2), a ``Name``,
``Enabled`` and its own properties; ``rviz/Group`` nests displays (a disabled group
disables its children). :func:`load_rviz_config` maps the display classes the viewer
draws to :class:`RvizDisplay` (topic, enabled, colour where the viewer has one) and lists
every other display by name in :attr:`RvizConfig.ignored` (one note:
:attr:`RvizConfig.note`). Mapped classes:

=====================  ===========================================================
RViz class             what the viewer takes
=====================  ===========================================================
Map                    ``Topic``, ``Enabled``, ``Color Scheme``, ``Alpha``
LaserScan, PointCloud2 ``Topic``, ``Enabled``, ``Color`` (``FlatColor`` only)
Path                   ``Topic``, ``Enabled``, ``Color``
Pose, PoseArray        ``Topic``, ``Enabled``, ``Color``
Odometry               ``Topic``, ``Enabled``, ``Color``
Image                  ``Image Topic`` (+ ``/<Transport Hint>`` unless ``raw``), ``Enabled``
Marker, MarkerArray    ``Marker Topic`` / ``Topic``, ``Enabled``
RobotModel             ``Robot Description`` (a parameter name in ROS 1, the topic of the
                       same name in visnav) / ``Description Topic``, ``Enabled``
TF                     ``Enabled`` (no topic: the frames' axes)
=====================  ===========================================================

The viewer subscribes to the topics of the enabled displays (plus TF) instead of every
topic, in the fixed frame of the file.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from visnav.safe_yaml import YamlError, load_yaml_file
from visnav.viz.errors import VizError

__all__ = ["MAPPED_CLASSES", "RvizConfig", "RvizConfigError", "RvizDisplay", "load_rviz_config"]

MAPPED_CLASSES: Mapping[str, str] = {
    "Map": "map",
    "LaserScan": "scan",
    "PointCloud2": "cloud",
    "Path": "path",
    "RobotModel": "robot_model",
    "TF": "tf",
    "Image": "image",
    "Marker": "marker",
    "MarkerArray": "marker",
    "Pose": "pose",
    "PoseArray": "pose_array",
    "Odometry": "odometry",
}
"""RViz display class (without its plugin prefix) -> the viewer's kind of display."""

_COLORED = {"scan", "cloud", "path", "pose", "pose_array", "odometry"}
_MAP_SCHEMES = ("map", "costmap", "raw")


class RvizConfigError(VizError):
    """An ``.rviz`` file that cannot be read (missing, not YAML, not an RViz config)."""


@dataclass(frozen=True)
class RvizDisplay:
    """One display of an ``.rviz`` file that the viewer maps.

    Attributes:
        name: its path of names in RViz's display tree (``Global Map/Costmap``).
        rviz_class: the RViz class (``rviz/LaserScan``).
        kind: the viewer's kind (a value of :data:`MAPPED_CLASSES`).
        topic: the topic it shows (None for TF, or a display without a topic).
        enabled: shown (its own ``Enabled`` and every enclosing group's).
        color: RGB 0..255 where the display has one colour the viewer can use.
        alpha: ``Alpha`` (1.0 when absent).
        color_scheme: a Map display's ``Color Scheme`` (``map``, ``costmap``, ``raw``).
    """

    name: str
    rviz_class: str
    kind: str
    topic: str | None
    enabled: bool
    color: tuple[int, int, int] | None = None
    alpha: float = 1.0
    color_scheme: str | None = None


@dataclass(frozen=True)
class RvizConfig:
    """What the viewer takes from an ``.rviz`` file.

    Attributes:
        path: the file.
        fixed_frame: ``Global Options: Fixed Frame`` (None if absent).
        displays: the mapped displays, in the file's order (disabled ones included).
        ignored: the displays not mapped, as ``Name (Class)``.
    """

    path: Path
    fixed_frame: str | None
    displays: tuple[RvizDisplay, ...]
    ignored: tuple[str, ...]

    @property
    def enabled(self) -> list[RvizDisplay]:
        """The enabled mapped displays."""
        return [d for d in self.displays if d.enabled]

    @property
    def topics(self) -> list[str]:
        """The topics of the enabled displays (in order, each once)."""
        return list(dict.fromkeys(d.topic for d in self.enabled if d.topic))

    @property
    def show_tf(self) -> bool:
        """Whether an enabled TF display is in the file (RViz draws frames only then)."""
        return any(d.kind == "tf" for d in self.enabled)

    @property
    def colors(self) -> dict[str, tuple[int, int, int]]:
        """Topic -> display colour, for the enabled displays that have one."""
        return {d.topic: d.color for d in self.enabled if d.topic and d.color is not None}

    @property
    def note(self) -> str | None:
        """One line naming the displays the viewer does not draw (None if all are mapped)."""
        if not self.ignored:
            return None
        return (
            f"{self.path}: RViz displays not shown by the viewer: {', '.join(self.ignored)} "
            f"(mapped: {', '.join(sorted(set(MAPPED_CLASSES)))})"
        )


def _color(value: Any) -> tuple[int, int, int] | None:
    """RViz's ``"R; G; B"`` colour (0..255)."""
    if not isinstance(value, str):
        return None
    parts = [p.strip() for p in value.split(";")]
    if len(parts) != 3:
        return None
    try:
        rgb = tuple(min(255, max(0, round(float(p)))) for p in parts)
    except ValueError:
        return None
    return rgb[0], rgb[1], rgb[2]


def _topic(value: Any) -> str | None:
    """A topic property: a string (ROS 1) or ``{Value: ...}`` (ROS 2)."""
    if isinstance(value, Mapping):
        value = value.get("Value")
    if value is None:
        return None
    text = str(value).strip()
    if not text:
        return None
    return text if text.startswith("/") else f"/{text}"


def _enabled(item: Mapping[str, Any]) -> bool:
    value = item.get("Enabled", item.get("Value", True))
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1", "yes")
    return bool(value)


def _display(item: Mapping[str, Any], name: str, kind: str, enabled: bool) -> RvizDisplay:
    rviz_class = str(item.get("Class", ""))
    topic: str | None
    if kind == "image":
        topic = _topic(item.get("Image Topic", item.get("Topic")))
        hint = str(item.get("Transport Hint", "raw") or "raw").strip()
        if topic is not None and hint not in ("raw", ""):
            topic = f"{topic.rstrip('/')}/{hint}"
    elif kind == "marker":
        topic = _topic(item.get("Marker Topic", item.get("Topic")))
    elif kind == "robot_model":
        topic = _topic(item.get("Description Topic", item.get("Robot Description")))
        topic = topic or "/robot_description"
    elif kind == "tf":
        topic = None
    else:
        topic = _topic(item.get("Topic"))
    color = None
    if kind in _COLORED:
        transformer = str(item.get("Color Transformer", "FlatColor") or "FlatColor")
        if kind not in ("scan", "cloud") or transformer == "FlatColor":
            color = _color(item.get("Color"))
    try:
        alpha = float(item.get("Alpha", 1.0))
    except (TypeError, ValueError):
        alpha = 1.0
    scheme = None
    if kind == "map":
        text = str(item.get("Color Scheme", "map") or "map").strip()
        scheme = text if text in _MAP_SCHEMES else "map"
    return RvizDisplay(
        name=name,
        rviz_class=rviz_class,
        kind=kind,
        topic=topic,
        enabled=enabled,
        color=color,
        alpha=alpha,
        color_scheme=scheme,
    )


def _walk(
    items: Any, prefix: str, parent_enabled: bool, ignored: list[str]
) -> Iterator[RvizDisplay]:
    if not isinstance(items, list):
        return
    for item in items:
        if not isinstance(item, Mapping):
            continue
        rviz_class = str(item.get("Class", ""))
        short = rviz_class.rsplit("/", 1)[-1]
        name = f"{prefix}{item.get('Name', short)}"
        enabled = parent_enabled and _enabled(item)
        if short == "Group":
            yield from _walk(item.get("Displays"), f"{name}/", enabled, ignored)
            continue
        kind = MAPPED_CLASSES.get(short)
        if kind is None:
            ignored.append(f"{name} ({rviz_class})")
            continue
        yield _display(item, name, kind, enabled)


def load_rviz_config(path: str | Path) -> RvizConfig:
    """Read an ``.rviz`` file (ROS 1 ``rviz`` or ROS 2 ``rviz2``).

    Args:
        path: the file (``rviz -d PATH``).

    Returns:
        The fixed frame, the mapped displays and the names of the others.

    Raises:
        RvizConfigError: the file is missing, not YAML or has no ``Visualization Manager``.
    """
    file = Path(path)
    try:
        data = load_yaml_file(file, what="the RViz config")
    except YamlError as exc:
        raise RvizConfigError(str(exc)) from exc
    manager = data.get("Visualization Manager") if isinstance(data, Mapping) else None
    if not isinstance(manager, Mapping):
        text = (
            f"{file}: no 'Visualization Manager' mapping: expected an RViz config "
            "(rviz -d FILE); save one from RViz with File > Save Config"
        )
        raise RvizConfigError(text)
    options = manager.get("Global Options")
    frame = options.get("Fixed Frame") if isinstance(options, Mapping) else None
    ignored: list[str] = []
    displays = tuple(_walk(manager.get("Displays"), "", True, ignored))
    return RvizConfig(
        path=file,
        fixed_frame=str(frame).strip("/ ") or None if frame else None,
        displays=displays,
        ignored=tuple(ignored),
    )
