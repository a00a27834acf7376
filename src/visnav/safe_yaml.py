"""The one YAML loader of visnav: safe tags only, alias expansion limited, clear errors.

Every YAML document visnav reads (launch files, parameter files, camera_info,
worlds, ``--expect`` files, command-line values) goes through :func:`load_yaml`
or a subclass of :class:`LimitedSafeLoader`. The loader is PyYAML's
``SafeLoader`` with two additions:

* **Alias limits.** Before anything is constructed, the composed node graph is
  measured: the nodes that aliases add when expanded (``*a`` counts the whole
  tree of ``&a``) may not exceed :attr:`LimitedSafeLoader.max_alias_nodes`, and an
  alias inside its own anchor (a recursive structure) is refused. A 469-byte
  "billion laughs" file is refused in milliseconds instead of taking 40 s and
  gigabytes. PyYAML, and so ROS 2's launch and parameter loading, has no such
  limit; this is where visnav differs.
* **Errors as one line.** Syntax errors, characters YAML does not allow (C0/C1
  control characters), values PyYAML cannot construct (``2001-13-45`` as a date,
  a 5,000-digit integer) and nesting too deep for the parser all become a
  :class:`YamlError` (or the caller's own error class) naming the file, the line
  and column, the problem and the fix.

Files whose later errors must name a line (launch files, worlds) load with
:func:`load_yaml_lines`: every mapping is a :class:`LineMap` that remembers its line,
a key written twice in one mapping is an error (PyYAML keeps the last silently), and
merge keys (``<<: *defaults``) work as YAML 1.1 says: the mapping's own keys override
merged ones, and of several merged mappings the first wins.

This module sits at the root of the package (beside ``errors.py``) so that every
layer may use it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import yaml

from visnav.errors import VisnavError
from visnav.textfile import read_text

__all__ = [
    "MAX_ALIAS_NODES",
    "LimitedSafeLoader",
    "LineLoader",
    "LineMap",
    "YamlError",
    "load_yaml",
    "load_yaml_file",
    "load_yaml_lines",
]

MAX_ALIAS_NODES = 100_000
"""Default cap on the nodes that alias expansion may add to one document."""


class YamlError(VisnavError, ValueError):
    """A YAML document that cannot be loaded (the message names the file, line and fix)."""


class LimitedSafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses alias bombs and recursive aliases.

    Subclass it to add constructors (line-numbered mappings, duplicate-key checks);
    the limits stay. Set :attr:`max_alias_nodes` on a subclass to change the cap.
    """

    max_alias_nodes: ClassVar[int] = MAX_ALIAS_NODES

    def compose_document(self) -> yaml.Node | None:
        """Compose one document, then check its alias expansion before construction.

        The same steps as PyYAML's ``Composer.compose_document``, with the check
        between composing and forgetting the anchors: a document without anchors
        cannot hold an alias and is not walked again.
        """
        self.get_event()  # type: ignore[no-untyped-call]  # DocumentStartEvent
        node: yaml.Node | None = self.compose_node(None, None)  # type: ignore[arg-type]
        self.get_event()  # type: ignore[no-untyped-call]  # DocumentEndEvent
        if self.anchors and node is not None:
            _check_aliases(node, self.max_alias_nodes)
        self.anchors = {}
        return node

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        """Construct a node; a value PyYAML cannot build becomes an error with its line."""
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, TypeError, OverflowError) as exc:
            if isinstance(exc, VisnavError):
                raise
            detail = " ".join(str(exc).split())[:160]
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"the value {_snippet(node)} cannot be read ({detail}); fix: quote it to "
                "keep it a string, or correct it",
                node.start_mark,
            ) from None


def _snippet(node: yaml.Node) -> str:
    if isinstance(node, yaml.ScalarNode):
        text = str(node.value)
        return repr(text if len(text) <= 40 else text[:37] + "...")
    return f"at column {node.start_mark.column + 1}"


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [item for pair in node.value for item in pair]
    return list(node.value)


