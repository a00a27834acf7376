"""Parameters a launch file gives a node that the node does not declare.

ROS 2 drops an override nobody declares without a word, and roslaunch leaves it on
the parameter server: either way a misspelt name (``global_fame``) or a parameter of
another node keeps the default in force. visnav names each such parameter when the
node has started, with the parameter of that node that does the job: first by meaning
(the same words whatever the spelling: ``frameName`` / ``frame_name``, a topic given as a
flat key ``cloud_topic`` / ``topics.cloud``, ROS's usual aliases ``odom`` / ``odometry``,
``base_frame_id`` / ``base_frame``), then by spelling.
"""

from __future__ import annotations

import difflib
import logging
import re
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["meaning", "report_unknown_parameters", "unknown_parameters"]

_LOG = logging.getLogger("visnav.launch")
_ALWAYS = frozenset({"use_sim_time"})
_WORD = re.compile(r"[A-Z]+(?=[A-Z][a-z]|\d|$)|[A-Z]?[a-z]+|\d+|[A-Z]+")
_SYNONYMS = {
    "odom": "odometry",
    "topics": "topic",
    "freq": "frequency",
    "hz": "rate",
    "max": "maximum",
    "min": "minimum",
    "vel": "velocity",
    "lin": "linear",
    "ang": "angular",
    "tol": "tolerance",
    "thresh": "threshold",
    "num": "number",
    "img": "image",
    "cam": "camera",
    "pointcloud": "cloud",
    "points": "cloud",
}
"""Words that name the same thing in ROS parameter names (each to one spelling)."""
_FILLER = frozenset({"id", "name", "the", "of"})
"""Words whose presence does not change what a parameter names (``frame_id`` = ``frame``)."""


def meaning(name: str) -> frozenset[str]:
    """The words of a parameter name, spelling and order aside.

    ``frameName``, ``frame_name`` and ``name.frame`` give the same set; so do
    ``odom_frame_id`` and ``odometry.frame``.
    """
    words = []
    for part in re.split(r"[._/\-]+", name):
        words += [w.lower() for w in _WORD.findall(part)]
    words = [_SYNONYMS.get(w, w) for w in words]
    kept = frozenset(w for w in words if w not in _FILLER)
    return kept or frozenset(words)


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
    by_meaning: dict[frozenset[str], list[str]] = {}
    for k in known:
        by_meaning.setdefault(meaning(k), []).append(k)
    out: list[tuple[str, str | None]] = []
    for name in given:
        if name in known:
            continue
        same = by_meaning.get(meaning(name), [])
        if len(same) == 1:
            out.append((name, same[0]))
            continue
        close = difflib.get_close_matches(name, same or known, n=1, cutoff=0.6 if not same else 0)
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
