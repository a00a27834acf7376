"""ROS 2 remap rules (rcl's grammar) and name resolution.

Remap rules (rcl's grammar) are matched against fully qualified names: both
sides of a name rule are expanded against the node first, and the first
matching rule wins.

==========================  =======================================================
``foo:=bar``                topic and service ``foo`` -> ``bar`` (relative to the node)
``/a/b:=/c``                absolute names
``~/x:=y``                  the node's private ``x`` -> ``<ns>/y``
``rostopic://foo:=bar``     topics only (``rosservice://`` for services only)
``talker:foo:=bar``         only in node ``talker``
``__node:=name``            rename the node (ROS 1 spelling ``__name:=name``)
``__ns:=/robot1``           move the node to another namespace
==========================  =======================================================

Tokens inside rules are letters, digits and single underscores, not starting
with a digit; ``{}`` substitutions, ``*``/``**`` wildcards and back-references
are rejected (rcl does not implement them either). :func:`resolve_topic_name`
is what a publisher or subscription applies to its name
(``rcl_node_resolve_name``): expand, remap, validate.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from enum import Enum
from typing import TypeAlias

from visnav.graph.names import (
    InvalidNameError,
    expand_topic_name,
    normalize_namespace,
    validate_full_topic_name,
    validate_namespace,
    validate_node_name,
)

__all__ = [
    "RemapKind",
    "RemapRule",
    "RemapRules",
    "Remapping",
    "as_remapping",
    "parse_remap_rule",
    "resolve_node_name_and_namespace",
    "resolve_topic_name",
]


# A token inside a remap rule, as rcl's lexer defines it: no leading digit and no "__".
_RULE_TOKEN = r"(?:[A-Za-z]_?|_)(?:[0-9A-Za-z]_?)*"  # noqa: S105 - a regex, not a password
_RULE_TOKEN_RE = re.compile(_RULE_TOKEN)
_RULE_NAME_RE = re.compile(rf"(?:~/|/)?{_RULE_TOKEN}(?:/{_RULE_TOKEN})*")
_RULE_NAMESPACE_RE = re.compile(rf"/(?:{_RULE_TOKEN}/)*(?:{_RULE_TOKEN})?")
_URL_TOPIC = "rostopic://"
_URL_SERVICE = "rosservice://"
_SEPARATOR = ":="
_NAME_FORMS = (
    "use 'name', '/abs/name' or '~/private' made of tokens of letters, digits and single '_' "
    "(no '{}' substitutions, no '__', no wildcards)"
)


class RemapKind(str, Enum):
    """What a remap rule renames."""

    NAME = "name"
    """Topic and service names (``foo:=bar``)."""
    TOPIC = "topic"
    """Topic names only (``rostopic://foo:=bar``)."""
    SERVICE = "service"
    """Service names only (``rosservice://foo:=bar``)."""
    NODE_NAME = "node_name"
    """The node's name (``__node:=new_name``, ROS 1 spelling ``__name:=new_name``)."""
    NAMESPACE = "namespace"
    """The node's namespace (``__ns:=/new/ns``)."""


def _invalid(text: str, problem: str, fix: str) -> InvalidNameError:
    return InvalidNameError("remap rule", text, "invalid_remap_rule", problem, fix)


def _parse_fields(text: str) -> tuple[RemapKind, str | None, str, str | None]:
    """Parse ``[node:]from:=to`` into (kind, match, replacement, node) with rcl's grammar."""
    if not isinstance(text, str):
        msg = f"remap rule must be a str, got {type(text).__name__} {text!r}"
        raise TypeError(msg)
    left, sep, right = text.partition(_SEPARATOR)
    if not sep or not left or not right:
        raise _invalid(text, "is not of the form 'from:=to'", "write e.g. 'chatter:=/talk'")
    node: str | None = None
    if not left.startswith((_URL_TOPIC, _URL_SERVICE)) and ":" in left:
        node, _, left = left.partition(":")
        if not _RULE_TOKEN_RE.fullmatch(node):
            fix = "write 'node_name:from:=to' with a plain node name (no '/', '~' or '__')"
            raise _invalid(text, f"the node-name prefix {node!r} is not a node name", fix)
    kind = RemapKind.NAME
    if left.startswith(_URL_TOPIC):
        kind, left = RemapKind.TOPIC, left[len(_URL_TOPIC) :]
    elif left.startswith(_URL_SERVICE):
        kind, left = RemapKind.SERVICE, left[len(_URL_SERVICE) :]
    elif left in ("__node", "__name"):
        if not _RULE_TOKEN_RE.fullmatch(right):
            fix = f"write '{left}:=new_name' (one token; set the namespace with '__ns:=/ns')"
            raise _invalid(text, f"the new node name {right!r} is not a single token", fix)
        return RemapKind.NODE_NAME, None, right, node
    elif left == "__ns":
        if not _RULE_NAMESPACE_RE.fullmatch(right):
            fix = "write '__ns:=/robot1' (absolute, tokens of letters, digits and single '_')"
            raise _invalid(text, f"the new namespace {right!r} is not an absolute namespace", fix)
        return RemapKind.NAMESPACE, None, right, node
    if not _RULE_NAME_RE.fullmatch(left):
        raise _invalid(text, f"the match side {left!r} is not a name rules accept", _NAME_FORMS)
    if not _RULE_NAME_RE.fullmatch(right):
        raise _invalid(text, f"the replacement {right!r} is not a name rules accept", _NAME_FORMS)
    return kind, left, right, node


@dataclass(frozen=True)
class RemapRule:
    """One remap rule, ``[node:][rostopic://|rosservice://]from:=to``.

    Build with :func:`parse_remap_rule`; direct construction is validated the
    same way. ``str(rule)`` gives the rule text back.

    Attributes:
        kind: what the rule renames.
        replacement: the right-hand side (a name, a node name or a namespace).
        match: the left-hand side of name rules; ``None`` for ``__node``/``__ns``.
        node: the node the rule is limited to, or ``None`` for every node.
    """

    kind: RemapKind
    replacement: str
    match: str | None = None
    node: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.kind, RemapKind):
            msg = f"RemapRule.kind must be a RemapKind, got {self.kind!r}"
            raise TypeError(msg)
        text = str(self)
        if _parse_fields(text) != (self.kind, self.match, self.replacement, self.node):
            raise _invalid(
                text, "its fields do not form a rule", "build rules with parse_remap_rule()"
            )

    def __str__(self) -> str:
        prefix = "" if self.node is None else f"{self.node}:"
        if self.kind is RemapKind.NODE_NAME:
            return f"{prefix}__node:={self.replacement}"
        if self.kind is RemapKind.NAMESPACE:
            return f"{prefix}__ns:={self.replacement}"
        url = {RemapKind.TOPIC: _URL_TOPIC, RemapKind.SERVICE: _URL_SERVICE}.get(self.kind, "")
        return f"{prefix}{url}{self.match}:={self.replacement}"

    def applies_to_node(self, node_name: str) -> bool:
        """Whether the rule targets the node (rules without a node prefix target all nodes)."""
        return self.node is None or self.node == node_name


