"""Gazebo Classic's model path: where ``model://NAME`` and Gazebo resource URIs are found.

Gazebo looks a ``model://NAME`` URI up in the directories of its model path, in order,
and takes the first one holding a directory ``NAME``. visnav builds the same list
(:func:`model_path`):

1. ``GAZEBO_MODEL_PATH`` (colon-separated), as Gazebo reads it;
2. the ``<export><gazebo_ros gazebo_model_path="${prefix}/models"/></export>`` of ROS
   packages (what ``gazebo_ros`` adds to the model path when it starts Gazebo): of the
   packages given explicitly (``packages={'turtlebot3_gazebo': DIR}``), of the package
   that holds the world file, and of the packages under ``ROS_PACKAGE_PATH`` and
   ``AMENT_PREFIX_PATH/share``;
3. ``~/.gazebo/models`` (where Gazebo keeps models downloaded from its online database).

A model directory's ``model.config`` names its SDF file per SDF version
(``<sdf version="1.5">model.sdf</sdf>``); :func:`model_sdf_file` picks the highest
version Gazebo 11 reads (1.7 and older), and ``model.sdf`` when there is no
``model.config``.

``file://media/...`` material scripts are Gazebo resources: they are found in
``GAZEBO_RESOURCE_PATH`` and the packages' ``gazebo_media_path`` exports (visnav knows
Gazebo's own ``gazebo.material`` colours without them).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from visnav.description.errors import WorldError

if TYPE_CHECKING:
    from collections.abc import Iterator, Mapping

__all__ = [
    "GAZEBO_SDF_VERSION",
    "ModelPath",
    "model_path",
    "model_sdf_file",
    "package_exports",
    "split_model_uri",
]

GAZEBO_SDF_VERSION = (1, 7)
"""The newest SDF version Gazebo 11 (SDFormat 9) reads; model.config picks up to it."""

_MAX_PACKAGE_DEPTH = 6  # directories searched below a ROS_PACKAGE_PATH entry
_MAX_CONFIG_BYTES = 1024 * 1024


@dataclass(frozen=True)
class ModelPath:
    """An ordered list of model directories and Gazebo resource directories.

    Attributes:
        roots: Directories holding model directories, searched in order.
        resources: Directories ``file://`` resource URIs (``media/materials/...``) start from.
        origins: Where each root came from (``GAZEBO_MODEL_PATH``, ``package foo``, ...).
    """

    roots: tuple[Path, ...] = ()
    resources: tuple[Path, ...] = ()
    origins: tuple[str, ...] = ()

    def find(self, name: str) -> Path | None:
        """The directory of model ``name`` (the first root that has it), or None."""
        if not name or name in (".", "..") or "/" in name or "\\" in name:
            return None
        for root in self.roots:
            candidate = root / name
            if candidate.is_dir():
                return candidate
        return None

    def describe(self) -> str:
        """The searched directories as one line, for error messages."""
        if not self.roots:
            return "no model directories (GAZEBO_MODEL_PATH is empty and no package exports any)"
        return "; ".join(
            f"{root} ({origin})" for root, origin in zip(self.roots, self.origins, strict=False)
        )

    def resource(self, relative: str) -> Path | None:
        """An existing file ``relative`` under one of the resource directories, or None."""
        for root in self.resources:
            candidate = root / relative
            if candidate.is_file():
                return candidate
        return None


def split_model_uri(uri: str) -> tuple[str, str]:
    """``model://NAME/rest`` -> ``(NAME, rest)``; extra leading slashes are dropped.

    Gazebo accepts ``model:///name/...`` (three slashes) as ``model://name/...``.
    """
    rest = uri[len("model://") :].lstrip("/")
    name, _, tail = rest.partition("/")
    return name, tail


def _read_xml(path: Path) -> ET.Element | None:
    try:
        if path.stat().st_size > _MAX_CONFIG_BYTES:
            return None
        return ET.fromstring(path.read_bytes())  # noqa: S314  (local package/model files)
    except (OSError, ET.ParseError, ValueError):
        return None


def package_exports(package_dir: Path) -> tuple[str | None, list[Path], list[Path]]:
    """Name and the ``gazebo_model_path`` / ``gazebo_media_path`` exports of a package.

    ``${prefix}`` is the package directory (as ``rospack plugins`` substitutes it).

    Returns:
        ``(name, model_dirs, media_dirs)``; ``(None, [], [])`` without a readable package.xml.
    """
    root = _read_xml(package_dir / "package.xml")
    if root is None:
        return None, [], []
    name = (root.findtext("name") or "").strip() or None
    models: list[Path] = []
    media: list[Path] = []
    export = root.find("export")
    for element in export.findall("gazebo_ros") if export is not None else []:
        for attribute, out in (("gazebo_model_path", models), ("gazebo_media_path", media)):
            value = element.get(attribute)
            if value:
                text = value.replace("${prefix}", str(package_dir))
                path = Path(text)
                out.append(path if path.is_absolute() else package_dir / path)
    return name, models, media


def _walk_packages(root: Path) -> Iterator[Path]:
    """Package directories under ``root`` (rospack's crawl: stop at a package.xml)."""
    stack = [(root, 0)]
    while stack:
        directory, depth = stack.pop()
        if (directory / "package.xml").is_file():
            yield directory
            continue
        if depth >= _MAX_PACKAGE_DEPTH or (directory / "CATKIN_IGNORE").exists():
            continue
        try:
            children = sorted(p for p in directory.iterdir() if p.is_dir())
        except OSError:
            continue
        stack.extend((child, depth + 1) for child in reversed(children))


def _enclosing_package(path: Path) -> Path | None:
    for ancestor in path.resolve().parents:
        if (ancestor / "package.xml").is_file():
            return ancestor
    return None


def _environment_paths(environ: Mapping[str, str], name: str) -> list[Path]:
    return [Path(p) for p in environ.get(name, "").split(os.pathsep) if p]


def model_path(
    *,
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    world_file: str | os.PathLike[str] | None = None,
    environ: Mapping[str, str] | None = None,
    home: str | os.PathLike[str] | None = None,
) -> ModelPath:
    """The model path Gazebo (started by ``gazebo_ros``) would search (see the module doc).

    Args:
        packages: Package name -> directory (the same mapping robots get).
        world_file: The world file; its enclosing package's exports are used.
        environ: Environment (default ``os.environ``).
        home: Home directory of ``~/.gazebo/models`` (default the user's).

    Returns:
        The ordered model and resource directories.
    """
    env = os.environ if environ is None else environ
    roots: list[Path] = []
    origins: list[str] = []
    resources: list[Path] = []

    def add(path: Path, origin: str) -> None:
        if path not in roots and path.is_dir():
            roots.append(path)
            origins.append(origin)

    for path in _environment_paths(env, "GAZEBO_MODEL_PATH"):
        add(path, "GAZEBO_MODEL_PATH")
    resources.extend(_environment_paths(env, "GAZEBO_RESOURCE_PATH"))
    package_dirs: list[Path] = [Path(d) for d in (packages or {}).values()]
    if world_file is not None:
        enclosing = _enclosing_package(Path(world_file))
        if enclosing is not None:
            package_dirs.append(enclosing)
    for root in _environment_paths(env, "ROS_PACKAGE_PATH"):
        if root.is_dir():
            package_dirs.extend(_walk_packages(root))
    for prefix in _environment_paths(env, "AMENT_PREFIX_PATH"):
        share = prefix / "share"
        if share.is_dir():
            package_dirs.extend(sorted(p for p in share.iterdir() if p.is_dir()))
    seen: set[Path] = set()
    for directory in package_dirs:
        if directory in seen:
            continue
        seen.add(directory)
        name, models, media = package_exports(directory)
        for path in models:
            add(path, f"package {name or directory.name}")
        resources.extend(media)
    home_dir = Path(home) if home is not None else Path.home()
    add(home_dir / ".gazebo" / "models", "Gazebo's model cache")
    return ModelPath(roots=tuple(roots), resources=tuple(resources), origins=tuple(origins))


def _version(text: str | None) -> tuple[int, ...] | None:
    if not text or not re.fullmatch(r"\s*\d+(\.\d+)*\s*", text):
        return None
    return tuple(int(v) for v in text.strip().split("."))


def model_sdf_file(model_dir: Path) -> Path:
    """The SDF file of a model directory, chosen as Gazebo chooses it.

    ``model.config``'s ``<sdf version="X">file</sdf>`` entries: the highest version not
    newer than :data:`GAZEBO_SDF_VERSION` (if all are newer, the oldest); without
    ``model.config`` (or without ``<sdf>`` in it), ``model.sdf``.

    Raises:
        WorldError: The chosen file does not exist, or model.config is malformed.
    """
    config = model_dir / "model.config"
    chosen = model_dir / "model.sdf"
    if config.is_file():
        root = _read_xml(config)
        if root is None:
            msg = f"{config}: malformed or unreadable model.config (XML); fix it or remove it"
            raise WorldError(msg)
        entries: list[tuple[tuple[int, ...], str]] = []
        for element in root.findall("sdf"):
            name = (element.text or "").strip()
            version = _version(element.get("version")) or (0,)
            if name:
                entries.append((version, name))
        if entries:
            usable = [e for e in entries if e[0] <= GAZEBO_SDF_VERSION]
            version, name = max(usable) if usable else min(entries)
            chosen = model_dir / name
    if not chosen.is_file():
        msg = (
            f"model {model_dir.name!r} in {model_dir}: its SDF file {chosen.name!r} does not "
            "exist; add it or name the right file in model.config's <sdf>"
        )
        raise WorldError(msg)
    return chosen
