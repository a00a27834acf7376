"""The ``empty`` world: a ground plane and a sun, like Gazebo's ``worlds/empty.world``.

What roslaunch files that include ``gazebo_ros/empty_world.launch`` get. Parameters:
``size`` (ground side in metres, default 100).
"""

from __future__ import annotations

from typing import Any

__all__ = ["generate"]


def generate(*, seed: int | None = None, params: dict[str, Any] | None = None) -> dict[str, Any]:
    """Return the empty world document (see :mod:`visnav.description.world` for the format).

    Raises:
        ValueError: an unknown parameter or a non-positive size.
    """
    params = dict(params or {})
    size = float(params.pop("size", 100.0))
    if params:
        msg = f"empty world: unknown parameter(s) {', '.join(sorted(params))}: expected size"
        raise ValueError(msg)
    if not size > 0:
        msg = f"empty world: size is {size}: expected a positive side length in metres"
        raise ValueError(msg)
    return {
        "name": "empty",
        "seed": 0 if seed is None else int(seed),
        "ground": {"size": [size, size]},
        "lights": [
            {
                "name": "sun",
                "type": "directional",
                "dir": [-0.5, 0.1, -0.9],
                "diffuse": [0.8, 0.8, 0.8],
            }
        ],
        "metadata": {"kind": "empty"},
    }
