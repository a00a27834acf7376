"""Name -> factory registries for swappable algorithms (local planners, costmap layers, ...).

A registry maps a plugin type name (the ROS name users write in a parameter, e.g.
``dwa_local_planner/DWAPlannerROS``) to a ``module:function`` path imported only when
the plugin is built, in the style of :mod:`visnav.node_registry`. Adding an
algorithm is writing its module and adding one line to the registry.
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Callable, Mapping
from typing import Any

from visnav.errors import VisnavError

__all__ = ["UnknownPluginError", "canonical_name", "resolve_factory"]


class UnknownPluginError(VisnavError, LookupError):
    """A plugin name is not in its registry, or its factory does not import."""


def canonical_name(
    name: str, registry: Mapping[str, str], aliases: Mapping[str, str], *, what: str, field: str
) -> str:
    """Return the registry key ``name`` stands for (itself, an alias, or ``pkg::Type``).

    Args:
        name: What the user wrote.
        registry: Canonical name -> ``module:function``.
        aliases: Other accepted spellings -> canonical name.
        what: The kind of plugin, for the message (``"local planner"``).
        field: The parameter that holds the name, for the message.

    Raises:
        UnknownPluginError: No such plugin (the closest names are suggested).
    """
    if name in registry:
        return name
    if name in aliases:
        return aliases[name]
    slashed = name.replace("::", "/")
    if slashed in registry:
        return slashed
    known = sorted({*registry, *aliases})
    close = difflib.get_close_matches(name, known, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    msg = f"{field} is {name!r}: expected a {what} ({', '.join(sorted(registry))}){hint}"
    raise UnknownPluginError(msg)


def resolve_factory(name: str, registry: Mapping[str, str], *, what: str) -> Callable[..., Any]:
    """Import and return the factory registered under canonical ``name``.

    Raises:
        UnknownPluginError: Not registered, or the path does not import to a callable.
    """
    path = registry.get(name)
    if path is None:
        msg = f"{what} {name!r} is not registered: expected one of {', '.join(sorted(registry))}"
        raise UnknownPluginError(msg)
    module_name, _, attr = path.partition(":")
    try:
        factory = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError) as exc:
        msg = f"{what} {name!r}: cannot import {path!r} ({exc}); check the registry line"
        raise UnknownPluginError(msg) from exc
    if not callable(factory):
        msg = f"{what} {name!r}: {path!r} is not callable"
        raise UnknownPluginError(msg)
    return factory  # type: ignore[no-any-return]
