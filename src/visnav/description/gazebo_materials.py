"""Colours of Gazebo material scripts (OGRE ``.material`` files) for SDF ``<script>``.

An SDF visual's ``<material><script><uri>...</uri><name>Gazebo/Grey</name></script>``
names an OGRE material. visnav renders one flat colour per visual, so a material
becomes its diffuse colour:

* Gazebo's own ``gazebo.material`` (``file://media/materials/scripts/gazebo.material``)
  is built in (:data:`GAZEBO_COLOURS`): the diffuse colour of each material (the ambient
  one where a material sets no diffuse), and for textured materials (``Gazebo/Wood``,
  ``Gazebo/Bricks``, ...) about the mean colour of their texture image;
* a model's own scripts (``<uri>model://mailbox/materials/scripts</uri>``, a directory
  or a ``.material`` file) are read by :func:`read_material_scripts`: ``material NAME
  [: PARENT] { technique { pass { diffuse r g b [a] texture_unit { texture f.png } } } }``;
  a texture becomes its image's mean colour times the diffuse colour, looked up in the
  script's ``<uri>`` directories and the ``../textures`` directory beside the script.

Everything else in a script (shaders, blending, several passes) is not used.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

__all__ = ["GAZEBO_COLOURS", "MaterialScripts", "image_mean_colour", "read_material_scripts"]

RGBA = tuple[float, float, float, float]

GAZEBO_COLOURS: dict[str, RGBA] = {
    # plain colours: the diffuse colour of gazebo.material (ambient where no diffuse)
    "Gazebo/Grey": (0.7, 0.7, 0.7, 1.0),
    "Gazebo/DarkGrey": (0.175, 0.175, 0.175, 1.0),
    "Gazebo/White": (1.0, 1.0, 1.0, 1.0),
    "Gazebo/FlatBlack": (0.1, 0.1, 0.1, 1.0),
    "Gazebo/Black": (0.0, 0.0, 0.0, 1.0),
    "Gazebo/Red": (1.0, 0.0, 0.0, 1.0),
    "Gazebo/RedBright": (0.87, 0.26, 0.07, 1.0),
    "Gazebo/Green": (0.0, 1.0, 0.0, 1.0),
    "Gazebo/Blue": (0.0, 0.0, 1.0, 1.0),
    "Gazebo/SkyBlue": (0.13, 0.44, 0.70, 1.0),
    "Gazebo/Yellow": (1.0, 1.0, 0.0, 1.0),
    "Gazebo/ZincYellow": (0.9725, 0.9529, 0.2078, 1.0),
    "Gazebo/Purple": (1.0, 0.0, 1.0, 1.0),
    "Gazebo/Turquoise": (0.0, 1.0, 1.0, 1.0),
    "Gazebo/Orange": (1.0, 0.5088, 0.0468, 1.0),
    "Gazebo/WhiteGlow": (1.0, 1.0, 1.0, 1.0),
    "Gazebo/RedGlow": (1.0, 0.0, 0.0, 1.0),
    "Gazebo/GreenGlow": (0.0, 1.0, 0.0, 1.0),
    "Gazebo/BlueGlow": (0.0, 0.0, 1.0, 1.0),
    "Gazebo/YellowGlow": (1.0, 1.0, 0.0, 1.0),
    "Gazebo/PurpleGlow": (1.0, 0.0, 1.0, 1.0),
    "Gazebo/TurquoiseGlow": (0.0, 1.0, 1.0, 1.0),
    "Gazebo/TurquoiseGlowOutline": (0.0, 1.0, 1.0, 0.5),
    "Gazebo/RedTransparentOverlay": (1.0, 0.0, 0.0, 0.5),
    "Gazebo/BlueTransparentOverlay": (0.0, 0.0, 1.0, 0.5),
    "Gazebo/GreenTransparentOverlay": (0.0, 1.0, 0.0, 0.5),
    "Gazebo/RedTransparent": (1.0, 0.0, 0.0, 0.5),
    "Gazebo/GreenTransparent": (0.0, 1.0, 0.0, 0.5),
    "Gazebo/BlueTransparent": (0.0, 0.0, 1.0, 0.5),
    "Gazebo/GreyTransparent": (0.5, 0.5, 0.5, 0.5),
    "Gazebo/YellowTransparent": (1.0, 1.0, 0.0, 0.5),
    "Gazebo/OrangeTransparent": (1.0, 0.44, 0.0, 0.6),
    "Gazebo/BlueLaser": (0.0, 0.0, 1.0, 0.6),
    "Gazebo/LightOn": (0.0, 1.0, 0.0, 1.0),
    "Gazebo/LightOff": (1.0, 0.0, 0.0, 1.0),
    "Gazebo/JointAnchor": (1.0, 1.0, 1.0, 1.0),
    "Gazebo/Pioneer2Body": (0.681193, 0.000923, 0.000923, 1.0),
    "Gazebo/Gold": (0.8, 0.64869, 0.120759, 1.0),
    # textured materials: about the mean colour of the texture (times the diffuse)
    "Gazebo/PioneerBody": (0.6, 0.05, 0.05, 1.0),
    "Gazebo/WoodFloor": (0.55, 0.4, 0.25, 1.0),
    "Gazebo/CeilingTiled": (0.8, 0.8, 0.78, 1.0),
    "Gazebo/PaintedWall": (0.85, 0.83, 0.78, 1.0),
    "Gazebo/WoodPallet": (0.6, 0.5, 0.35, 1.0),
    "Gazebo/Wood": (0.6, 0.45, 0.3, 1.0),
    "Gazebo/Bricks": (0.6, 0.3, 0.25, 1.0),
    "Gazebo/WindowFrame": (0.8, 0.8, 0.8, 1.0),
    "Gazebo/Road": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Residential": (0.35, 0.35, 0.35, 1.0),
    "Gazebo/Tertiary": (0.35, 0.35, 0.35, 1.0),
    "Gazebo/Pedestrian": (0.55, 0.55, 0.55, 1.0),
    "Gazebo/Footway": (0.55, 0.55, 0.55, 1.0),
    "Gazebo/Motorway": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Lanes_6": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Trunk": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Lanes_4": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Primary": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Lanes_2": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Secondary": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Lane_1": (0.3, 0.3, 0.3, 1.0),
    "Gazebo/Steps": (0.5, 0.5, 0.5, 1.0),
    "Gazebo/GreyGradientSky": (0.6, 0.6, 0.6, 1.0),
    "Gazebo/CloudySky": (0.7, 0.75, 0.85, 1.0),
    "drc/san_fauxcity_sign": (0.7, 0.7, 0.7, 1.0),
    # grid.material (imported by gazebo.material)
    "Gazebo/Grid": (1.0, 1.0, 1.0, 1.0),
    "Gazebo/GridXY": (1.0, 1.0, 1.0, 1.0),
}
"""Flat colour of each material of Gazebo's ``gazebo.material`` (RGBA in [0, 1])."""

