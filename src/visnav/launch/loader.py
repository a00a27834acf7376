"""Load any launch file visnav reads into a :class:`LaunchDescription`.

``.yaml`` / ``.yml``: visnav's YAML format (:mod:`visnav.launch.yaml_format`);
``.launch`` / ``.xml``: roslaunch XML (:mod:`visnav.launch.roslaunch`); ``.py``:
refused (ROS 2 Python launch files are out of scope). Other names are sniffed
(``<`` first: XML). A name that is not a file is looked up among visnav's
built-in launch files (``scenarios/launch/``).
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

from visnav.launch.description import LaunchDescription, NodeSpec
from visnav.launch.errors import LaunchArgError, LaunchParseError
from visnav.launch.roslaunch import load_roslaunch
from visnav.launch.substitutions import (
    SubstitutionContext,
    find_package,
    own_package,
    visnav_share,
)
from visnav.launch.yaml_format import Scope, load_yaml_launch

__all__ = [
    "builtin_launch_files",
    "find_launch_file",
    "find_package_launch_file",
    "load_launch",
    "parse_launch_args",
]

_YAML = (".yaml", ".yml")
_XML = (".launch", ".xml")


def parse_launch_args(items: Sequence[str]) -> dict[str, str]:
    """Parse ``name:=value`` command-line arguments.

    Raises:
        LaunchArgError: an item without ``:=``, an empty name, a name given twice.
    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name.strip():
            msg = f"launch argument {item!r}: expected name:=value (e.g. robot:=car)"
            raise LaunchArgError(msg)
        name = name.strip()
        if name in out:
            msg = f"launch argument {name!r} is given twice ({out[name]!r} and {value!r})"
            raise LaunchArgError(msg)
        out[name] = value
    return out


def builtin_launch_files() -> list[str]:
    """File names of visnav's built-in launch files."""
    folder = visnav_share() / "scenarios" / "launch"
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if p.suffix in (*_YAML, *_XML))


