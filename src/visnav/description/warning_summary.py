"""One grouped, ordered summary of a description's warnings, for the terminal.

Parsers collect their warnings as ``"file:line: <tag>: text"`` strings
(:attr:`~visnav.description.gazebo_specs.GazeboExtensions.warnings`,
:attr:`~visnav.description.urdf_model.Urdf.warnings`, ``world.warnings``) and log each
only at debug level; whoever loads a description logs one summary block
(:func:`log_warning_summary`): a header line, then one indented line per distinct
warning. A TurtleBot3 gives ~30 warnings; the summary gives a dozen lines, and the
two that matter come first.

Grouping: warnings with the same tag and the same text apart from the quoted names
in it (``'wheel_left_link'``, ``'Gazebo/FlatBlack'``) are one line with their count,
the names that differ listed, and every place they were written (``file:14, 25``).

Order, by consequence (:class:`Consequence`), then by first appearance:

1. ``LOST``: what the simulation loses: an ignored ``<sensor>`` (unsupported type, or
   nothing published without its plugin), an ignored ``<plugin>`` (a drive,
   ros_control, a sensor's ROS interface). These lines are marked ``!``.
2. ``CHANGED``: a sensor or plugin that runs differently from Gazebo (an option not
   supported, a rate that differs, noise left out), an inertia made physical.
3. ``DETAIL``: everything else (surface parameters, materials, joint properties).

The class is read from the warning's tag and text (:func:`consequence_of`): a
``<sensor>`` or ``<plugin>`` warning that says it "is ignored" or "skipped" (and names
no child element before that) or that "nothing is published" is ``LOST``, unless it says it
behaves "like Gazebo" (a sensor without a ROS plugin publishes nothing in Gazebo
either).
"""

from __future__ import annotations

import enum
import logging
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import PurePath

__all__ = [
    "Consequence",
    "DescriptionWarning",
    "WarningGroup",
    "WarningSummary",
    "consequence_of",
    "log_warning_summary",
    "summarize_warnings",
]

_LOG = logging.getLogger("visnav.description")

_MESSAGE = re.compile(r"^(?P<where>.*?): <(?P<tag>[^<>\s]+)>: (?P<text>.*)$", re.DOTALL)
_QUOTED = re.compile(r"'[^']*'")
_CHILD_TAG = re.compile(r"<[A-Za-z_][\w:.-]*>")
_LOCATION = re.compile(r"^(?P<file>.*):(?P<line>\d+)$")
_CHANGED_TAGS = frozenset(
    {"sensor", "plugin", "camera", "ray", "gpu_ray", "lidar", "imu", "noise", "ros", "depth"}
    | {"inertia"}  # the dynamics differ from the file's
)
_MAX_NAMES = 3
_MAX_LINES = 6
_MAX_TEXT = 200  # characters of one warning's text on its line (debug level has it whole)


class Consequence(enum.IntEnum):
    """What a warning costs the simulation (lower sorts first)."""

    LOST = 0
    """A sensor, drive or plugin is not simulated at all."""
    CHANGED = 1
    """A sensor or plugin runs, differently from Gazebo."""
    DETAIL = 2
    """A property without a visible effect on the data is ignored."""


def consequence_of(tag: str | None, text: str) -> Consequence:
    """Classify one warning by its element tag and text (see the module docs)."""
    if tag in ("sensor", "plugin"):
        if "like Gazebo" in text:  # Gazebo does the same: nothing is lost by simulating here
            return Consequence.CHANGED
        if "nothing is published" in text:
            return Consequence.LOST
        for word in ("ignored", "skipped"):
            head, found, _ = text.partition(word)
            if found and not _CHILD_TAG.search(head):
                return Consequence.LOST
        return Consequence.CHANGED
    if tag in _CHANGED_TAGS or "sensor '" in text or "plugin '" in text:
        return Consequence.CHANGED
    return Consequence.DETAIL


@dataclass(frozen=True)
class DescriptionWarning:
    """One warning, split into where it was written, its element's tag and its text.

    Attributes:
        location: ``file:line`` (or the file alone, or '' when unknown).
        tag: the element's tag (None for a warning about the whole file).
        text: what is wrong.
    """

    location: str
    tag: str | None
    text: str

    @classmethod
    def parse(cls, message: str) -> DescriptionWarning:
        """Split a ``"file:line: <tag>: text"`` message (anything else is all text)."""
        match = _MESSAGE.match(message)
        if match is None:
            where, sep, rest = message.partition(": ")
            if sep and (_LOCATION.match(where) or PurePath(where).suffix):
                return cls(where, None, rest)
            return cls("", None, message)
        return cls(match["where"], match["tag"], match["text"])

    @property
    def consequence(self) -> Consequence:
        """See :func:`consequence_of`."""
        return consequence_of(self.tag, self.text)


@dataclass(frozen=True)
class WarningGroup:
    """Warnings that differ only in the names they quote.

    Attributes:
        consequence: what they cost.
        tag: the element tag.
        text: the text with the differing names merged (``'a', 'b' (+2)``).
        count: how many warnings.
        locations: every distinct ``file:line``, in order of appearance.
    """

    consequence: Consequence
    tag: str | None
    text: str
    count: int
    locations: tuple[str, ...]

    def format(self, *, base_dir: str | None = None) -> str:
        """One line: ``! file:14, 25: text (4x)`` (``!`` for :attr:`Consequence.LOST`).

        A text longer than 200 characters is cut (each warning is logged whole at debug
        level).
        """
        mark = "!" if self.consequence is Consequence.LOST else " "
        where = _format_locations(self.locations, base_dir)
        text = self.text
        if len(text) > _MAX_TEXT:
            text = text[: _MAX_TEXT - 4].rsplit(" ", 1)[0] + " ..."
        if self.tag is not None and f"<{self.tag}>" not in text:
            text = f"<{self.tag}> {text}"
        count = f" ({self.count}x)" if self.count > 1 else ""
        return f"{mark} {where}: {text}{count}" if where else f"{mark} {text}{count}"


