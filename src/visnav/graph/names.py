"""ROS 2 node, namespace and topic names: validation, expansion, helpers.

The rules follow ROS 2 (rmw's name validators and rcl's ``validate_topic_name``
and ``expand_topic_name``), so a name that works in visnav works unchanged in
ROS 2 and the other way round.

* A **node name** is one token: ASCII letters, digits and ``_``, not starting
  with a digit, at most 255 characters (``talker``).
* A **namespace** is absolute: ``/`` or ``/a/b`` (tokens as above, no trailing
  ``/``, at most 245 characters). :func:`normalize_namespace` turns ``""`` and
  ``"a"`` into ``/`` and ``/a``, as ``rcl_node_init`` does.
* A **topic name** as written in code may be absolute (``/chatter``), relative
  (``chatter``: the node's namespace is prefixed), private (``~`` or
  ``~/chatter``: namespace and node name are prefixed) and may contain the
  substitutions ``{node}``, ``{ns}`` / ``{namespace}`` or user-given ones.
* A **fully qualified** topic name is what expansion produces: absolute, no
  ``~`` or braces, at most 247 characters (``/ns/node/chatter``).

The remap grammar and name resolution (:func:`resolve_topic_name`, ...) live in
:mod:`visnav.graph.remap`; they are re-exported here.
"""

from __future__ import annotations

import re
import string
from collections.abc import Mapping

from visnav.graph.errors import GraphError

__all__ = [
    "NAMESPACE_MAX_LENGTH",
    "NODE_NAME_MAX_LENGTH",
    "TOPIC_NAME_MAX_LENGTH",
    "InvalidNameError",
    "RemapKind",
    "RemapRule",
    "RemapRules",
    "Remapping",
    "as_remapping",
    "demangle_name",
    "expand_topic_name",
    "is_hidden_name",
    "join_namespace",
    "mangle_name",
    "namespace_of",
    "normalize_namespace",
    "parse_remap_rule",
    "resolve_node_name_and_namespace",
    "resolve_topic_name",
    "split_name",
    "validate_full_topic_name",
    "validate_namespace",
    "validate_node_name",
    "validate_topic_name",
]

NODE_NAME_MAX_LENGTH = 255
"""Longest node name rmw accepts."""

TOPIC_NAME_MAX_LENGTH = 255 - 8
"""Longest fully qualified topic name rmw accepts (DDS's 255 minus 8 reserved for prefixes)."""

NAMESPACE_MAX_LENGTH = TOPIC_NAME_MAX_LENGTH - 2
"""Longest namespace rmw accepts (room is left for the shortest topic, ``/x``)."""

_ALNUM = frozenset(string.ascii_letters + string.digits)
_TOKEN_CHARS = _ALNUM | {"_"}
_ABSOLUTE_CHARS = _TOKEN_CHARS | {"/"}
_BUILTIN_SUBSTITUTIONS = ("node", "ns", "namespace")
_SUBSTITUTION_RE = re.compile(r"\{([^{}]*)\}")
_SUBSTITUTION_KEY_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_SUBSTITUTION_VALUE_RE = re.compile(r"[A-Za-z0-9_/]+")
_SUBSTITUTION_FIX = "use e.g. '{node}/foo', '{ns}' or a key passed in substitutions="
_BRACE_FIX = "balance the braces, e.g. '{node}/foo'"

_PROBLEMS = {
    "empty": "must not be empty",
    "not_absolute": "must start with '/'",
    "ends_with_slash": "must not end with '/'",
    "repeated_slash": "must not contain '//' (empty token)",
    "misplaced_tilde": "'~' (the private namespace) may only be the first character",
    "tilde_not_followed_by_slash": "the private-namespace '~' must be followed by '/'",
    "substitution_starts_with_number": "substitution names must not start with a digit",
    "empty_substitution": "'{}' is an empty substitution",
    "relative_name": "is absolute and cannot be joined to a namespace",
    "contains_percent": "contains '%', which mangling uses for '/'",
}


