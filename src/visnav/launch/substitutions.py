"""``$(...)`` substitutions of launch files, shared by the YAML format and the roslaunch import.

Forms (``$(name arg ...)``, nestable: ``$(arg $(arg which))``):

======================================  ==============================================
``$(arg x)``, ``$(var x)``              the launch argument ``x`` (ROS 1 / ROS 2 names)
``$(env X)``, ``$(env X default)``      environment variable (an error if unset and no
                                        default)
``$(optenv X)``, ``$(optenv X dflt)``   environment variable, ``""`` or ``dflt`` if unset
``$(find-pkg-share pkg)``,              a package's directory: ``visnav`` is visnav's own
``$(find pkg)``                         files (``scenarios/...``); others come from
                                        ``packages`` (``--package name=DIR``), the launch
                                        file's own package, or ``ROS_PACKAGE_PATH``
``$(dirname)``                          the directory of the current launch file
``$(anon name)``                        ``name`` made unique per launch (pid + counter)
``$(equals A B)``, ``$(not-equals A B)``  ``true`` / ``false``: the two words compared as
                                        text (ROS 2 Iron's); quote a word that may be
                                        empty: ``$(not-equals '$(arg out)' '')``
``$(eval EXPR)``                        roslaunch's expression language, evaluated safely
                                        (:mod:`visnav.launch.expression`): ``$(eval
                                        arg('model') == 'burger')``; ``$(...)`` inside it
                                        are substituted first (ROS 2's rule)
======================================  ==============================================

Text outside ``$(...)`` is kept as is; the result of a substitution is not scanned again.
"""

from __future__ import annotations

import difflib
import os
import shlex
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from visnav.launch.errors import LaunchArgError, LaunchParseError, where
from visnav.launch.expression import EvalFunctions, evaluate_expression, format_value

__all__ = [
    "SUBSTITUTIONS",
    "VIRTUAL_PACKAGES",
    "SubstitutionContext",
    "find_package",
    "has_substitution",
    "own_package",
    "ros_packages",
    "substitute",
    "visnav_share",
]

# Packages the roslaunch import understands without a directory on disk.
VIRTUAL_PACKAGES: Mapping[str, str] = {
    "gazebo_ros": "visnav://gazebo_ros",
    "xacro": "visnav://xacro",
}


def visnav_share() -> Path:
    """The directory of visnav's own files (``$(find-pkg-share visnav)``)."""
    return Path(__file__).resolve().parent.parent


def _package_name(package_xml: Path) -> str | None:
    try:
        text = package_xml.read_text(errors="replace")
    except OSError:
        return None
    start = text.find("<name>")
    end = text.find("</name>", start)
    if start < 0 or end < 0:
        return None
    return text[start + len("<name>") : end].strip() or None


def own_package(path: Path) -> tuple[str, str] | None:
    """The package a file belongs to: ``(name, directory)`` of the nearest ``package.xml``.

    Looks at most three directories up (``pkg/launch/x.launch`` -> ``pkg``).
    """
    for parent in list(path.resolve().parents)[:3]:
        xml = parent / "package.xml"
        if xml.is_file():
            name = _package_name(xml)
            if name:
                return name, str(parent)
    return None


_IGNORE_MARKERS = ("CATKIN_IGNORE", "AMENT_IGNORE", "COLCON_IGNORE")
_MAX_CRAWL_DEPTH = 8


def ros_packages(root: Path, *, max_depth: int = _MAX_CRAWL_DEPTH) -> Iterator[tuple[str, Path]]:
    """The packages under ``root`` as rospack crawls them: ``(name, directory)``.

    A directory with a ``package.xml`` is a package and is not searched further;
    hidden directories and those with a ``CATKIN_IGNORE`` (``AMENT_IGNORE``,
    ``COLCON_IGNORE``) file are skipped.
    """
    seen: set[str] = set()
    for folder, dirs, files in os.walk(root, followlinks=True):
        here = Path(folder)
        depth = len(here.relative_to(root).parts)
        real = os.path.realpath(folder)
        if real in seen:  # a symlink loop, or a directory linked twice
            dirs[:] = []
            continue
        seen.add(real)
        if any(marker in files for marker in _IGNORE_MARKERS):
            dirs[:] = []
            continue
        if "package.xml" in files:
            dirs[:] = []
            name = _package_name(here / "package.xml")
            if name:
                yield name, here
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")) if depth < max_depth else []


