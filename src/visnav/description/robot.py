"""Robot descriptions: URDF / Xacro files with ``<gazebo>`` blocks, loaded into plain specs.

:func:`load_robot` expands Xacro (with ``$(find pkg)`` resolved by visnav's package
lookup, arguments checked), parses the URDF (:mod:`visnav.description.urdf`) and
interprets its ``<gazebo>`` sensors and plugins (:mod:`visnav.description.gazebo`).
No MuJoCo here: :mod:`visnav.sim.robot` turns a :class:`RobotDescription` into bodies.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from visnav.description.gazebo import GazeboExtensions, parse_gazebo_extensions
from visnav.description.urdf import RobotDescriptionError, Urdf, find_package, parse_urdf
from visnav.description.warning_summary import log_warning_summary
from visnav.description.xacro_locations import display_path, locating_xacro, strip_locations
from visnav.textfile import read_text

__all__ = ["RobotDescription", "expand_xacro", "load_robot"]

_LOG = logging.getLogger("visnav.description.robot")
_XACRO_LOCK = threading.Lock()  # xacro keeps its parser state in module globals


@dataclass(frozen=True)
class RobotDescription:
    """A robot: its URDF, its Gazebo sensors/plugins, the expanded XML and all warnings."""

    urdf: Urdf
    gazebo: GazeboExtensions
    xml: str = field(repr=False)
    warnings: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        """The ``<robot name>``."""
        return self.urdf.name

    @property
    def source(self) -> str:
        """The file the description was read from (or ``"<string>"``)."""
        return self.urdf.source


@contextmanager
def _xacro_find(base_dir: Path | None, packages: Mapping[str, Path | str] | None) -> Iterator[None]:
    """Make xacro's ``$(find pkg)`` use visnav's package lookup instead of ament_index."""
    from xacro import substitution_args  # noqa: PLC0415 - optional heavy import

    original = substitution_args._eval_find

    def find(pkg: str) -> str:
        path = find_package(pkg, base_dir=base_dir, packages=packages)
        if path is None:
            msg = (
                f"$(find {pkg}): package {pkg!r} not found. Fix: pass "
                f"packages={{'{pkg}': '/path/to/{pkg}'}} to load_robot"
            )
            raise RobotDescriptionError(msg)
        return str(path)

    substitution_args._eval_find = find
    try:
        yield
    finally:
        substitution_args._eval_find = original


class _ArgTable(dict[str, str]):
    """xacro's argument table, remembering the names the document declared or used."""

    def __init__(self, items: Mapping[str, str]) -> None:
        super().__init__(items)
        self.touched: set[str] = set()

    def __contains__(self, key: object) -> bool:
        if isinstance(key, str):
            self.touched.add(key)
        return super().__contains__(key)

    def __getitem__(self, key: str) -> str:
        self.touched.add(key)
        return super().__getitem__(key)


def _include_cycle(stack: Sequence[str]) -> list[str] | None:
    """The first file that includes itself (directly or not) in xacro's file stack."""
    seen: dict[str, int] = {}
    for k, name in enumerate(stack):
        if name in seen:
            return [Path(f).name for f in stack[seen[name] : k + 1]]
        seen[name] = k
    return None


def _check_args(source: str | Path, table: _ArgTable) -> None:
    unknown = sorted(set(table) - table.touched)
    if unknown:
        known = ", ".join(sorted(table.touched)) or "none"
        given = " ".join(f"{n}:={table[n]}" for n in unknown)
        msg = (
            f"{source}: unknown Xacro argument{'s' if len(unknown) > 1 else ''} "
            f"{', '.join(unknown)} (given as {given}); the file declares: {known}. "
            "Fix: use one of those names"
        )
        raise RobotDescriptionError(msg)


def expand_xacro(
    source: str | Path,
    *,
    args: Mapping[str, str] | None = None,
    packages: Mapping[str, Path | str] | None = None,
    text: str | None = None,
    strict_args: bool = False,
) -> str:
    """Run Xacro on a file (or on ``text``) with ``name:=value`` arguments.

    Args:
        source: the .xacro file (used for includes and messages).
        args: Xacro arguments, as ``xacro file name:=value`` would pass them.
        packages: package name -> directory for ``$(find pkg)``.
        text: the document, when it is not read from ``source``.
        strict_args: refuse arguments the document neither declares
            (``<xacro:arg>``) nor uses (``$(arg name)``). The ``xacro`` tool ignores
            them, as roslaunch's ``$(find xacro)`` commands rely on; ``visnav sim
            --arg`` is strict so that a typo is not silently dropped.

    Returns:
        The expanded URDF XML.

    Raises:
        RobotDescriptionError: Xacro failed (the message names the file and
            Xacro's reason; an include cycle is named as such), or, with
            ``strict_args``, an unknown argument (the known ones are listed).
    """
    return _run_xacro(source, args=args, packages=packages, text=text, strict_args=strict_args)[0]