def _check_aliases(root: yaml.Node, limit: int) -> None:
    """Refuse a node graph whose alias expansion adds more than ``limit`` nodes or recurses.

    The expanded size is computed bottom-up over the collection nodes with
    memoisation (a scalar counts one), so the check costs one visit per distinct
    collection however large the expansion would be. Aliases of scalars are not
    counted: they cannot grow faster than the text.

    Raises:
        yaml.composer.ComposerError: too much expansion, or an alias inside its anchor.
    """
    if isinstance(root, yaml.ScalarNode):
        return
    scalar = yaml.ScalarNode
    size: dict[int, int] = {}
    active: set[int] = set()
    distinct = 0
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        kids = _children(node)
        if done:
            active.discard(key)
            total, leaves = 1, 0
            for child in kids:
                if isinstance(child, scalar):
                    leaves += 1
                else:
                    total += size[id(child)]
            size[key] = total + leaves
            distinct += 1 + leaves
            continue
        if key in size:
            continue
        if key in active:
            raise yaml.composer.ComposerError(
                None,
                None,
                "an alias refers to the anchored node that contains it (a recursive "
                "structure); fix: visnav files cannot be recursive, write the value out",
                node.start_mark,
            )
        active.add(key)
        stack.append((node, True))
        stack.extend((child, False) for child in kids if not isinstance(child, scalar))
    added = size[id(root)] - distinct
    if added > limit:
        raise yaml.composer.ComposerError(
            None,
            None,
            f"aliases expand to {added:,} more nodes, over visnav's limit of {limit:,} "
            "(an alias bomb?); fix: write the repeated values out or nest fewer aliases",
            root.start_mark,
        )


def _position(text: str, index: int) -> tuple[int, int]:
    line = text.count("\n", 0, index) + 1
    return line, index - (text.rfind("\n", 0, index) + 1) + 1


def _describe(exc: BaseException, text: str, source: str, what: str) -> str:
    """One line for a failure to load ``text`` from ``source``."""
    if isinstance(exc, yaml.reader.ReaderError):
        line, col = _position(text, exc.position)
        code = exc.character if isinstance(exc.character, int) else 0
        return (
            f"{source}:{line}: {what} contains the character U+{code:04X} at column {col}, "
            "which YAML does not allow (a control character); fix: delete it, or write it "
            f'as the escape "\\x{code:02x}" inside a double-quoted string'
        )
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        at = f":{mark.line + 1}" if mark is not None else ""
        column = f" (column {mark.column + 1})" if mark is not None else ""
        problem = " ".join(str(exc.problem or exc.context or "invalid YAML").split())
        fix = "" if "fix:" in problem else "; fix the syntax there"
        return f"{source}{at}: {what} does not parse as YAML{column}: {problem}{fix}"
    if isinstance(exc, RecursionError):
        return (
            f"{source}: {what} is nested too deeply for the YAML parser; "
            "fix: flatten the nesting (a config file needs a few levels, not hundreds)"
        )
    detail = " ".join(str(exc).split())[:200]
    return (
        f"{source}: {what} has a YAML value that cannot be read ({detail}); "
        "fix: quote the value to keep it a string, or correct it"
    )


def load_yaml(
    text: str,
    *,
    source: str,
    what: str = "the file",
    loader: type[LimitedSafeLoader] = LimitedSafeLoader,
    error: Callable[[str], Exception] = YamlError,
) -> Any:
    """Load one YAML document with the limits of :class:`LimitedSafeLoader`.

    Args:
        text: the YAML text.
        source: the file (or option) it came from, for messages.
        what: what the text is meant to be (``"the launch file"``).
        loader: a :class:`LimitedSafeLoader` subclass with extra constructors.
        error: the exception class raised on failure (the caller's VisnavError
            subclass); :class:`YamlError` by default.

    Returns:
        The Python value (None for an empty document).

    Raises:
        YamlError: (or ``error``) the text is not YAML, breaks a limit, or holds a
            value that cannot be constructed. A VisnavError raised by a custom
            constructor passes through unchanged.
    """
    try:
        instance = loader(text)
    except yaml.YAMLError as exc:
        raise error(_describe(exc, text, source, what)) from None
    instance.name = source
    try:
        return instance.get_single_data()
    except VisnavError:
        raise
    except (yaml.YAMLError, RecursionError, ValueError, TypeError, OverflowError) as exc:
        raise error(_describe(exc, text, source, what)) from None
    finally:
        instance.dispose()


def load_yaml_file(
    path: str | Path,
    *,
    what: str = "the file",
    loader: type[LimitedSafeLoader] = LimitedSafeLoader,
    error: Callable[[str], Exception] = YamlError,
) -> Any:
    """Read a UTF-8 YAML file and load it with :func:`load_yaml`.

    Raises:
        YamlError: (or ``error``) the file is missing, unreadable or not UTF-8 (the
            message of :func:`visnav.textfile.read_text`), or as :func:`load_yaml`.
    """
    text = read_text(path, what=what, error=error)
    return load_yaml(text, source=str(path), what=what, loader=loader, error=error)


