"""Parameters a launch file gives a node that the node does not declare.

ROS 2 drops an override nobody declares without a word, and roslaunch leaves it on
the parameter server: either way a misspelt name (``global_fame``) or a parameter of
another node keeps the default in force. visnav names each such parameter when the
node has started, with the closest name the node does declare.
"""

from __future__ import annotations

import difflib
import logging
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["report_unknown_parameters", "unknown_parameters"]

_LOG = logging.getLogger("visnav.launch")
_ALWAYS = frozenset({"use_sim_time"})


def unknown_parameters(
    given: Mapping[str, Any], declared: Iterable[str]
) -> list[tuple[str, str | None]]:
    """The names of ``given`` that are not in ``declared``, each with the closest declared one.

    Args:
        given: the overrides the launch file gave (flat ``a.b`` names).
        declared: the names the node declared.

    Returns:
        ``(name, closest or None)`` in the order of ``given``.
    """
    known = sorted(set(declared) | _ALWAYS)
    out: list[tuple[str, str | None]] = []
    for name in given:
        if name in known:
            continue
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        if not close:  # a name under the right prefix reads better than nothing
            head = name.rsplit(".", 1)[0]
            same = [k for k in known if k.startswith(head + ".")] if "." in name else []
            close = difflib.get_close_matches(name, same, n=1, cutoff=0.0)
        out.append((name, close[0] if close else None))
    return out


def report_unknown_parameters(
    node: Any, given: Mapping[str, Any], *, where: str = "", executable: str = ""
) -> list[str]:
    """Log (warning) and return one line per parameter ``node`` did not declare.

    Args:
        node: the started node (its ``parameters`` mapping lists what it declared).
        given: the parameter overrides the launch file gave it.
        where: ``file:line`` of the node in the launch file.
        executable: the node's executable, for the message.
    """
    declared = getattr(node, "parameters", None)
    if not isinstance(declared, Mapping):
        return []
    fqn = node.get_fully_qualified_name()
    kind = f" [{executable}]" if executable else ""
    lines = []
    for name, close in unknown_parameters(given, declared):
        hint = f"; did you mean {close!r}?" if close else ""
        lines.append(
            f"{where + ': ' if where else ''}node {fqn}{kind} has no parameter {name!r}{hint} "
            f"(the value {given[name]!r} is not applied)"
        )
    for line in lines:
        _LOG.warning("%s", line)
    return lines