def parse_remap_rule(text: str) -> RemapRule:
    """Parse one remap rule with rcl's grammar (see the module docstring for the forms).

    Args:
        text: the rule, e.g. ``"talker:chatter:=/talk"``.

    Returns:
        The parsed rule.

    Raises:
        InvalidNameError: the text is not a valid rule (``rule == "invalid_remap_rule"``).
    """
    kind, match, replacement, node = _parse_fields(text)
    return RemapRule(kind=kind, replacement=replacement, match=match, node=node)


class Remapping:
    """An ordered, immutable list of remap rules; the first matching rule wins.

    Build from rule strings, :class:`RemapRule` objects or a ``{from: to}``
    mapping (``{"chatter": "/talk", "__ns": "/robot1"}``). ``local + global_``
    chains two lists so that ``local`` is tried first, as rcl tries a node's own
    arguments before the process-wide ones.

    Example:
        >>> r = Remapping(["chatter:=/talk", "__ns:=/robot1"])
        >>> r.remap_topic_name("/robot1/chatter", "talker", "/robot1")
        '/talk'
    """

    __slots__ = ("_rules",)

    def __init__(self, rules: Iterable[RemapRule | str] | Mapping[str, str] | str = ()) -> None:
        if isinstance(rules, str):
            rules = (rules,)
        elif isinstance(rules, Mapping):
            rules = [f"{key}{_SEPARATOR}{value}" for key, value in rules.items()]
        self._rules: tuple[RemapRule, ...] = tuple(
            r if isinstance(r, RemapRule) else parse_remap_rule(r) for r in rules
        )

    @property
    def rules(self) -> tuple[RemapRule, ...]:
        """The rules in match order."""
        return self._rules

    def __iter__(self) -> Iterator[RemapRule]:
        return iter(self._rules)

    def __len__(self) -> int:
        return len(self._rules)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Remapping) and self._rules == other._rules

    def __hash__(self) -> int:
        return hash(self._rules)

    def __repr__(self) -> str:
        return f"Remapping({[str(r) for r in self._rules]!r})"

    def __add__(self, other: RemapRules) -> Remapping:
        return Remapping((*self._rules, *as_remapping(other).rules))

    def remap_topic_name(
        self, name: str, node_name: str, node_namespace: str, *, is_service: bool = False
    ) -> str | None:
        """Apply the first matching name rule to a fully qualified name.

        Both sides of each rule are expanded against the node before comparing,
        so ``foo:=bar`` for node ``n`` in ``/ns`` maps ``/ns/foo`` to ``/ns/bar``.

        Args:
            name: the fully qualified (expanded) name.
            node_name: the node's (already remapped) name.
            node_namespace: the node's (already remapped) namespace.
            is_service: ``name`` is a service: ``rosservice://`` rules apply and
                ``rostopic://`` rules do not (and the other way round).

        Returns:
            The expanded replacement, or ``None`` when no rule matched. It is not
            validated; :func:`resolve_topic_name` does that.
        """
        hit = _first_name_rule(self, name, node_name, node_namespace, is_service=is_service)
        return None if hit is None else hit[1]

    def remap_node_name(self, node_name: str) -> str | None:
        """Return the name given by the first ``__node`` rule for ``node_name``, or ``None``."""
        for rule in self._rules:
            if rule.kind is RemapKind.NODE_NAME and rule.applies_to_node(node_name):
                return rule.replacement
        return None

    def remap_namespace(self, node_name: str) -> str | None:
        """Return the namespace given by the first ``__ns`` rule for ``node_name``, or ``None``.

        rcl matches ``node:__ns:=...`` against the node's name after ``__node``
        remapping; pass that name.
        """
        for rule in self._rules:
            if rule.kind is RemapKind.NAMESPACE and rule.applies_to_node(node_name):
                return rule.replacement
        return None