class InvalidNameError(GraphError, ValueError):
    """A node name, namespace, topic name or remap rule breaks the ROS 2 naming rules.

    The message names the offending value, the rule it breaks, where, and the fix.

    Attributes:
        kind: what was being checked, e.g. ``"topic name"``, ``"node name"``,
            ``"namespace"``, ``"remap rule"``.
        name: the offending value.
        rule: a stable identifier of the broken rule: ``empty``, ``not_absolute``,
            ``ends_with_slash``, ``unallowed_characters``, ``repeated_slash``,
            ``token_starts_with_number``, ``too_long``, ``misplaced_tilde``,
            ``tilde_not_followed_by_slash``, ``unmatched_curly_brace``,
            ``substitution_unallowed_characters``, ``substitution_starts_with_number``,
            ``empty_substitution``, ``unknown_substitution``, ``bad_substitution``,
            ``contains_percent``, ``relative_name``, ``invalid_remap_rule``.
        problem: what is wrong, in words.
        fix: how to fix it.
        index: position of the first offending character, when there is one.
    """

    def __init__(
        self, kind: str, name: str, rule: str, problem: str, fix: str, index: int | None = None
    ) -> None:
        self.kind = kind
        self.name = name
        self.rule = rule
        self.problem = problem
        self.fix = fix
        self.index = index
        where = "" if index is None else f" (at index {index})"
        super().__init__(f"invalid {kind} {name!r}: {problem}{where}; fix: {fix}")

    def __reduce__(
        self,
    ) -> tuple[type[InvalidNameError], tuple[str, str, str, str, str, int | None]]:
        return (type(self), (self.kind, self.name, self.rule, self.problem, self.fix, self.index))


def _error(
    kind: str, name: str, rule: str, fix: str, index: int | None = None, problem: str = ""
) -> InvalidNameError:
    return InvalidNameError(kind, name, rule, problem or _PROBLEMS[rule], fix, index)


def _require_str(kind: str, value: object) -> str:
    if not isinstance(value, str):
        msg = f"{kind} must be a str, got {type(value).__name__} {value!r}"
        raise TypeError(msg)
    return value


def _suggest_token(text: str, default: str = "name") -> str:
    """Turn arbitrary text into a valid token (for fix suggestions)."""
    out = "".join(c if c in _TOKEN_CHARS else "_" for c in text) or default
    return f"_{out}" if out[0].isdigit() else out


def _suggest_absolute(text: str) -> str:
    """Turn arbitrary text into a valid absolute name (for fix suggestions)."""
    tokens = [_suggest_token(t) for t in text.split("/") if t]
    return "/" + "/".join(tokens) if tokens else "/name"


def _digit_token_error(kind: str, name: str, index: int) -> InvalidNameError:
    end = name.find("/", index)
    token = name[index : end if end >= 0 else len(name)]
    return _error(
        kind,
        name,
        "token_starts_with_number",
        f"start the token with a letter or '_', e.g. {'_' + token!r}",
        index,
        f"tokens must not start with a digit ({token!r})",
    )


def _check_tokens(kind: str, name: str, fixed: str) -> None:
    """Reject '//' and tokens that start with a digit (rmw and rcl share this scan)."""
    for i in range(len(name) - 1):
        if name[i] == "/" and name[i + 1] == "/":
            raise _error(kind, name, "repeated_slash", f"remove the repeated '/': {fixed!r}", i + 1)
        if name[i] == "/" and name[i + 1].isdigit():
            raise _digit_token_error(kind, name, i + 1)


def _check_length(kind: str, name: str, max_length: int) -> None:
    if len(name) > max_length:
        problem = f"is {len(name)} characters long, more than the {max_length} ROS 2 allows"
        fix = f"shorten it to at most {max_length} characters"
        raise _error(kind, name, "too_long", fix, max_length - 1, problem)