_MAX_SCRIPT_BYTES = 4 * 1024 * 1024
_TOKEN = re.compile(r'"[^"\n]*"|[{}]|[^\s{}]+')


@dataclass
class _Material:
    parent: str | None = None
    diffuse: tuple[float, ...] | None = None
    ambient: tuple[float, ...] | None = None
    textures: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class MaterialScripts:
    """Materials read from OGRE scripts: name -> flat colour, plus what went wrong."""

    colours: dict[str, RGBA]
    warnings: tuple[str, ...] = ()


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.DOTALL)
    return re.sub(r"//[^\n]*", " ", text)


def _numbers(words: Sequence[str]) -> tuple[float, ...] | None:
    out: list[float] = []
    for word in words[:4]:
        try:
            value = float(word)
        except ValueError:
            break
        if not np.isfinite(value):
            return None
        out.append(min(max(value, 0.0), 1.0))
    return tuple(out) if len(out) >= 3 else None


def _apply(current: _Material | None, block: str | None, statement: list[str]) -> None:
    """A ``diffuse`` / ``ambient`` of a pass or a ``texture`` of a texture unit."""
    if current is None or not statement:
        return
    key, args = statement[0], statement[1:]
    if key in ("diffuse", "ambient") and block == "pass":
        values = _numbers(args)
        if values is not None and getattr(current, key) is None:
            setattr(current, key, values)
    elif key == "texture" and block == "texture_unit" and args:
        current.textures.append(args[0])