def find_launch_file(name: str | os.PathLike[str]) -> Path:
    """Return the launch file ``name``: a path, or a built-in launch file's name.

    Raises:
        LaunchParseError: neither exists (the closest built-in name is suggested).
    """
    path = Path(name)
    if path.is_file():
        return path
    folder = visnav_share() / "scenarios" / "launch"
    for candidate in (folder / path.name, *(folder / f"{path.name}.launch{s}" for s in _YAML)):
        if str(name) == path.name and candidate.is_file():
            return candidate
    builtins = builtin_launch_files()
    close = difflib.get_close_matches(path.name, builtins, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    listing = f" (built-in launch files: {', '.join(builtins)})" if builtins else ""
    msg = f"launch file {str(name)!r} does not exist{hint}{listing}"
    raise LaunchParseError(msg)


def find_package_launch_file(
    package: str,
    name: str,
    *,
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    env: Mapping[str, str] | None = None,
) -> Path:
    """Find ``roslaunch PACKAGE FILE``'s file: ``name`` anywhere under the package's directory.

    The package comes from ``packages`` (``--package NAME=DIR``) or ``ROS_PACKAGE_PATH``
    (a directory whose ``package.xml`` names it), as ``$(find)`` finds it; the file is
    searched for by name in the whole package (hidden directories skipped), as roslaunch
    does; a name with a ``/`` is also tried as a path inside the package.

    Raises:
        LaunchArgError: the package is not found (the message says how to make it known).
        LaunchParseError: no such file in the package, or several (all listed).
    """
    root = Path(find_package(package, packages=packages, env=env))
    if "/" in name and (root / name).is_file():
        return root / name
    base = Path(name).name
    found: list[Path] = []
    seen: set[str] = set()
    for folder, dirs, files in os.walk(root, followlinks=True):
        real = os.path.realpath(folder)
        dirs[:] = [] if real in seen else sorted(d for d in dirs if not d.startswith("."))
        if real in seen:  # a symlink loop
            continue
        seen.add(real)
        if base in files:
            found.append(Path(folder) / base)
    if len(found) == 1:
        return found[0]
    if found:
        listing = ", ".join(str(f.relative_to(root)) for f in found)
        msg = (
            f"package {package!r} ({root}) has {len(found)} files named {base!r}: {listing}; "
            "give the file's path instead of PACKAGE FILE"
        )
        raise LaunchParseError(msg)
    launch_files = sorted(
        str(f.relative_to(root))
        for pattern in ("*.launch", "*.launch.xml", "*.launch.yaml")
        for f in root.rglob(pattern)
    )
    close = difflib.get_close_matches(base, [Path(f).name for f in launch_files], n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    shown = ", ".join(launch_files[:12]) + (" ..." if len(launch_files) > 12 else "")
    msg = (
        f"package {package!r} ({root}) has no file named {base!r}{hint} (its launch files: "
        f"{shown or 'none'})"
    )
    raise LaunchParseError(msg)


def _kind(path: Path) -> str:
    name = path.name
    if name.endswith(".py"):
        msg = (
            f"{path}: ROS 2 Python launch files are out of scope: write a visnav YAML launch "
            "file (docs/launch.md); roslaunch XML (.launch) files are imported"
        )
        raise LaunchParseError(msg)
    if path.suffix in _YAML:
        return "yaml"
    if path.suffix in _XML:
        return "xml"
    try:
        head = path.read_text(errors="replace")[:256].lstrip()
    except OSError:
        return "yaml"
    return "xml" if head.startswith("<") else "yaml"


class _Loader:
    """Loads a file of either format; includes come back here."""

    def __init__(self, description: LaunchDescription, *, skip_unmapped: bool = False) -> None:
        self.description = description
        self.skip_unmapped = skip_unmapped

    def include(
        self, path: str, args: Mapping[str, str], scope: Scope, chain: tuple[str, ...]
    ) -> list[NodeSpec]:
        return self.load(Path(path), args, scope, chain, top=False)

    def load(
        self,
        path: Path,
        args: Mapping[str, str],
        scope: Scope,
        chain: tuple[str, ...],
        *,
        top: bool,
    ) -> list[NodeSpec]:
        resolved = path.resolve()
        for link in chain:
            if Path(link.rsplit(":", 1)[0]).resolve() == resolved:
                cycle = " -> ".join([*chain, str(path)])
                msg = f"{path}: the launch file includes itself ({cycle})"
                raise LaunchParseError(msg)
        if not path.is_file():
            via = f" (included from {chain[-1]})" if chain else ""
            msg = f"launch file {path} does not exist{via}"
            raise LaunchParseError(msg)
        own = own_package(path)
        packages = scope.ctx.packages
        if own is not None and isinstance(packages, dict):
            packages.setdefault(*own)
        description = self.description if top else None
        if _kind(path) == "xml":
            return load_roslaunch(
                path,
                args,
                scope,
                chain=chain,
                include=self.include,
                description=description,
                skip_unmapped=self.skip_unmapped,
            )
        return load_yaml_launch(
            path, args, scope, chain=chain, include=self.include, description=description
        )


def load_launch(
    path: str | os.PathLike[str],
    args: Mapping[str, str] | None = None,
    *,
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    env: Mapping[str, str] | None = None,
    skip_unmapped: bool = False,
) -> LaunchDescription:
    """Load a launch file (YAML or roslaunch XML) with its includes.

    Args:
        path: the file, or the name of a built-in launch file.
        args: ``name -> value`` launch arguments (strings, as ``name:=value`` gives them).
        packages: package directories for ``$(find-pkg-share name)`` / ``$(find name)``.
        env: environment for ``$(env)`` and ``ROS_PACKAGE_PATH`` (default ``os.environ``).
        skip_unmapped: roslaunch files: leave out the elements and nodes visnav cannot map
            (each one a note) instead of refusing the file.

    Returns:
        The validated description.

    Raises:
        LaunchError: the file does not parse, an arg is missing or unknown, a node is
            unknown, an element cannot be mapped (subclasses say which).
    """
    file = find_launch_file(path)
    description = LaunchDescription(source=str(file))
    folders = {k: str(Path(v).expanduser().resolve()) for k, v in (packages or {}).items()}
    ctx = SubstitutionContext(packages=folders, env=env)
    loader = _Loader(description, skip_unmapped=skip_unmapped)
    scope = Scope(ctx=ctx)
    description.nodes = loader.load(file, dict(args or {}), replace(scope), (), top=True)
    description.validate()
    return description