RemapRules: TypeAlias = Remapping | Iterable[RemapRule | str] | Mapping[str, str] | str | None
"""Anything :func:`as_remapping` accepts."""


def as_remapping(rules: RemapRules) -> Remapping:
    """Return ``rules`` as a :class:`Remapping` (``None``: no rules; a str: one rule)."""
    if rules is None:
        return Remapping()
    if isinstance(rules, Remapping):
        return rules
    return Remapping(rules)


def _first_name_rule(
    remapping: Remapping, name: str, node_name: str, node_namespace: str, *, is_service: bool
) -> tuple[RemapRule, str] | None:
    """Return the first name rule matching ``name`` and its expanded replacement."""
    wanted = RemapKind.SERVICE if is_service else RemapKind.TOPIC
    for rule in remapping.rules:
        if rule.match is None or rule.kind not in (RemapKind.NAME, wanted):
            continue
        if not rule.applies_to_node(node_name):
            continue
        if expand_topic_name(rule.match, node_name, node_namespace, validate=False) == name:
            return rule, expand_topic_name(
                rule.replacement, node_name, node_namespace, validate=False
            )
    return None


def resolve_topic_name(
    name: str,
    node_name: str,
    node_namespace: str,
    rules: RemapRules = None,
    *,
    is_service: bool = False,
    substitutions: Mapping[str, str] | None = None,
) -> str:
    """Resolve the name a publisher, subscription or service was given (``rcl_node_resolve_name``).

    Expand the name against the node, apply the first matching remap rule, and
    validate the result as a fully qualified name.

    Args:
        name: the name as written in code (relative, private or absolute).
        node_name: the node's name after ``__node`` remapping.
        node_namespace: the node's namespace after ``__ns`` remapping.
        rules: remap rules (see :func:`as_remapping`).
        is_service: resolve a service name (``rosservice://`` rules apply).
        substitutions: extra ``{key}`` replacements for expansion.

    Returns:
        The fully qualified, remapped name.

    Raises:
        InvalidNameError: an input is invalid, or the result is not a valid fully
            qualified name (the message names the rule that produced it).
    """
    expanded = expand_topic_name(name, node_name, node_namespace, substitutions=substitutions)
    remapping = as_remapping(rules)
    hit = _first_name_rule(remapping, expanded, node_name, node_namespace, is_service=is_service)
    if hit is None:
        return expanded
    rule, remapped = hit
    try:
        validate_full_topic_name(remapped)
    except InvalidNameError as exc:
        problem = f"{exc.problem} (rule {str(rule)!r} remapped {expanded!r} to it)"
        fix = f"change the rule's replacement: {exc.fix}"
        raise InvalidNameError(
            "remapped topic name", remapped, exc.rule, problem, fix, exc.index
        ) from exc
    return remapped


def resolve_node_name_and_namespace(
    name: str, namespace: str = "/", rules: RemapRules = None
) -> tuple[str, str]:
    """Apply ``__node`` and ``__ns`` rules to a node's name and namespace (as ``rcl_node_init``).

    The namespace is normalised (``""`` -> ``/``, ``a`` -> ``/a``) and both are
    validated before remapping. ``__node`` rules are matched against the given
    name, ``__ns`` rules against the name after ``__node`` remapping. A trailing
    ``/`` that rcl's grammar allows in ``__ns:=/a/`` is dropped.

    Args:
        name: the node name given in code.
        namespace: the namespace given in code.
        rules: remap rules (see :func:`as_remapping`).

    Returns:
        ``(node_name, namespace)`` after remapping.

    Raises:
        InvalidNameError: the name, the namespace or a remapped value is invalid.
    """
    validate_node_name(name)
    namespace = normalize_namespace(namespace)
    validate_namespace(namespace)
    remapping = as_remapping(rules)
    new_name = remapping.remap_node_name(name) or name
    new_namespace = remapping.remap_namespace(new_name) or namespace
    if len(new_namespace) > 1:
        new_namespace = new_namespace.rstrip("/")
    validate_node_name(new_name)
    validate_namespace(new_namespace)
    return new_name, new_namespace
