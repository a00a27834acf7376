"""roslaunch XML parsed with the line of every element (ElementTree keeps no lines)."""

from __future__ import annotations

from dataclasses import dataclass, field
from xml.parsers import expat

from visnav.launch.errors import LaunchParseError

__all__ = ["XmlElement", "parse_xml"]


@dataclass
class XmlElement:
    """An XML element with the line it starts on (ElementTree keeps no lines).

    Attributes:
        tag: the element name.
        attrs: its attributes.
        line: 1-based line of its start tag.
        children: child elements.
        text: the text directly inside it.
    """

    tag: str
    attrs: dict[str, str]
    line: int
    children: list[XmlElement] = field(default_factory=list)
    text: str = ""


def parse_xml(text: str, source: str) -> XmlElement:
    """Parse XML into :class:`XmlElement` s.

    Raises:
        LaunchParseError: the text is not well-formed XML (file and line given).
    """
    parser = expat.ParserCreate()
    stack: list[XmlElement] = []
    roots: list[XmlElement] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        element = XmlElement(tag, dict(attrs), parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(element)
        stack.append(element)

    def end(_tag: str) -> None:
        stack.pop()

    def data(chunk: str) -> None:
        if stack:
            stack[-1].text += chunk

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = data
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        reason = expat.errors.messages[exc.code] if exc.code else str(exc)
        msg = f"{source}:{exc.lineno}: the launch file does not parse as XML: {reason}"
        raise LaunchParseError(msg) from None
    return roots[0]