class LineMap(dict[Any, Any]):
    """A YAML mapping that remembers the line it starts on (1-based; None if built by hand)."""

    line: int | None = None


_MERGE_TAG = "tag:yaml.org,2002:merge"
_VALUE_TAG = "tag:yaml.org,2002:value"

_Pair = tuple[yaml.Node, yaml.Node]


class LineLoader(LimitedSafeLoader):
    """:class:`LimitedSafeLoader` whose mappings are :class:`LineMap` (see the module docstring).

    Set :attr:`string_keys` on a subclass to turn every key into ``str`` (YAML ``1:`` and
    ``true:`` become ``"1"`` and ``"True"``) for formats whose keys are names.
    """

    string_keys: ClassVar[bool] = False


class _StringKeyLineLoader(LineLoader):
    string_keys = True


def _split_merges(node: yaml.MappingNode) -> tuple[list[_Pair], list[_Pair]]:
    """``(merged pairs, own pairs)`` of a mapping, without changing the node.

    Merged pairs are in override order (a later pair wins): the last merged mapping
    first, so the first one written wins, as PyYAML's ``flatten_mapping``. The alias
    limit has already bounded what merges can add.

    Raises:
        yaml.constructor.ConstructorError: a merge value that is not a mapping or a
            list of mappings.
    """
    merged: list[_Pair] = []
    own: list[_Pair] = []
    for key_node, value_node in node.value:
        if key_node.tag != _MERGE_TAG:
            if key_node.tag == _VALUE_TAG:  # the '=' key is a plain string (as PyYAML)
                key_node.tag = "tag:yaml.org,2002:str"
            own.append((key_node, value_node))
            continue
        sources = value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]
        for source in reversed(sources):
            if not isinstance(source, yaml.MappingNode):
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    "a merge key '<<' takes a mapping or a list of mappings (an alias such "
                    "as *defaults); fix: merge a mapping, or use another key name",
                    source.start_mark,
                )
            inner_merged, inner_own = _split_merges(source)
            merged.extend(inner_merged)
            merged.extend(inner_own)
    return merged, own


def _key(loader: LineLoader, key_node: yaml.Node) -> Any:
    key = loader.construct_object(key_node, deep=True)
    if loader.string_keys:
        return str(key)
    try:
        hash(key)
    except TypeError:
        raise yaml.constructor.ConstructorError(
            None,
            None,
            f"a key is a {type(key).__name__}, which cannot be a mapping key; fix: write "
            "the key as a plain word or number",
            key_node.start_mark,
        ) from None
    return key


def _construct_line_map(loader: LineLoader, node: yaml.MappingNode) -> LineMap:
    merged, own = _split_merges(node)
    result = LineMap()
    result.line = node.start_mark.line + 1
    for key_node, value_node in merged:  # later ones override earlier ones
        result[_key(loader, key_node)] = loader.construct_object(value_node, deep=True)
    written: set[Any] = set()
    for key_node, value_node in own:
        key = _key(loader, key_node)
        if key in written:
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"duplicate key {key!r}: {key!r} appears twice in one mapping; fix: keep one",
                key_node.start_mark,
            )
        written.add(key)
        result[key] = loader.construct_object(value_node, deep=True)
    return result


LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_line_map)


def load_yaml_lines(
    text: str,
    *,
    source: str,
    what: str = "the file",
    error: Callable[[str], Exception] = YamlError,
    string_keys: bool = False,
) -> Any:
    """Load one YAML document whose mappings are :class:`LineMap` (module docstring).

    Args:
        text: the YAML text.
        source: the file it came from, for messages.
        what: what the text is meant to be (``"the world file"``).
        error: the exception class raised on failure.
        string_keys: turn every mapping key into ``str``.

    Returns:
        The Python value (None for an empty document).

    Raises:
        YamlError: (or ``error``) as :func:`load_yaml`, and for a key written twice in one
            mapping, an unhashable key or a merge of something that is not a mapping,
            each with its line.
    """
    loader = _StringKeyLineLoader if string_keys else LineLoader
    return load_yaml(text, source=source, what=what, loader=loader, error=error)
