"""Where each element of an expanded Xacro document was written: file and line.

Xacro flattens includes and macros into one document, and the expanded XML is a
single line, so a message about an element of it cannot point at line 1 of the
top file and be useful. :func:`locating_xacro` runs Xacro with its parser wrapped:
every element of every file it reads (the top file and each ``<xacro:include>``)
gets an attribute :data:`LOCATION_ATTRIBUTE` holding ``"file:line"`` of its start
tag. Xacro copies attributes with the elements, so an element produced by a macro
carries the line of the macro body where it was written, and one from an include
the line in the included file. :func:`visnav.description.urdf_model.parse_xml`
takes the attribute off each element again and records it as the element's
location (:meth:`~visnav.description.urdf_model.XmlDoc.where`);
:func:`strip_locations` removes it from a document that is published.

Elements of the Xacro namespace (``xacro:macro``, ``xacro:include``, macro calls
...) are not annotated: Xacro checks their attributes (a macro call's attributes
are its parameters).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from xml.parsers import expat

__all__ = ["LOCATION_ATTRIBUTE", "display_path", "locating_xacro", "strip_locations"]

LOCATION_ATTRIBUTE = "visnav_source_location"
"""The attribute carrying ``"file:line"`` through Xacro's expansion (never published)."""


def display_path(path: str | os.PathLike[str]) -> str:
    """A path as messages show it: relative to the working directory when inside it."""
    text = os.fspath(path)
    if text.startswith("<"):
        return text
    try:
        relative = os.path.relpath(text)
    except ValueError:  # another drive (Windows)
        return os.path.normpath(text)
    return relative if not relative.startswith("..") else str(Path(text).resolve())


def _start_lines(text: str | bytes) -> list[int] | None:
    """The line of every start tag, in document order (None when expat refuses the text)."""
    lines: list[int] = []
    parser = expat.ParserCreate()

    def start(_tag: str, _attrs: dict[str, str]) -> None:
        lines.append(parser.CurrentLineNumber)

    parser.StartElementHandler = start
    try:
        parser.Parse(text, True)
    except expat.ExpatError:
        return None
    return lines


def _is_xacro_element(element: Any) -> bool:
    tag = str(element.tagName)
    uri = str(element.namespaceURI or "")
    return tag.startswith("xacro:") or uri.rstrip("/").endswith("wiki/xacro")


def _annotate(document: Any, text: str | bytes, name: str) -> None:
    lines = _start_lines(text)
    elements = document.getElementsByTagName("*")  # document order, as expat's start events
    if lines is None or len(lines) != len(elements):
        return
    for element, line in zip(elements, lines, strict=True):
        if not _is_xacro_element(element):
            element.setAttribute(LOCATION_ATTRIBUTE, f"{name}:{line}")


@contextmanager
def locating_xacro(top: str) -> Iterator[None]:
    """While active, documents Xacro parses carry :data:`LOCATION_ATTRIBUTE` on each element.

    Call it with Xacro's global state held (visnav runs Xacro under one lock).

    Args:
        top: the name of the top document when Xacro parses text rather than a file
            (``"<string>"``, or the file the text came from).
    """
    import xacro  # noqa: PLC0415 - optional heavy import

    original = xacro.parse

    def parse(inp: Any, filename: str | None = None) -> Any:
        document = original(inp, filename)
        text: str | bytes | None = None
        name = top
        if inp is None and filename is not None:
            path = Path(str(getattr(xacro, "root_dir", "") or ""), filename)
            try:
                text = path.read_bytes()
            except OSError:
                return document
            name = display_path(path)
        elif isinstance(inp, str):
            text = inp
        if text is not None and hasattr(document, "getElementsByTagName"):
            _annotate(document, text, name)
        return document

    xacro.parse = parse
    try:
        yield
    finally:
        xacro.parse = original


def strip_locations(document: Any) -> None:
    """Remove :data:`LOCATION_ATTRIBUTE` from every element of a minidom document."""
    for element in document.getElementsByTagName("*"):
        if element.hasAttribute(LOCATION_ATTRIBUTE):
            element.removeAttribute(LOCATION_ATTRIBUTE)
