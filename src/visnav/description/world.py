"""Worlds: the YAML world format, the SDF subset and the built-in worlds (no MuJoCo).

A world is static geometry on a ground plane, with textures (procedural, so
that a camera sees visual features wherever it looks), lights and physics
settings. :func:`load_world` reads a YAML file, an SDF file (a subset, for
Gazebo users; see :mod:`visnav.description.sdf_world`) or a built-in world by name
(``office``, ``forest``); :func:`visnav.sim.world_spec.build_world_spec` turns the result into a
``mujoco.MjSpec`` to which robots are then attached.

YAML world format (every key optional except where noted; lengths in metres,
angles in radians, colours in [0, 1])::

    name: my_world
    seed: 7                      # seeds noise textures (and generators)
    physics: {timestep: 0.002, gravity: [0, 0, -9.81], integrator: implicitfast}
    ground: {size: [40, 40], z: 0.0, material: floor}   # `ground: null` for none;
                                 # or {size: [40, 40], texture: tiles, tile: 2.0}
    headlight: {active: true, ambient: [.35, .35, .35], diffuse: [.45, .45, .45]}
    textures:                    # name -> texture
      tiles: {type: checker, rgb1: [.8, .8, .8], rgb2: [.3, .3, .3],
              width: 256, height: 256, mark: random, random: 0.02, markrgb: [1, 1, 1]}
      plaster: {type: noise, rgb1: [.9, .8, .6], rgb2: [.4, .3, .2], scale: 16, seed: 3}
      sky: {type: gradient, rgb1: [.6, .8, 1], rgb2: [0, 0, .2]}
      logo: {type: file, file: logo.png}   # relative to the YAML file
    materials:                   # name -> material
      floor: {texture: tiles, tile: 2.0}   # one texture repeat per 2 m
      wall: {texture: plaster, tile: 1.5, rgba: [1, 1, 1, 1], specular: 0.1}
    objects:                     # list; `type` is required
      - {type: box, name: wall_n, pos: [0, 5, 1.25], size: [10, 0.15, 2.5], material: wall}
      - {type: cylinder, pos: [2, 1, 1], radius: 0.3, length: 2, yaw: 0.3, rgba: [.2, .6, .2, 1]}
      - {type: sphere, pos: [0, 0, 3], radius: 0.5, collision: false}   # visual only
      - {type: mesh, file: chair.obj, scale: 0.01, pos: [1, 1, 0], rpy: [1.5708, 0, 0]}
    lights:
      - {type: directional, dir: [-0.3, 0.2, -1], diffuse: [.6, .6, .6]}
      - {type: point, pos: [0, 0, 3], diffuse: [.3, .3, .3], attenuation: [1, 0.1, 0]}
    metadata: {start: [0, 0, 0], goal: [5, 5, 0]}   # free-form, kept as is

Box ``size`` is the full extent (as in SDF), ``rpy`` is fixed-axis roll, pitch,
yaw (``yaw: a`` is shorthand for ``rpy: [0, 0, a]``). Shapes default to
``visual: true, collision: true``. Textures without a ``seed`` get one derived
from the world seed and their name, so ``load_world(..., seed=n)`` re-rolls
every unseeded texture. Unknown keys are errors, not silently ignored.

In the MuJoCo spec every world element is named ``world/<name>``; collision-only
shapes are in geom group 3, which visnav cameras do not draw.

Each name has one home: this module loads worlds (:func:`load_world`,
:func:`builtin_world_names`); the world types (``WorldDescription``, ``Box``, ...) are in
:mod:`visnav.description.worldmodel`, :func:`~visnav.description.world_yaml.world_from_dict`
(a world from a dict) in :mod:`visnav.description.world_yaml`, ``WorldError`` and
``WorldWarning`` in :mod:`visnav.description.errors`. The full reference,
with the SDF subset and the built-in worlds, is ``docs/worlds.md``.
"""

from __future__ import annotations

import difflib
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from visnav.description.errors import WorldError, WorldWarning
from visnav.description.sdf_world import load_sdf_world
from visnav.description.warning_summary import log_warning_summary
from visnav.description.world_yaml import load_yaml_world, world_from_dict
from visnav.description.xacro_locations import display_path

