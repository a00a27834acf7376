"""SDF ``<include>``, ``model://`` mesh URIs and material scripts, resolved as Gazebo Classic does.

:class:`SdfResources` is what the SDF world parser asks when a document refers to a file
outside itself:

* :meth:`SdfResources.include` reads the model an ``<include><uri>`` names
  (``model://NAME`` through the :class:`~visnav.description.model_path.ModelPath`, or a
  path to a model directory or SDF file) and returns its top element (``<model>``, or
  ``<light>`` for ``model://sun``) with the include's ``<name>``, ``<pose>`` and
  ``<static>`` applied, as SDFormat does (the include's pose replaces the model's);
* :meth:`SdfResources.mesh_file` resolves a mesh ``<uri>``: ``model://NAME/path``,
  ``file://`` (absolute, or relative to the SDF file), ``package://pkg/path`` and plain
  paths;
* :meth:`SdfResources.script_colour` turns ``<script><uri>...</uri><name>N</name>`` into a
  colour (Gazebo's own ``gazebo.material`` built in, a model's ``.material`` files read).

A model that is not found is recorded in :attr:`SdfResources.missing` (Gazebo would try to
download it); the parser reports all of them at once.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from visnav.description.errors import WorldError
from visnav.description.gazebo_materials import GAZEBO_COLOURS, read_material_scripts
from visnav.description.model_path import ModelPath, model_sdf_file, split_model_uri
from visnav.description.urdf_model import find_package

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

__all__ = ["BUILTIN_MODELS", "Included", "SdfResources", "missing_models_error"]

BUILTIN_MODELS = ("ground_plane", "sun")
"""Models visnav knows without a model path (Gazebo ships them in its own model directory)."""

_MAX_INCLUDE_DEPTH = 16
_MAX_SDF_BYTES = 64 * 1024 * 1024

RGBA = tuple[float, float, float, float]


@dataclass(frozen=True)
class Included:
    """The element an ``<include>`` brings in, and the directory its relative paths start from."""

    element: ET.Element
    base_dir: Path
    source: str


@dataclass
class SdfResources:
    """Resolves includes, mesh URIs and material scripts for one world (see the module doc).

    Attributes:
        model_path: Where ``model://`` names are looked up.
        packages: Package name -> directory for ``package://`` URIs.
        parse: Parses an SDF document's text (with its source name) into its root element.
        missing: ``(uri, where)`` of every model that was not found, in order.
        warnings: Problems found while reading material scripts (missing textures, ...).
    """

    model_path: ModelPath
    parse: Callable[[str, str], ET.Element]
    packages: Mapping[str, str | Path] = field(default_factory=dict)
    missing: list[tuple[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    _depth: int = 0
    _scripts: dict[tuple[tuple[Path, ...], str], RGBA | None] = field(default_factory=dict)

    # includes ---------------------------------------------------------------

    def model_dir(self, uri: str, base_dir: Path | None) -> Path | None:
        """The model directory (or SDF file) an include URI names, or None if not found."""
        if uri.startswith("model://"):
            name, rest = split_model_uri(uri)
            found = self.model_path.find(name)
            return found / rest if found is not None and rest else found
        if uri.startswith(("http://", "https://")):
            return None
        path = Path(uri.removeprefix("file://"))
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        return path if path.exists() else None

    def include(
        self, element: ET.Element, uri: str, base_dir: Path | None, where: str
    ) -> Included | None:
        """Read the model an ``<include>`` names, with its name/pose/static applied.

        Returns:
            The included element, or None when the model was not found (recorded in
            :attr:`missing`; ``model://ground_plane`` / ``model://sun`` are not recorded:
            the caller builds Gazebo's own).

        Raises:
            WorldError: The model's SDF is missing or malformed, or includes nest deeper
                than 16 levels (an include cycle).
        """
        target = self.model_dir(uri, base_dir)
        if target is None:
            name = split_model_uri(uri)[0] if uri.startswith("model://") else uri
            if name not in BUILTIN_MODELS:
                self.missing.append((uri, where))
            return None
        if self._depth >= _MAX_INCLUDE_DEPTH:
            msg = f"{where}: <include> of {uri!r} nests {_MAX_INCLUDE_DEPTH} levels deep (cycle?)"
            raise WorldError(msg)
        sdf_file = model_sdf_file(target) if target.is_dir() else target
        try:
            size = sdf_file.stat().st_size
            if size > _MAX_SDF_BYTES:
                msg = f"{sdf_file}: {size} bytes, larger than {_MAX_SDF_BYTES}; not read"
                raise WorldError(msg)
            text = sdf_file.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            msg = f"{where}: <include> {uri!r}: {sdf_file} cannot be read ({exc.strerror or exc})"
            raise WorldError(msg) from None
        root = self.parse(text, str(sdf_file))
        top = next((c for c in root if c.tag in ("model", "light", "actor")), None)
        if root.tag != "sdf" or top is None:
            msg = (
                f"{sdf_file}: included by {where} ({uri!r}) has no <sdf><model> (or <light>); "
                "an included file must hold one model"
            )
            raise WorldError(msg)
        _apply_overrides(element, top)
        return Included(element=top, base_dir=sdf_file.parent, source=str(sdf_file))

    def nested(self) -> _Nesting:
        """A context manager counting include depth (cycle protection)."""
        return _Nesting(self)

    # meshes -------------------------------------------------------------------

    def mesh_file(self, uri: str, base_dir: Path | None, where: str) -> Path | None:
        """The mesh file a ``<mesh><uri>`` names; None when its model is not found (recorded).

        Raises:
            WorldError: The URI is an unsupported scheme, or the file is not where it points.
        """
        if uri.startswith("model://"):
            name, rest = split_model_uri(uri)
            found = self.model_path.find(name)
            if found is None:
                self.missing.append((f"model://{name}", where))
                return None
            path = found / rest
        elif uri.startswith("package://"):
            package, _, rest = uri[len("package://") :].partition("/")
            root = find_package(package, base_dir=base_dir, packages=self.packages)
            found = root if root is not None else self.model_path.find(package)
            if found is None:
                msg = (
                    f"{where}: mesh {uri!r}: package {package!r} not found; pass "
                    f"packages={{'{package}': DIR}} (visnav sim --package) or set ROS_PACKAGE_PATH"
                )
                raise WorldError(msg)
            path = found / rest
        elif uri.startswith(("http://", "https://")):
            msg = f"{where}: mesh {uri!r}: web URIs are not fetched; download it and use a path"
            raise WorldError(msg)
        else:
            path = self.relative_file(uri.removeprefix("file://"), base_dir)
        if not path.is_file():
            msg = f"{where}: mesh file {uri!r} does not exist (looked at {path})"
            raise WorldError(msg)
        return path

    def relative_file(self, text: str, base_dir: Path | None) -> Path:
        """A relative file path found as Gazebo finds it (the first candidate if none exists).

        Absolute paths are kept; others are looked for beside the SDF file, then in the
        resource paths (``GAZEBO_RESOURCE_PATH``, packages' ``gazebo_media_path``) and
        the model path directories.
        """
        path = Path(text)
        if path.is_absolute():
            return path
        candidates = [base_dir / path] if base_dir is not None else [path]
        candidates += [root / path for root in self.model_path.resources]
        candidates += [root / path for root in self.model_path.roots]
        return next((c for c in candidates if c.is_file()), candidates[0])

    # materials ----------------------------------------------------------------

    def script_colour(self, uris: list[str], name: str, base_dir: Path | None) -> RGBA | None:
        """Colour of material ``name`` from its script URIs (None: not found anywhere)."""
        paths: list[Path] = []
        for uri in uris:
            if uri.startswith("model://"):
                model, rest = split_model_uri(uri)
                found = self.model_path.find(model)
                if found is not None:
                    paths.append(found / rest)
            elif uri.startswith(("file://media/", "file://media\\")):
                resource = self.model_path.resource(uri[len("file://") :])
                if resource is not None:
                    paths.append(resource)
            else:
                path = Path(uri.removeprefix("file://"))
                if not path.is_absolute() and base_dir is not None:
                    path = base_dir / path
                paths.append(path)
        key = (tuple(p for p in paths if p.exists()), name)
        if key not in self._scripts:
            scripts = read_material_scripts(key[0], [name]) if key[0] else None
            self._scripts[key] = scripts.colours.get(name) if scripts is not None else None
            if scripts is not None:
                self.warnings.extend(scripts.warnings)
        return self._scripts[key] or GAZEBO_COLOURS.get(name)


class _Nesting:
    def __init__(self, resources: SdfResources) -> None:
        self.resources = resources

    def __enter__(self) -> None:
        self.resources._depth += 1

    def __exit__(self, *exc: object) -> None:
        self.resources._depth -= 1


def _apply_overrides(include: ET.Element, top: ET.Element) -> None:
    """The include's ``<name>``, ``<pose>`` and ``<static>`` replace the model's own."""
    name = (include.findtext("name") or "").strip()
    if name:
        top.set("name", name)
    for tag in ("pose", "static"):
        override = include.find(tag)
        if override is None:
            continue
        for old in top.findall(tag):
            top.remove(old)
        top.insert(0, override)


def missing_models_error(
    missing: list[tuple[str, str]], model_path: ModelPath, source: str
) -> WorldError:
    """One error naming every model that was not found, and how to make them found."""
    names: dict[str, list[str]] = {}
    for uri, where in missing:
        names.setdefault(uri, []).append(where)
    listed = "; ".join(f"{uri} (at {wheres[0]})" for uri, wheres in names.items())
    msg = (
        f"{source}: {len(names)} model(s) not found: {listed}. Gazebo would download them "
        "from its online model database; visnav does not. Searched: "
        f"{model_path.describe()}. Fix: put the models in a directory and add it to "
        "GAZEBO_MODEL_PATH (colon-separated), or give the package that exports them "
        "(<gazebo_ros gazebo_model_path=...> in its package.xml) with --package NAME=DIR / "
        "packages=; or load the rest with skip_missing_models "
        "(visnav sim --skip-missing-models)"
    )
    return WorldError(msg)
