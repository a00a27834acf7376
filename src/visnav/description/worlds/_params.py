"""Checked access to a world generator's parameters (errors are ``ValueError``)."""

from __future__ import annotations

import colorsys
import difflib
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Mapping

    import numpy as np

__all__ = ["Params", "random_colour"]


class Params:
    """Typed reads of ``params`` against documented defaults; unknown names are errors."""

    def __init__(self, world: str, params: Mapping[str, Any], defaults: Mapping[str, Any]) -> None:
        self.world = world
        self.params = dict(params)
        self.defaults = dict(defaults)
        unknown = sorted(set(self.params) - set(self.defaults))
        if unknown:
            name = unknown[0]
            close = difflib.get_close_matches(name, list(self.defaults), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            msg = (
                f"unknown parameter {name!r}{hint} "
                f"(parameters of {world}: {', '.join(sorted(self.defaults))})"
            )
            raise ValueError(msg)

    def _raw(self, name: str) -> Any:
        return self.params.get(name, self.defaults[name])

    def number(self, name: str, *, low: float | None = None, positive: bool = False) -> float:
        """A finite float, optionally > 0 or >= ``low``."""
        value = self._raw(name)
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            msg = f"parameter {name!r}: expected a finite number, got {value!r}"
            raise ValueError(msg)
        if positive and value <= 0:
            msg = f"parameter {name!r}: expected a value > 0, got {value!r}"
            raise ValueError(msg)
        if low is not None and value < low:
            msg = f"parameter {name!r}: expected a value >= {low}, got {value!r}"
            raise ValueError(msg)
        return float(value)

    def integer(self, name: str, *, low: int = 0) -> int:
        """An int >= ``low``."""
        value = self._raw(name)
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            msg = f"parameter {name!r}: expected an integer >= {low}, got {value!r}"
            raise ValueError(msg)
        return value

    def vector(self, name: str, n: int) -> tuple[float, ...]:
        """A list of ``n`` finite numbers."""
        value = self._raw(name)
        ok = isinstance(value, (list, tuple)) and len(value) == n
        if ok:
            ok = all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in value
            )
        if not ok:
            msg = f"parameter {name!r}: expected a list of {n} numbers, got {value!r}"
            raise ValueError(msg)
        return tuple(float(v) for v in value)

    def interval(self, name: str) -> tuple[float, float]:
        """A ``[low, high]`` pair with 0 < low <= high."""
        low, high = self.vector(name, 2)
        if not 0 < low <= high:
            msg = (
                f"parameter {name!r}: expected [low, high] with 0 < low <= high, got {[low, high]}"
            )
            raise ValueError(msg)
        return low, high


def random_colour(
    rng: np.random.Generator,
    *,
    hue: tuple[float, float],
    sat: tuple[float, float],
    val: tuple[float, float],
) -> tuple[float, float, float]:
    """An RGB colour drawn uniformly in an HSV box (hue may wrap past 1)."""
    h = float(rng.uniform(*hue)) % 1.0
    s = float(rng.uniform(*sat))
    v = float(rng.uniform(*val))
    r, g, b = colorsys.hsv_to_rgb(h, s, v)
    return (round(r, 4), round(g, 4), round(b, 4))