def _check_absolute(kind: str, name: str, *, max_length: int, allow_root: bool) -> None:
    """Rules shared by fully qualified topic names, namespaces and enclaves (in rmw's order)."""
    if not name:
        fix = "use '/' for the root namespace" if allow_root else "give a name such as '/chatter'"
        raise _error(kind, name, "empty", fix, 0)
    if allow_root and name == "/":
        return
    if name[0] != "/":
        fix = f"make it absolute: '/{name}'"
        if kind.endswith("topic name"):
            fix += " (or expand a relative name with expand_topic_name())"
        raise _error(kind, name, "not_absolute", fix, 0)
    if name[-1] == "/":
        stripped = name.rstrip("/")
        if stripped:
            fix = f"remove the trailing '/': {stripped!r}"
        elif allow_root:
            fix = "the root namespace is written '/'"
        else:
            fix = "give the topic a name under '/', e.g. '/chatter'"
        raise _error(kind, name, "ends_with_slash", fix, len(name) - 1)
    for i, c in enumerate(name):
        if c not in _ABSOLUTE_CHARS:
            problem = f"character {c!r} is not allowed; characters allowed: alphanumerics, '_', '/'"
            fix = f"e.g. {_suggest_absolute(name)!r}"
            raise _error(kind, name, "unallowed_characters", fix, i, problem)
    _check_tokens(kind, name, _suggest_absolute(name))
    _check_length(kind, name, max_length)


def validate_node_name(name: str) -> None:
    """Check a node name (rmw ``validate_node_name``).

    Args:
        name: the node name, e.g. ``"talker"``.

    Raises:
        InvalidNameError: the name is empty, contains anything but ASCII letters,
            digits and ``_`` (a ``/`` belongs in the namespace), starts with a digit,
            or is longer than 255 characters.
        TypeError: ``name`` is not a str.
    """
    kind = "node name"
    _require_str(kind, name)
    if not name:
        raise _error(kind, name, "empty", "give a name such as 'talker'", 0)
    for i, c in enumerate(name):
        if c in _TOKEN_CHARS:
            continue
        if "/" in name.strip("/"):
            head, _, tail = name.strip("/").rpartition("/")
            fix = (
                f"a node name is one token: use name {_suggest_token(tail)!r} "
                f"with namespace {_suggest_absolute(head)!r}"
            )
        else:
            fix = f"use only letters, digits and '_', e.g. {_suggest_token(name, 'node')!r}"
        problem = f"character {c!r} is not allowed; characters allowed: alphanumerics and '_'"
        raise _error(kind, name, "unallowed_characters", fix, i, problem)
    if name[0].isdigit():
        fix = f"start it with a letter or '_', e.g. {'_' + name!r}"
        raise _error(kind, name, "token_starts_with_number", fix, 0, "must not start with a digit")
    _check_length(kind, name, NODE_NAME_MAX_LENGTH)


def validate_namespace(namespace: str) -> None:
    """Check a node namespace (rmw ``validate_namespace``).

    Args:
        namespace: an absolute namespace, ``"/"`` or e.g. ``"/robot1/sensors"``.

    Raises:
        InvalidNameError: the namespace is empty, relative, ends with ``/`` (other
            than the root ``/``), contains ``//``, characters other than ASCII
            letters, digits, ``_`` and ``/``, a token starting with a digit, or is
            longer than 245 characters. :func:`normalize_namespace` fixes the
            first two.
        TypeError: ``namespace`` is not a str.
    """
    _require_str("namespace", namespace)
    _check_absolute("namespace", namespace, max_length=NAMESPACE_MAX_LENGTH, allow_root=True)


def validate_full_topic_name(name: str) -> None:
    """Check a fully qualified topic or service name (rmw ``validate_full_topic_name``).

    Args:
        name: e.g. ``"/robot1/camera/image_raw"``.

    Raises:
        InvalidNameError: the name is empty, relative, ends with ``/``, contains
            ``//``, ``~``, braces or other characters than ASCII letters, digits,
            ``_`` and ``/``, has a token starting with a digit, or is longer than
            247 characters.
        TypeError: ``name`` is not a str.
    """
    _require_str("topic name", name)
    kind = "fully qualified topic name"
    _check_absolute(kind, name, max_length=TOPIC_NAME_MAX_LENGTH, allow_root=False)