def _search_ros_package_path(name: str, env: Mapping[str, str]) -> Path | None:
    for root_text in env.get("ROS_PACKAGE_PATH", "").split(os.pathsep):
        if not root_text:
            continue
        root = Path(root_text).expanduser()
        direct = root / name
        if (direct / "package.xml").is_file() and _package_name(direct / "package.xml") == name:
            return direct
        for found, folder in ros_packages(root):
            if found == name:
                return folder
    return None


def find_package(
    name: str,
    *,
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    env: Mapping[str, str] | None = None,
    virtual: bool = False,
) -> str:
    """Return the directory of package ``name``.

    Args:
        name: the package name.
        packages: explicit ``name -> directory`` (searched first).
        env: environment for ``ROS_PACKAGE_PATH`` (default ``os.environ``).
        virtual: also accept the packages the roslaunch import maps itself
            (``gazebo_ros``, ``xacro``), returned as ``visnav://name``.

    Raises:
        LaunchArgError: the package is not known (the message says how to make it known).
    """
    packages = packages or {}
    if name in packages:
        return str(Path(packages[name]).resolve())
    if name == "visnav":
        return str(visnav_share())
    if virtual and name in VIRTUAL_PACKAGES:
        return VIRTUAL_PACKAGES[name]
    environ = os.environ if env is None else env
    found = _search_ros_package_path(name, environ)
    if found is not None:
        return str(found.resolve())
    known = ["visnav", *packages, *(VIRTUAL_PACKAGES if virtual else ())]
    on_path = [
        pkg
        for root in environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)
        if root
        for pkg, _ in ros_packages(Path(root).expanduser())
    ]
    close = difflib.get_close_matches(name, [*known, *on_path], n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    msg = (
        f"package {name!r} not found{hint}: visnav knows {', '.join(sorted(set(known)))} and "
        f"{len(set(on_path))} package(s) on ROS_PACKAGE_PATH; give its directory with "
        f"--package {name}=DIR or add its parent to ROS_PACKAGE_PATH"
    )
    raise LaunchArgError(msg)


@dataclass
class SubstitutionContext:
    """What substitutions can see.

    Attributes:
        args: launch arguments (and ``let`` values) in scope, name -> string value.
        file: the current launch file (for ``$(dirname)`` and error messages).
        line: the current line (error messages).
        packages: explicit package directories for ``$(find ...)``.
        env: the environment (default ``os.environ``).
        virtual_packages: accept ``gazebo_ros`` / ``xacro`` in ``$(find ...)`` (roslaunch).
        anon: names already given by ``$(anon name)`` (one launch gives one value per name).
    """

    args: dict[str, str] = field(default_factory=dict)
    file: str | None = None
    line: int | None = None
    packages: Mapping[str, str | os.PathLike[str]] = field(default_factory=dict)
    env: Mapping[str, str] | None = None
    virtual_packages: bool = False
    anon: dict[str, str] = field(default_factory=dict)

    @property
    def prefix(self) -> str:
        """``file:line: `` for messages."""
        return where(self.file, self.line)

    def environ(self) -> Mapping[str, str]:
        """The environment in use."""
        return os.environ if self.env is None else self.env

    def arg(self, name: str) -> str:
        """Return the value of launch argument ``name``.

        Raises:
            LaunchArgError: no such argument in scope (the closest one is suggested).
        """
        if name in self.args:
            return self.args[name]
        close = difflib.get_close_matches(name, list(self.args), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        known = ", ".join(sorted(self.args)) or "none"
        msg = (
            f"{self.prefix}$(arg {name}): no argument {name!r} is declared{hint} (arguments in "
            f"scope: {known}); declare it with an 'arg' entry before using it"
        )
        raise LaunchArgError(msg)


def _words(ctx: SubstitutionContext, kind: str, words: list[str], counts: tuple[int, int]) -> None:
    low, high = counts
    if not low <= len(words) <= high:
        want = str(low) if low == high else f"{low} to {high}"
        msg = f"{ctx.prefix}$({kind} {' '.join(words)}): expected {want} argument(s)"
        raise LaunchParseError(msg)


def _sub_arg(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "arg", words, (1, 1))
    return ctx.arg(words[0])


def _sub_env(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "env", words, (1, 2))
    value = ctx.environ().get(words[0])
    if value is not None:
        return value
    if len(words) == 2:
        return words[1]
    msg = (
        f"{ctx.prefix}$(env {words[0]}): environment variable {words[0]} is not set; set it, or "
        f"give a default: $(env {words[0]} DEFAULT) or $(optenv {words[0]})"
    )
    raise LaunchArgError(msg)


def _sub_optenv(ctx: SubstitutionContext, words: list[str]) -> str:
    if not words:
        _words(ctx, "optenv", words, (1, 2))
    default = " ".join(words[1:])
    return ctx.environ().get(words[0], default)


def _sub_find(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "find-pkg-share", words, (1, 1))
    try:
        found = find_package(
            words[0], packages=ctx.packages, env=ctx.environ(), virtual=ctx.virtual_packages
        )
    except LaunchArgError as exc:
        raise LaunchArgError(f"{ctx.prefix}{exc}") from None
    if isinstance(ctx.packages, dict) and words[0] != "visnav" and "://" not in found:
        # remembered: the simulator resolves the package's package:// and model:// URIs
        ctx.packages.setdefault(words[0], found)
    return found


def _sub_dirname(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "dirname", words, (0, 0))
    if ctx.file is None:
        msg = "$(dirname) used outside a launch file: there is no file to take the directory of"
        raise LaunchParseError(msg)
    return str(Path(ctx.file).resolve().parent)


def _sub_anon(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "anon", words, (1, 1))
    name = words[0]
    if name not in ctx.anon:
        ctx.anon[name] = f"{name}_{os.getpid()}_{len(ctx.anon) + 1}"
    return ctx.anon[name]


def _sub_equals(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "equals", words, (2, 2))
    return "true" if words[0] == words[1] else "false"


def _sub_not_equals(ctx: SubstitutionContext, words: list[str]) -> str:
    _words(ctx, "not-equals", words, (2, 2))
    return "false" if words[0] == words[1] else "true"


def _sub_eval_words(ctx: SubstitutionContext, words: list[str]) -> str:
    # reached only through SUBSTITUTIONS lookups; _parse handles $(eval ...) itself
    return _substitute_eval(" ".join(words), ctx)


_QUOTED = frozenset({"equals", "not-equals"})  # words may be quoted (an empty one: '')


SUBSTITUTIONS: Mapping[str, Callable[[SubstitutionContext, list[str]], str]] = {
    "arg": _sub_arg,
    "var": _sub_arg,
    "env": _sub_env,
    "optenv": _sub_optenv,
    "find-pkg-share": _sub_find,
    "find": _sub_find,
    "dirname": _sub_dirname,
    "anon": _sub_anon,
    "eval": _sub_eval_words,
    "equals": _sub_equals,
    "not-equals": _sub_not_equals,
}


def has_substitution(text: str) -> bool:
    """Whether ``text`` contains a ``$(...)`` substitution."""
    return "$(" in text


def _evaluate(body: str, ctx: SubstitutionContext) -> str:
    words = body.split()
    if not words:
        msg = f"{ctx.prefix}empty substitution '$()': expected e.g. $(arg name)"
        raise LaunchParseError(msg)
    kind, rest = words[0], words[1:]
    if kind in _QUOTED:
        try:
            rest = shlex.split(body)[1:]
        except ValueError as exc:
            msg = f"{ctx.prefix}$({body}): {exc}: close the quotes (an empty word is '')"
            raise LaunchParseError(msg) from None
    handler = SUBSTITUTIONS.get(kind)
    if handler is None:
        close = difflib.get_close_matches(kind, list(SUBSTITUTIONS), n=1)
        hint = f"; did you mean $({close[0]} ...)?" if close else ""
        msg = (
            f"{ctx.prefix}unknown substitution $({body}){hint} visnav substitutes "
            f"{', '.join(f'$({k} ...)' for k in SUBSTITUTIONS)}"
        )
        raise LaunchParseError(msg)
    return handler(ctx, rest)


def _eval_end(text: str, start: int, ctx: SubstitutionContext) -> int:
    """The index of the ``)`` closing the ``$(eval`` whose body starts at ``start``.

    Parentheses are counted outside quoted strings, so ``$(eval arg('a') + ')')`` works.
    """
    depth = 0
    quote = ""
    i = start
    while i < len(text):
        char = text[i]
        if quote:
            if char == "\\":
                i += 1
            elif char == quote:
                quote = ""
        elif char in "'\"":
            quote = char
        elif char == "(":
            depth += 1
        elif char == ")":
            if depth == 0:
                return i
            depth -= 1
        i += 1
    msg = (
        f"{ctx.prefix}unclosed $(eval ...) in {text!r}: its '(' has no matching ')' "
        "(parentheses inside quotes are not counted)"
    )
    raise LaunchParseError(msg)


def _eval_functions(ctx: SubstitutionContext) -> EvalFunctions:
    return EvalFunctions(
        arg=ctx.arg,
        find=lambda name: _sub_find(ctx, [name]),
        env=lambda name: _sub_env(ctx, [name]),
        optenv=lambda name, default: ctx.environ().get(name, default),
        anon=lambda name: _sub_anon(ctx, [name]),
        dirname=lambda: _sub_dirname(ctx, []),
    )


def _substitute_eval(body: str, ctx: SubstitutionContext) -> str:
    expression = _parse(body, 0, ctx, nested=False)[0] if has_substitution(body) else body
    value = evaluate_expression(expression, _eval_functions(ctx), prefix=ctx.prefix)
    return format_value(value)


def _parse(text: str, start: int, ctx: SubstitutionContext, *, nested: bool) -> tuple[str, int]:
    """Expand ``text`` from ``start``; inside a ``$(``, stop at its ``)``. Return (text, end)."""
    out: list[str] = []
    i = start
    while i < len(text):
        if text.startswith("$(eval", i) and text[i + 6 : i + 7] in (" ", "\t", "\n", ")"):
            end = _eval_end(text, i + 6, ctx)
            out.append(_substitute_eval(text[i + 6 : end], ctx))
            i = end + 1
            continue
        if text.startswith("$(", i):
            body, i = _parse(text, i + 2, ctx, nested=True)
            out.append(_evaluate(body, ctx))
            continue
        char = text[i]
        if nested and char == ")":
            return "".join(out), i + 1
        out.append(char)
        i += 1
    if nested:
        msg = f"{ctx.prefix}unclosed substitution in {text!r}: a '$(' has no matching ')'"
        raise LaunchParseError(msg)
    return "".join(out), i


def substitute(text: str, ctx: SubstitutionContext) -> str:
    """Expand every ``$(...)`` in ``text``.

    Raises:
        LaunchArgError: an unknown argument, an unset environment variable, an unknown package.
        LaunchParseError: an unknown substitution, a wrong number of words, an unclosed ``$(``.
    """
    if not has_substitution(text):
        return text
    return _parse(text, 0, ctx, nested=False)[0]
