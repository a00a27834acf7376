"""One SDF document set being read: elements with their file and line, values, warnings.

:class:`SdfReader` is the low-level half of :mod:`visnav.description.sdf_world`: it parses
SDF text (the world file and every file an ``<include>`` brings in) remembering each
element's file and line, and reads values the way SDFormat does (an empty value is a
warning and SDFormat's default, not an error).
"""

from __future__ import annotations

import logging
import math
import warnings
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING
from xml.parsers import expat

import numpy as np

from visnav.description.errors import WorldError, WorldWarning
from visnav.description.rigid import rpy_to_matrix

if TYPE_CHECKING:
    from pathlib import Path

    import numpy.typing as npt

__all__ = ["Pose", "SdfReader", "compose", "rpy_of"]

SDF_DEFAULTS: dict[str, tuple[float, ...]] = {  # SDFormat's defaults of required values
    "size": (1.0, 1.0, 1.0),
    "radius": (0.5,),
    "length": (1.0,),
}

Pose = tuple["npt.NDArray[np.float64]", "npt.NDArray[np.float64]"]  # (rotation 3x3, translation 3)


_LOG = logging.getLogger("visnav.description.world")


class SdfReader:
    """Parses SDF documents and reads their values; collects the warnings."""

    def __init__(self, source: str, base_dir: Path | None) -> None:
        self.source = source
        self.base_dir = base_dir
        self.lines: dict[int, tuple[str, int]] = {}
        self.roots: list[ET.Element] = []  # parsed documents, kept alive for `lines`
        self.warnings: list[str] = []

    def where(self, element: ET.Element) -> str:
        """``file:line`` of an element."""
        found = self.lines.get(id(element))
        return f"{found[0]}:{found[1]}" if found is not None else self.source

    def note(self, text: str) -> None:
        """A warning that belongs to no element."""
        self.warnings.append(text)
        warnings.warn(text, WorldWarning, stacklevel=4)

    def gazebo_only(self, element: ET.Element, text: str) -> None:
        """Log, at debug level, an element that only configures Gazebo itself.

        Its client window or its own solver: it changes nothing visnav simulates, so it is
        not a warning.
        """
        _LOG.debug("%s: <%s>: %s", self.where(element), element.tag, text)

    def warn(self, element: ET.Element, text: str) -> None:
        """Record and issue a :class:`WorldWarning` about an element."""
        message = f"{self.where(element)}: <{element.tag}>: {text}"
        self.warnings.append(message)
        warnings.warn(message, WorldWarning, stacklevel=4)

    def error(self, element: ET.Element, text: str) -> WorldError:
        """A :class:`WorldError` naming an element's file and line."""
        return WorldError(f"{self.where(element)}: <{element.tag}>: {text}")

    def parse(self, text: str, source: str | None = None) -> ET.Element:
        """Parse one SDF document (its root element), remembering every line."""
        source = self.source if source is None else source
        builder = ET.TreeBuilder()
        parser = expat.ParserCreate()

        def start(tag: str, attrs: dict[str, str]) -> None:
            self.lines[id(builder.start(tag, attrs))] = (source, parser.CurrentLineNumber)

        parser.StartElementHandler = start
        parser.EndElementHandler = builder.end
        parser.CharacterDataHandler = builder.data
        try:
            parser.Parse(text, True)
        except expat.ExpatError as exc:
            msg = (
                f"{source}:{exc.lineno}: malformed SDF (XML): "
                f"{expat.errors.messages[exc.code]} at column {exc.offset + 1}; fix the XML syntax"
            )
            raise WorldError(msg) from None
        root: ET.Element = builder.close()
        self.roots.append(root)
        return root

    # values ---------------------------------------------------------------

    def floats(
        self, element: ET.Element, n: int, default: tuple[float, ...] | None = None
    ) -> tuple[float, ...]:
        """``n`` finite numbers (empty with a default: a warning and the default)."""
        text = (element.text or "").split()
        if not text and default is not None:
            self.warn(element, f"empty; SDF's default {' '.join(f'{v:g}' for v in default)} used")
            return default
        try:
            values = tuple(float(v) for v in text)
        except ValueError:
            raise self.error(element, f"expected {n} numbers, got {element.text!r}") from None
        if len(values) != n or not all(math.isfinite(v) for v in values):
            raise self.error(element, f"expected {n} finite numbers, got {element.text!r}")
        return values

    def child_floats(
        self, parent: ET.Element, tag: str, n: int, default: tuple[float, ...] | None = None
    ) -> tuple[float, ...]:
        """The numbers of child ``tag`` (absent: ``default``, else an error)."""
        element = parent.find(tag)
        if element is None:
            if default is None:
                raise self.error(parent, f"missing <{tag}>")
            return default
        return self.floats(element, n, default or SDF_DEFAULTS.get(tag))

    def boolean(self, element: ET.Element | None, default: bool) -> bool:
        """An SDF boolean (true/false/1/0; empty or absent: ``default``)."""
        if element is None:
            return default
        text = (element.text or "").strip().lower()
        if not text:
            self.warn(element, f"empty; SDF's default {str(default).lower()} used")
            return default
        if text in ("1", "true"):
            return True
        if text in ("0", "false"):
            return False
        raise self.error(element, f"expected true/false/1/0, got {element.text!r}")

    def pose(self, parent: ET.Element) -> Pose:
        """The ``<pose>`` of an element as (rotation, translation)."""
        element = parent.find("pose")
        if element is None:
            return np.eye(3), np.zeros(3)
        relative = element.get("relative_to")
        if relative:
            self.warn(
                element, f"relative_to={relative!r} is not supported; read as the parent frame"
            )
        x, y, z, r, p, yaw = self.floats(element, 6, (0.0,) * 6)
        return rpy_to_matrix((r, p, yaw)), np.array([x, y, z])

    def colour(
        self,
        element: ET.Element,
        default: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0),
    ) -> tuple[float, float, float, float]:
        """An ``r g b [a]`` colour, clamped to [0, 1] (empty: a warning and ``default``)."""
        values = (element.text or "").split()
        if not values:
            self.warn(element, f"empty; SDF's default {' '.join(f'{v:g}' for v in default)} used")
            return default
        try:
            rgba = [float(v) for v in values]
        except ValueError:
            raise self.error(element, f"expected r g b [a], got {element.text!r}") from None
        if len(rgba) == 3:
            rgba.append(1.0)
        if len(rgba) != 4:
            raise self.error(element, f"expected r g b [a], got {element.text!r}")
        r, g, b, a = (min(max(v, 0.0), 1.0) for v in rgba)
        return (r, g, b, a)


def compose(a: Pose, b: Pose) -> Pose:
    """Pose ``a`` composed with pose ``b`` (``b`` expressed in ``a``)."""
    return a[0] @ b[0], a[0] @ b[1] + a[1]


def rpy_of(rot: npt.NDArray[np.float64]) -> tuple[float, float, float]:
    """Fixed-axis roll, pitch, yaw of a rotation matrix (inverse of rpy_to_matrix)."""
    pitch = math.asin(max(-1.0, min(1.0, -rot[2, 0])))
    if abs(rot[2, 0]) < 1.0 - 1e-9:
        roll = math.atan2(rot[2, 1], rot[2, 2])
        yaw = math.atan2(rot[1, 0], rot[0, 0])
    else:
        roll = 0.0
        yaw = math.atan2(-rot[0, 1], rot[1, 1])
    return (roll, pitch, yaw)