def validate_topic_name(name: str) -> None:
    """Check a topic or service name as written in code (rcl ``validate_topic_name``).

    Relative (``chatter``), private (``~``, ``~/chatter``) and absolute names and
    ``{...}`` substitutions are allowed. Unlike rcl this also rejects ``//`` and
    the empty substitution ``{}`` here, since expansion can never make them
    valid. The length limit applies to the expanded name, not here.

    Args:
        name: the name given to a publisher, subscription or service.

    Raises:
        InvalidNameError: the name breaks a rule; the message says which and how
            to fix it.
        TypeError: ``name`` is not a str.
    """
    kind = "topic name"
    _require_str(kind, name)
    if not name:
        raise _error(kind, name, "empty", "give a name such as 'chatter'", 0)
    if name[0].isdigit():
        raise _digit_token_error(kind, name, 0)
    if name[-1] == "/":
        stripped = name.rstrip("/")
        fix = (
            f"remove the trailing '/': {stripped!r}"
            if stripped
            else "give a name such as 'chatter'"
        )
        raise _error(kind, name, "ends_with_slash", fix, len(name) - 1)
    _check_characters_and_braces(kind, name)
    _check_tokens(kind, name, re.sub("/+", "/", name))
    if name[0] == "~" and len(name) > 1 and name[1] != "/":
        raise _error(kind, name, "tilde_not_followed_by_slash", f"write {'~/' + name[1:]!r}", 1)


def _check_characters_and_braces(kind: str, name: str) -> None:
    """The character scan of rcl's topic validation: allowed characters, '~' and braces."""
    open_brace: int | None = None
    for i, c in enumerate(name):
        in_brace = open_brace is not None
        if c in _TOKEN_CHARS:
            if in_brace and i - 1 == open_brace and c.isdigit():
                raise _error(kind, name, "substitution_starts_with_number", _SUBSTITUTION_FIX, i)
        elif c == "~":
            if i != 0:
                fix = "write a private name as '~/foo', or drop the '~'"
                raise _error(kind, name, "misplaced_tilde", fix, i)
        elif c == "}" and in_brace:
            if open_brace == i - 1:
                fix = "name the substitution, e.g. '{node}', or remove the braces"
                raise _error(kind, name, "empty_substitution", fix, open_brace)
            open_brace = None
        elif c == "}":
            problem = "'}' has no matching '{'"
            raise _error(kind, name, "unmatched_curly_brace", _BRACE_FIX, i, problem)
        elif c == "{" and not in_brace:
            open_brace = i
        elif in_brace:
            problem = (
                f"character {c!r} is not allowed inside '{{...}}'; substitution names hold "
                "alphanumerics and '_' only (no nesting, no '/')"
            )
            raise _error(
                kind, name, "substitution_unallowed_characters", _SUBSTITUTION_FIX, i, problem
            )
        elif c != "/":
            problem = (
                f"character {c!r} is not allowed; characters allowed: alphanumerics, '_', '/', "
                "a leading '~' and '{' '}' substitutions"
            )
            fix = f"replace it, e.g. {re.sub(r'[^A-Za-z0-9_/~{}]', '_', name)!r}"
            raise _error(kind, name, "unallowed_characters", fix, i, problem)
    if open_brace is not None:
        problem = "'{' is never closed"
        raise _error(kind, name, "unmatched_curly_brace", _BRACE_FIX, open_brace, problem)


def normalize_namespace(namespace: str) -> str:
    """Normalise a namespace as ``rcl_node_init`` does: ``""`` -> ``"/"``, ``"a"`` -> ``"/a"``.

    The result is not validated; pass it to :func:`validate_namespace`.

    Args:
        namespace: the namespace as given by the user.

    Returns:
        The namespace with a leading ``/``.
    """
    _require_str("namespace", namespace)
    if not namespace:
        return "/"
    return namespace if namespace.startswith("/") else "/" + namespace


