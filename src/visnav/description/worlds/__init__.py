"""Built-in world generators.

Each generator is a function ``generate(*, seed, params) -> dict`` returning a
document in the YAML world format of :mod:`visnav.description.world` (which validates
it); bad parameters raise ``ValueError`` naming the parameter. Load them with
``visnav.description.world.load_world("office")`` or ``load_world("forest", params=...)``.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from visnav.description.worlds.empty import generate as _empty
from visnav.description.worlds.forest import generate as _forest
from visnav.description.worlds.office import generate as _office

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

__all__ = ["GENERATORS"]

GENERATORS: Mapping[str, Callable[..., dict[str, Any]]] = MappingProxyType(
    {"empty": _empty, "forest": _forest, "office": _office}
)
"""World name -> generator."""