def _parse_script(text: str) -> dict[str, _Material]:
    """Materials of one script: the first diffuse / ambient / textures of any pass."""
    materials: dict[str, _Material] = {}
    stack: list[str] = []  # block keywords
    current: _Material | None = None
    pending: list[str] = []  # the last line's words: the header of a block opened below
    for line in _strip_comments(text).splitlines():
        statement: list[str] = []
        for word in (w.strip('"') for w in _TOKEN.findall(line)):
            if word == "{":
                header = statement or pending
                keyword = header[0] if header else ""
                if keyword == "material" and not stack and len(header) >= 2:
                    current = _Material()
                    materials[header[1]] = current
                    if len(header) >= 4 and header[2] == ":":
                        current.parent = header[3]
                stack.append(keyword)
                statement, pending = [], []
            elif word == "}":
                _apply(current, stack[-1] if stack else None, statement)
                if stack:
                    stack.pop()
                if not stack:
                    current = None
                statement, pending = [], []
            else:
                statement.append(word)
        _apply(current, stack[-1] if stack else None, statement)
        if statement:
            pending = statement
    return materials


def image_mean_colour(path: Path) -> tuple[float, float, float, float] | None:
    """Mean RGB of an image file in [0, 1] (alpha 1), or None when it cannot be read."""
    try:
        from PIL import Image  # noqa: PLC0415  (pillow comes with trimesh's image support)

        with Image.open(path) as image:
            rgba = np.asarray(image.convert("RGBA").reduce(4), dtype=np.float64) / 255.0
    except (OSError, ValueError, ImportError, SyntaxError):
        return None
    if rgba.size == 0:
        return None
    pixels = rgba.reshape(-1, 4)
    mean = pixels[:, :3].mean(axis=0)
    return (float(mean[0]), float(mean[1]), float(mean[2]), 1.0)


def _script_files(uris: Iterable[Path]) -> tuple[list[Path], list[Path]]:
    scripts: list[Path] = []
    dirs: list[Path] = []
    for path in uris:
        if path.is_dir():
            dirs.append(path)
            scripts.extend(sorted(path.glob("*.material")))
        elif path.is_file():
            dirs.append(path.parent)
            scripts.append(path)
    return scripts, dirs


def read_material_scripts(
    uris: Iterable[Path], names: Iterable[str] | None = None
) -> MaterialScripts:
    """Flat colours of the materials in OGRE scripts (files or directories of ``*.material``).

    Args:
        uris: The resolved ``<script><uri>`` paths (directories or files).
        names: Only these materials (None: all); textures are read only for them.

    Returns:
        Material name -> RGBA, and one warning per texture image that is missing.
    """
    scripts, dirs = _script_files(uris)
    parsed: dict[str, _Material] = {}
    warnings: list[str] = []
    for script in scripts:
        try:
            if script.stat().st_size > _MAX_SCRIPT_BYTES:
                warnings.append(f"material script {script} is larger than 4 MB; not read")
                continue
            text = script.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            warnings.append(f"material script {script} cannot be read ({exc.strerror or exc})")
            continue
        parsed.update(_parse_script(text))
    texture_dirs = [*dirs, *(d.parent / "textures" for d in dirs)]
    colours: dict[str, RGBA] = {}
    wanted = parsed if names is None else [n for n in names if n in parsed]
    for name in wanted:
        colour = _resolve(name, parsed, texture_dirs, warnings, depth=0)
        if colour is not None:
            colours[name] = colour
    return MaterialScripts(colours=colours, warnings=tuple(warnings))


def _resolve(
    name: str,
    parsed: dict[str, _Material],
    texture_dirs: list[Path],
    warnings: list[str],
    *,
    depth: int,
) -> RGBA | None:
    material = parsed.get(name)
    if material is None:
        return GAZEBO_COLOURS.get(name)
    base: tuple[float, ...] | None = material.diffuse or material.ambient
    if base is None and material.parent is not None and depth < 8:
        inherited = _resolve(material.parent, parsed, texture_dirs, warnings, depth=depth + 1)
        base = inherited
    colour = np.ones(4)
    if base is not None:
        colour[: len(base)] = base
    for texture in material.textures[:1]:
        image = next((d / texture for d in texture_dirs if (d / texture).is_file()), None)
        mean = image_mean_colour(image) if image is not None else None
        if mean is None:
            warnings.append(
                f"material {name!r}: texture {texture!r} not found or unreadable (looked in "
                f"{', '.join(str(d) for d in texture_dirs) or 'no directory'}); untextured"
            )
        else:
            colour[:3] *= mean[:3]
    if base is None and not material.textures:
        return None
    r, g, b, a = (float(v) for v in np.clip(colour, 0.0, 1.0))
    return (r, g, b, a)