def _check_substitutions(substitutions: Mapping[str, str] | None) -> Mapping[str, str]:
    if not substitutions:
        return {}
    for key, value in substitutions.items():
        kind = "substitution key"
        if not isinstance(key, str) or not _SUBSTITUTION_KEY_RE.fullmatch(key):
            problem = "keys hold alphanumerics and '_' and do not start with a digit"
            fix = "use a key like 'robot' (written '{robot}' in names)"
            raise _error(kind, str(key), "bad_substitution", fix, None, problem)
        if key in _BUILTIN_SUBSTITUTIONS:
            problem = f"'{{{key}}}' is built in (node name or namespace) and cannot be redefined"
            raise _error(kind, key, "bad_substitution", "choose another key", None, problem)
        if not isinstance(value, str) or not _SUBSTITUTION_VALUE_RE.fullmatch(value):
            problem = "values hold alphanumerics, '_' and '/' only and must not be empty"
            fix = f"e.g. {_suggest_token(str(value))!r}"
            raise _error(f"value of {{{key}}}", str(value), "bad_substitution", fix, None, problem)
    return substitutions


def expand_topic_name(
    name: str,
    node_name: str,
    node_namespace: str,
    *,
    substitutions: Mapping[str, str] | None = None,
    validate: bool = True,
) -> str:
    """Expand a topic or service name to a fully qualified one (rcl ``expand_topic_name``).

    Absolute names stay as they are; a leading ``~`` becomes the node's namespace
    plus its name; then ``{node}``, ``{ns}``, ``{namespace}`` and the keys of
    ``substitutions`` are replaced; a still relative name gets the node's
    namespace as prefix. For node ``my_node``:

    ===============  ======================  =========================
    name             in namespace ``/``      in namespace ``/my_ns``
    ===============  ======================  =========================
    ``ping``         ``/ping``               ``/my_ns/ping``
    ``/ping``        ``/ping``               ``/ping``
    ``~``            ``/my_node``            ``/my_ns/my_node``
    ``~/ping``       ``/my_node/ping``       ``/my_ns/my_node/ping``
    ``{node}/ping``  ``/my_node/ping``       ``/my_ns/my_node/ping``
    ===============  ======================  =========================

    Args:
        name: the name as written in code.
        node_name: the node's name (validated).
        node_namespace: the node's absolute namespace (validated; ``"/"`` for root).
        substitutions: extra ``{key}`` -> value replacements.
        validate: check the result with :func:`validate_full_topic_name`. With
            ``False`` the result is exactly rcl's, which can be invalid: ``{ns}/x``
            in the root namespace expands to ``//x``.

    Returns:
        The fully qualified name.

    Raises:
        InvalidNameError: the name, node name, namespace or a substitution is
            invalid, a substitution is unknown, or (with ``validate``) the
            expanded name is invalid.
    """
    validate_topic_name(name)
    validate_node_name(node_name)
    validate_namespace(node_namespace)
    subs = _check_substitutions(substitutions)
    out = name
    if not (name.startswith("/") and "{" not in name):
        if out.startswith("~"):
            out = join_namespace(node_namespace, node_name) + out[1:]
        if "{" in out:
            out = _SUBSTITUTION_RE.sub(
                lambda m: _substitution(m.group(1), name, node_name, node_namespace, subs), out
            )
        if not out.startswith("/"):
            out = join_namespace(node_namespace, out)
    if validate:
        try:
            validate_full_topic_name(out)
        except InvalidNameError as exc:
            fix = exc.fix
            if exc.rule == "repeated_slash" and node_namespace == "/" and "{n" in name:
                fix = (
                    "in the root namespace '{ns}' is '/', so '{ns}/x' becomes '//x'; write the "
                    "relative name 'x' instead (it is placed in the node's namespace)"
                )
            problem = (
                f"{exc.problem} (expanded from {name!r}, node {node_name!r} in {node_namespace!r})"
            )
            raise InvalidNameError(
                "expanded topic name", out, exc.rule, problem, fix, exc.index
            ) from exc
    return out


