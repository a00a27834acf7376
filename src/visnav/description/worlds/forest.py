"""``forest``: columns and boxes scattered at random, like ego-planner's random_forest.

ego-planner's ``map_generator/random_forest`` drops vertical pillars uniformly
over the map, rejecting positions within 2 m of the start and the goal and
closer than ``min_distance`` to an earlier pillar. visnav does the same with
real shapes: textured cylinders ("columns") and yawed boxes, both standing on
the ground. Differences: the spacing is the *gap between footprints* (a box
counts as its circumscribed circle), not between centres, so passages are at
least ``min_spacing`` wide; the keep-out discs must hold no part of any
obstacle; every obstacle lies fully inside the map.

Parameters (``load_world("forest", params={...})``):

============== ================= =================================================
name           default           meaning
============== ================= =================================================
size           [40, 40]          map extent x, y in metres, centred on the origin
obstacles      120               number of obstacles (columns + boxes)
box_fraction   0.25              share of boxes among the obstacles
column_radius  [0.15, 0.45]      column radius range (m)
column_height  [3.0, 6.0]        column height range (m)
box_size       [0.5, 2.0]        box footprint side range (m)
box_height     [0.5, 3.0]        box height range (m)
min_spacing    1.0               minimum gap between two footprints (m)
start          [-17, 0]          centre of the start keep-out disc
goal           [17, 0]           centre of the goal keep-out disc
keepout_radius 2.0               radius of both keep-out discs (m)
============== ================= =================================================

The seed (default 0) decides positions, sizes and textures; equal seeds give
equal worlds. ``metadata`` records start, goal, keep-out radius and bounds.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from visnav.description.worlds._params import Params, random_colour

__all__ = ["DEFAULTS", "generate"]

DEFAULTS: dict[str, Any] = {
    "size": [40.0, 40.0],
    "obstacles": 120,
    "box_fraction": 0.25,
    "column_radius": [0.15, 0.45],
    "column_height": [3.0, 6.0],
    "box_size": [0.5, 2.0],
    "box_height": [0.5, 3.0],
    "min_spacing": 1.0,
    "start": [-17.0, 0.0],
    "goal": [17.0, 0.0],
    "keepout_radius": 2.0,
}

_ATTEMPTS_PER_OBSTACLE = 400
_BARK_TEXTURES = 6
_BOX_TEXTURES = 4


def _textures(rng: np.random.Generator) -> tuple[dict[str, Any], dict[str, Any]]:
    textures: dict[str, Any] = {
        "forest_floor": {
            "type": "noise",
            "rgb1": random_colour(rng, hue=(0.22, 0.3), sat=(0.4, 0.6), val=(0.35, 0.45)),
            "rgb2": random_colour(rng, hue=(0.08, 0.12), sat=(0.4, 0.6), val=(0.25, 0.35)),
            "width": 256,
            "height": 256,
            "scale": 16,
            "seed": int(rng.integers(2**31)),
        }
    }
    materials: dict[str, Any] = {"forest_floor": {"texture": "forest_floor", "tile": 4.0}}
    for i in range(_BARK_TEXTURES):
        name = f"bark_{i}"
        textures[name] = {
            "type": "noise",
            "rgb1": random_colour(rng, hue=(0.05, 0.12), sat=(0.3, 0.7), val=(0.35, 0.6)),
            "rgb2": random_colour(rng, hue=(0.0, 0.15), sat=(0.1, 0.5), val=(0.1, 0.3)),
            "width": 128,
            "height": 256,
            "scale": 8,
            "seed": int(rng.integers(2**31)),
        }
        materials[name] = {"texture": name, "tile": 1.0}
    for i in range(_BOX_TEXTURES):
        name = f"rock_{i}"
        textures[name] = {
            "type": "noise",
            "rgb1": random_colour(rng, hue=(0.0, 1.0), sat=(0.0, 0.3), val=(0.5, 0.8)),
            "rgb2": random_colour(rng, hue=(0.0, 1.0), sat=(0.2, 0.6), val=(0.15, 0.35)),
            "width": 256,
            "height": 256,
            "scale": 16,
            "seed": int(rng.integers(2**31)),
        }
        materials[name] = {"texture": name, "tile": 1.5}
    return textures, materials


def generate(*, seed: int | None = None, params: dict[str, Any] | None = None) -> dict[str, Any]:
    """Generate the forest world document.

    Args:
        seed: Random seed (default 0).
        params: Parameters (see the module docstring).

    Returns:
        A world document for :func:`visnav.description.world_yaml.world_from_dict`.

    Raises:
        ValueError: A parameter is invalid, or the obstacles do not fit.
    """
    p = Params("forest", params or {}, DEFAULTS)
    size_x, size_y = p.vector("size", 2)
    if size_x <= 0 or size_y <= 0:
        msg = f"parameter 'size': expected positive extents, got {[size_x, size_y]}"
        raise ValueError(msg)
    count = p.integer("obstacles")
    box_fraction = p.number("box_fraction", low=0.0)
    if box_fraction > 1.0:
        msg = f"parameter 'box_fraction': expected a value in [0, 1], got {box_fraction}"
        raise ValueError(msg)
    r_lo, r_hi = p.interval("column_radius")
    ch_lo, ch_hi = p.interval("column_height")
    b_lo, b_hi = p.interval("box_size")
    bh_lo, bh_hi = p.interval("box_height")
    spacing = p.number("min_spacing", low=0.0)
    start = np.array(p.vector("start", 2))
    goal = np.array(p.vector("goal", 2))
    keepout = p.number("keepout_radius", low=0.0)
    world_seed = 0 if seed is None else int(seed)
    rng = np.random.default_rng(world_seed)

    n_boxes = round(count * box_fraction)
    kinds = ["box"] * n_boxes + ["column"] * (count - n_boxes)
    kinds = [kinds[i] for i in rng.permutation(count)]
    centres = np.zeros((count, 2))
    radii = np.zeros(count)
    objects: list[dict[str, Any]] = []
    half = np.array([size_x, size_y]) / 2.0
    for index, kind in enumerate(kinds):
        for _ in range(_ATTEMPTS_PER_OBSTACLE):
            if kind == "column":
                radius = float(rng.uniform(r_lo, r_hi))
                height = float(rng.uniform(ch_lo, ch_hi))
                footprint = radius
            else:
                sx, sy = (float(v) for v in rng.uniform(b_lo, b_hi, size=2))
                height = float(rng.uniform(bh_lo, bh_hi))
                yaw = float(rng.uniform(-math.pi, math.pi))
                footprint = 0.5 * math.hypot(sx, sy)
            if np.any(half <= footprint):
                continue
            xy = rng.uniform(-half + footprint, half - footprint)
            if np.linalg.norm(xy - start) - footprint < keepout:
                continue
            if np.linalg.norm(xy - goal) - footprint < keepout:
                continue
            gaps = np.linalg.norm(centres[:index] - xy, axis=1) - radii[:index] - footprint
            if index and gaps.min() < spacing:
                continue
            break
        else:
            msg = (
                f"could place only {index} of {count} obstacles in {size_x} x {size_y} m with "
                f"min_spacing {spacing} m and keepout_radius {keepout} m; lower 'obstacles' or "
                "'min_spacing', or enlarge 'size'"
            )
            raise ValueError(msg)
        centres[index] = xy
        radii[index] = footprint
        x, y = float(xy[0]), float(xy[1])  # unrounded: the spacing was checked on these
        if kind == "column":
            objects.append(
                {
                    "type": "cylinder",
                    "name": f"column_{index}",
                    "pos": [x, y, height / 2.0],
                    "radius": radius,
                    "length": height,
                    "material": f"bark_{int(rng.integers(_BARK_TEXTURES))}",
                }
            )
        else:
            objects.append(
                {
                    "type": "box",
                    "name": f"box_{index}",
                    "pos": [x, y, height / 2.0],
                    "yaw": yaw,
                    "size": [sx, sy, height],
                    "material": f"rock_{int(rng.integers(_BOX_TEXTURES))}",
                }
            )
    textures, materials = _textures(rng)
    return {
        "name": "forest",
        "seed": world_seed,
        "ground": {"size": [size_x + 10.0, size_y + 10.0], "material": "forest_floor"},
        "textures": textures,
        "materials": materials,
        "objects": objects,
        "lights": [
            {
                "name": "sun",
                "type": "directional",
                "dir": [-0.4, 0.3, -1.0],
                "diffuse": [0.55, 0.55, 0.5],
            },
        ],
        "metadata": {
            "kind": "forest",
            "start": [float(start[0]), float(start[1])],
            "goal": [float(goal[0]), float(goal[1])],
            "keepout_radius": keepout,
            "min_spacing": spacing,
            "bounds": [-size_x / 2.0, -size_y / 2.0, size_x / 2.0, size_y / 2.0],
        },
    }