@dataclass(frozen=True)
class WarningSummary:
    """The grouped warnings of one description.

    Attributes:
        subject: what was loaded (``robot 'turtlebot3_waffle_pi' (file)``).
        total: number of warnings.
        groups: the distinct warnings, most consequential first.
        base_dir: locations in this directory are shown relative to it.
    """

    subject: str
    total: int
    groups: tuple[WarningGroup, ...]
    base_dir: str | None = None

    @property
    def lost(self) -> tuple[WarningGroup, ...]:
        """The groups that lose a sensor, a drive or a plugin."""
        return tuple(g for g in self.groups if g.consequence is Consequence.LOST)

    def header(self) -> str:
        """The first line: subject, counts, what is lost."""
        kinds = len(self.groups)
        what = f"{self.total} warning{'s' if self.total != 1 else ''}"
        if kinds != self.total:
            what += f" ({kinds} distinct)"
        lost = sum(g.count for g in self.lost)
        if lost:
            what += f"; {lost} lose a sensor, drive or plugin (marked !)"
        where = f" [paths relative to {self.base_dir}]" if self.base_dir else ""
        return f"{self.subject}: {what}{where}"

    def format(self) -> str:
        """The header and one indented line per group."""
        lines = [self.header()]
        lines.extend("  " + g.format(base_dir=self.base_dir) for g in self.groups)
        return "\n".join(lines)


def _skeleton(text: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    return tuple(_QUOTED.split(text)), tuple(_QUOTED.findall(text))


def _merge(parts: tuple[str, ...], slots: list[list[str]]) -> str:
    out = [parts[0]]
    for values, part in zip(slots, parts[1:], strict=True):
        shown = ", ".join(values[:_MAX_NAMES])
        if len(values) > _MAX_NAMES:
            shown += f" (+{len(values) - _MAX_NAMES})"
        out.extend((shown, part))
    return "".join(out)


def _format_locations(locations: Sequence[str], base_dir: str | None) -> str:
    by_file: dict[str, list[str]] = {}
    for location in locations:
        match = _LOCATION.match(location)
        file, line = (match["file"], match["line"]) if match else (location, "")
        if base_dir and file.startswith(base_dir + os.sep):
            file = file[len(base_dir) + 1 :]
        lines = by_file.setdefault(file, [])
        if line and line not in lines:
            lines.append(line)
    parts = []
    for file, lines in by_file.items():
        if not lines:
            parts.append(file)
            continue
        shown = ", ".join(lines[:_MAX_LINES])
        if len(lines) > _MAX_LINES:
            shown += f" (+{len(lines) - _MAX_LINES})"
        parts.append(f"{file}:{shown}")
    return "; ".join(parts)


def summarize_warnings(
    warnings: Sequence[str], *, subject: str, base_dir: str | None = None
) -> WarningSummary:
    """Group and order warnings (see the module docs).

    Args:
        warnings: ``"file:line: <tag>: text"`` messages, in the order they were found.
        subject: what was loaded, for the header.
        base_dir: show locations in this directory relative to it.

    Returns:
        The summary; :meth:`WarningSummary.format` is the terminal text.
    """
    order: list[tuple[str | None, tuple[str, ...]]] = []
    found: dict[tuple[str | None, tuple[str, ...]], list[DescriptionWarning]] = {}
    for message in warnings:
        warning = DescriptionWarning.parse(message)
        key = (warning.tag, _skeleton(warning.text)[0])
        if key not in found:
            order.append(key)
            found[key] = []
        found[key].append(warning)
    groups: list[WarningGroup] = []
    for key in order:
        members = found[key]
        parts = key[1]
        slots: list[list[str]] = [[] for _ in parts[1:]]
        for member in members:
            for k, value in enumerate(_skeleton(member.text)[1]):
                if value not in slots[k]:
                    slots[k].append(value)
        locations: list[str] = []
        for member in members:
            if member.location and member.location not in locations:
                locations.append(member.location)
        first = members[0]
        groups.append(
            WarningGroup(
                consequence=first.consequence,
                tag=first.tag,
                text=_merge(parts, slots),
                count=len(members),
                locations=tuple(locations),
            )
        )
    groups.sort(key=lambda g: g.consequence)  # stable: first appearance within a class
    base = os.path.normpath(base_dir) if base_dir else None
    return WarningSummary(subject, len(warnings), tuple(groups), None if base == "." else base)


def log_warning_summary(
    warnings: Sequence[str],
    *,
    subject: str,
    base_dir: str | None = None,
    logger: logging.Logger | None = None,
) -> WarningSummary | None:
    """Log the summary of ``warnings`` as one WARNING record (nothing when there are none).

    Args:
        warnings: the messages.
        subject: what was loaded, for the header.
        base_dir: show locations in this directory relative to it.
        logger: where to log (default ``visnav.description``).

    Returns:
        The summary, or None without warnings.
    """
    if not warnings:
        return None
    summary = summarize_warnings(warnings, subject=subject, base_dir=base_dir)
    (logger or _LOG).warning("%s", summary.format())
    return summary