def _substitution(
    key: str, name: str, node_name: str, node_namespace: str, subs: Mapping[str, str]
) -> str:
    if key == "node":
        return node_name
    if key in ("ns", "namespace"):
        return node_namespace
    if key in subs:
        return subs[key]
    known = ", ".join(f"{{{k}}}" for k in (*_BUILTIN_SUBSTITUTIONS, *subs))
    fix = f"use one of {known}, or pass substitutions={{{key!r}: ...}}"
    problem = f"unknown substitution {{{key}}}"
    raise _error(
        "topic name", name, "unknown_substitution", fix, name.find("{" + key + "}"), problem
    )


def join_namespace(namespace: str, name: str) -> str:
    """Join a namespace and a relative name.

    ``("/a", "b/c")`` -> ``"/a/b/c"``, ``("/", "b")`` -> ``"/b"``,
    ``("/ns", "talker")`` -> ``"/ns/talker"`` (a node's fully qualified name).
    Neither argument is validated beyond the checks below.

    Args:
        namespace: an absolute namespace (``""`` is taken as ``/``).
        name: a relative name; ``""`` returns the namespace.

    Returns:
        The joined name.

    Raises:
        InvalidNameError: ``name`` is absolute or ``namespace`` is relative.
    """
    _require_str("namespace", namespace)
    _require_str("name", name)
    if name.startswith("/"):
        raise _error("name", name, "relative_name", "use it as it is, or drop the leading '/'", 0)
    if namespace and not namespace.startswith("/"):
        raise _error("namespace", namespace, "not_absolute", f"use '/{namespace}'", 0)
    base = namespace.rstrip("/")
    if not name:
        return base or "/"
    return f"{base}/{name}"


def split_name(name: str) -> tuple[str, str]:
    """Split a name into namespace and base name.

    ``"/a/b/c"`` -> ``("/a/b", "c")``, ``"/c"`` -> ``("/", "c")``,
    ``"a/b"`` -> ``("a", "b")``, ``"c"`` -> ``("", "c")``.

    Args:
        name: a topic, service or fully qualified node name (not validated).

    Returns:
        ``(namespace, basename)``.
    """
    _require_str("name", name)
    head, sep, tail = name.rpartition("/")
    if sep and not head:
        head = "/"
    return head, tail


def namespace_of(name: str) -> str:
    """Return the namespace part of a name: ``"/a/b/c"`` -> ``"/a/b"``, ``"/c"`` -> ``"/"``."""
    return split_name(name)[0]


def is_hidden_name(name: str) -> bool:
    """Whether a name is hidden: a token starts with ``_`` (``ros2 topic list`` hides these)."""
    _require_str("name", name)
    return any(token.startswith("_") for token in name.split("/"))


def mangle_name(name: str) -> str:
    """Replace every ``/`` with ``%``, as rmw_zenoh does for names inside liveliness tokens.

    ``"/a/b"`` -> ``"%a%b"``, ``"/"`` -> ``"%"``.

    Args:
        name: a ROS name (topic, namespace, node name, enclave).

    Returns:
        The mangled name, a single key-expression chunk.

    Raises:
        InvalidNameError: the name contains ``%`` (no valid ROS name does; it
            would not demangle back).
    """
    _require_str("name", name)
    if "%" in name:
        fix = "ROS names never contain '%'; validate the name first"
        raise _error("name", name, "contains_percent", fix, name.index("%"))
    return name.replace("/", "%")


def demangle_name(mangled: str) -> str:
    """Inverse of :func:`mangle_name`: replace every ``%`` with ``/``."""
    _require_str("mangled name", mangled)
    return mangled.replace("%", "/")


# The remap grammar lives in visnav.graph.remap (it needs the validators above).
from visnav.graph.remap import (  # noqa: E402
    RemapKind,
    Remapping,
    RemapRule,
    RemapRules,
    as_remapping,
    parse_remap_rule,
    resolve_node_name_and_namespace,
    resolve_topic_name,
)