def _run_xacro(
    source: str | Path,
    *,
    args: Mapping[str, str] | None,
    packages: Mapping[str, Path | str] | None,
    text: str | None,
    strict_args: bool,
) -> tuple[str, str]:
    """:func:`expand_xacro`, returning the XML and the XML with source locations.

    The second text carries each element's ``file:line`` (see
    :mod:`visnav.description.xacro_locations`) for :func:`parse_urdf`; the first is
    the document Xacro produces, to publish.
    """
    import xacro  # noqa: PLC0415 - optional heavy import

    path = Path(source)
    base_dir = path.resolve().parent if text is None else None
    mappings = {str(k): str(v) for k, v in (args or {}).items()}
    table = _ArgTable(mappings)
    with _XACRO_LOCK, _xacro_find(base_dir, packages), locating_xacro(display_path(source)):
        try:
            if text is None:
                doc = xacro.process_file(str(path), mappings=table)
            else:
                xacro.init_stacks(None)
                doc = xacro.parse(text)
                xacro.process_doc(doc, mappings=table)
        except RobotDescriptionError:
            raise
        except Exception as exc:
            files = [str(f) for f in getattr(xacro, "filestack", None) or [] if f]
            cycle = _include_cycle(files)
            if cycle is not None:
                msg = (
                    f"{source}: xacro include cycle: {' -> '.join(cycle)}. Fix: remove the "
                    f"<xacro:include> of {cycle[-1]} from {cycle[-2]} (or guard it)"
                )
                raise RobotDescriptionError(msg) from None
            reason = " ".join((str(exc) or type(exc).__name__).split())[:500]
            stack = " <- ".join(reversed(files[-5:]))
            where = f" (in {stack})" if stack else ""
            msg = (
                f"{source}: xacro failed{where}: {reason}. Fix: correct the Xacro; arguments "
                f"given: {mappings or 'none'}"
            )
            raise RobotDescriptionError(msg) from exc
        located: str = doc.toxml()
        strip_locations(doc)
        xml: str = doc.toxml()
    if strict_args:
        _check_args(source, table)
    return xml, located


def _is_xacro(text: str, path: Path | None) -> bool:
    if path is not None and path.name.endswith(".xacro"):
        return True
    return "xmlns:xacro" in text or "<xacro:" in text


def load_robot(
    path_or_xml: str | Path,
    *,
    args: Mapping[str, str] | None = None,
    packages: Mapping[str, Path | str] | None = None,
) -> RobotDescription:
    """Load a robot from a URDF or Xacro file, or from URDF/Xacro XML text.

    Args:
        path_or_xml: a file path, or XML text (anything starting with ``<``).
        args: Xacro ``name:=value`` arguments; one the Xacro neither declares nor uses
            is an error (ignored with a warning for plain URDF).
        packages: package name -> directory for ``package://`` and ``$(find pkg)``.

    Returns:
        The description with its Gazebo sensors and plugins and every warning
        (logged as one grouped summary, :mod:`visnav.description.warning_summary`).

    Raises:
        RobotDescriptionError: unreadable file, Xacro failure, malformed URDF,
            missing mesh or invalid ``<gazebo>`` configuration.
    """
    path: Path | None = None
    if isinstance(path_or_xml, Path) or not str(path_or_xml).lstrip().startswith("<"):
        path = Path(path_or_xml)
        text = read_text(path, what="the robot description", error=RobotDescriptionError)
        source = str(path)
    else:
        text = str(path_or_xml)
        source = "<string>"
    warnings: list[str] = []
    if _is_xacro(text, path):
        xml, located = _run_xacro(
            path if path is not None else source,
            args=args,
            packages=packages,
            text=None if path is not None else text,
            strict_args=True,
        )
    else:
        xml = located = text
        if args:
            message = f"{source}: arguments {dict(args)} given but the file is not Xacro; ignored"
            warnings.append(message)
    base_dir = path.resolve().parent if path is not None else None
    urdf = parse_urdf(located, source=source, base_dir=base_dir, packages=packages)
    gazebo = parse_gazebo_extensions(urdf)
    warnings += [*urdf.warnings, *gazebo.warnings]
    log_warning_summary(
        warnings,
        subject=f"robot {urdf.name!r} ({display_path(source)})",
        base_dir=display_path(path.parent) if path is not None else None,
        logger=_LOG,
    )
    return RobotDescription(urdf=urdf, gazebo=gazebo, xml=xml, warnings=tuple(warnings))