if TYPE_CHECKING:
    from collections.abc import Mapping

    from visnav.description.worldmodel import WorldDescription

__all__ = ["builtin_world_names", "load_world"]

_YAML_SUFFIXES = (".yaml", ".yml")
_SDF_SUFFIXES = (".sdf", ".world")


def builtin_world_names() -> tuple[str, ...]:
    """Names of the built-in worlds (``office``, ``forest``, ...)."""
    from visnav.description.worlds import GENERATORS  # noqa: PLC0415  (data layer, loaded lazily)

    return tuple(sorted(GENERATORS))


def _load_builtin(
    name: str, params: Mapping[str, Any] | None, seed: int | None
) -> WorldDescription:
    from visnav.description.worlds import GENERATORS  # noqa: PLC0415

    generator = GENERATORS.get(name)
    if generator is None:
        close = difflib.get_close_matches(name, list(GENERATORS), n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        msg = (
            f"unknown world {name!r}{hint} Built-in worlds: {', '.join(sorted(GENERATORS))}; "
            "or give the path of a .yaml / .sdf / .world file"
        )
        raise WorldError(msg)
    try:
        doc = generator(seed=seed, params=dict(params or {}))
    except (ValueError, TypeError) as exc:
        msg = f"world {name!r}: {exc}"
        raise WorldError(msg) from None
    return world_from_dict(doc, source=f"builtin:{name}")


def load_world(
    source: str | os.PathLike[str],
    *,
    params: Mapping[str, Any] | None = None,
    seed: int | None = None,
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    skip_missing_models: bool = False,
) -> WorldDescription:
    """Load a world from a file or a built-in generator.

    Args:
        source: A ``.yaml`` / ``.yml`` file, an SDF ``.sdf`` / ``.world`` file,
            or the name of a built-in world (:func:`builtin_world_names`).
        params: Parameters of a built-in generator (for example
            ``{"size": [40, 40], "obstacles": 120}`` for ``forest``).
        seed: Overrides the world's seed (textures, random layouts).
        packages: Package name -> directory: an SDF world's ``model://`` models are
            also looked up in the model paths these packages export (as ``gazebo_ros``
            does), and ``package://`` URIs resolve (see
            :mod:`visnav.description.model_path`).
        skip_missing_models: An SDF world whose included models are not found loads
            without them (one warning) instead of raising.

    An SDF world's warnings (``world.warnings``) are logged as one grouped summary
    (:mod:`visnav.description.warning_summary`), not as one ``WorldWarning`` each
    (:func:`~visnav.description.sdf_world.parse_sdf_world` issues those).

    Returns:
        The world.

    Raises:
        WorldError: Missing or malformed file (with file and line), unknown
            world name (with the closest name), parameters given for a file,
            invalid content, SDF models not found (all listed in one error).
    """
    text = os.fspath(source)
    path = Path(text)
    suffix = path.suffix.lower()
    looks_like_file = suffix in _YAML_SUFFIXES + _SDF_SUFFIXES or os.sep in text
    if not path.is_file() and not looks_like_file:
        return _load_builtin(text, params, seed)
    if not path.is_file():
        names = ", ".join(builtin_world_names())
        msg = f"world file {text!r} does not exist (built-in worlds: {names})"
        raise WorldError(msg)
    if params:
        msg = (
            f"{text}: params {sorted(params)} are only accepted by built-in world generators "
            f"({', '.join(builtin_world_names())}); edit the file instead"
        )
        raise WorldError(msg)
    if suffix in _SDF_SUFFIXES or (suffix not in _YAML_SUFFIXES and _sniff_xml(path)):
        with warnings.catch_warnings():  # each one is in world.warnings: one summary below
            warnings.simplefilter("ignore", WorldWarning)
            world = load_sdf_world(
                path, seed=seed, packages=packages, skip_missing_models=skip_missing_models
            )
        log_warning_summary(
            world.warnings,
            subject=f"world {world.name!r} ({display_path(path)})",
            base_dir=display_path(path.parent),
        )
        return world
    return load_yaml_world(path, seed=seed)


def _sniff_xml(path: Path) -> bool:
    try:
        with path.open("rb") as f:
            head = f.read(256).lstrip()
    except OSError:
        return False
    return head.startswith(b"<")
