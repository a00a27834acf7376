"""roslaunch (ROS 1) XML import: the parts of a ``.launch`` file that map onto visnav.

Read the way roslaunch reads it: ``<arg>`` (``default``, fixed ``value``, or
required), ``$(arg)``, ``$(find)``, ``$(env)``, ``$(optenv)``, ``$(dirname)``,
``$(anon)``, ``$(eval)`` (:mod:`visnav.launch.expression`); ``if`` / ``unless`` on every
element; ``<group ns>``; ``<remap>``
(scoped to its group, inherited by includes); ``<param>`` (``value`` with
roslaunch's type guessing or ``type``, ``textfile``, ``command`` running xacro)
and ``<rosparam command="load">`` fill one parameter server, which is read after
the whole file is loaded, as roslaunch sets every parameter before it starts
nodes. ``/use_sim_time`` becomes every node's ``use_sim_time``.

``<include>`` of ``$(find gazebo_ros)/launch/empty_world.launch`` becomes the
visnav simulator node; other roslaunch files are imported recursively, visnav
YAML files are loaded as such. ``<node>`` elements map as
:mod:`visnav.launch.ros_nodes` describes.

Everything that cannot be mapped (another ``<node>``, ``<env>``, ``<machine>``,
``<test>``, a ``command`` that is not xacro, ...) is collected, and one
:class:`~visnav.launch.errors.RoslaunchImportError` lists all of it with the
lines and what can be mapped (or, with ``skip_unmapped``, each becomes a note and
the rest imports). Every package the import knows (``--package``, the ``$(find)`` ed
ones, the launch files' own) reaches the ``sim`` node as its ``packages`` parameter,
for ``package://`` meshes and ``model://`` models. ROS 2 launch files (Python, or XML
with ``exec=``) are out of scope.
"""

from __future__ import annotations

import contextlib
import difflib
import os
import shlex
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from visnav.launch.description import LaunchDescription, NodeSpec
from visnav.launch.errors import (
    LaunchArgError,
    LaunchError,
    LaunchParseError,
    RoslaunchImportError,
    where,
)
from visnav.launch.ros_nodes import (
    EMPTY_WORLD_ARGS,
    MAPPABLE,
    ParamServer,
    RosNode,
    empty_world_node,
    fold_spawns,
    translate_node,
)
from visnav.launch.ros_planner_nodes import translation_order
from visnav.launch.roslaunch_xml import XmlElement, parse_xml
from visnav.launch.substitutions import (
    VIRTUAL_PACKAGES,
    SubstitutionContext,
    own_package,
    substitute,
)
from visnav.launch.yaml_format import IncludeLoader, Scope, join_namespace, parse_bool
from visnav.safe_yaml import load_yaml
from visnav.textfile import TextFileError, read_text

__all__ = ["XmlElement", "load_roslaunch", "parse_xml"]

_EMPTY_WORLD = f"{VIRTUAL_PACKAGES['gazebo_ros']}/launch/empty_world.launch"
_XACRO_NAMES = ("xacro", "xacro.py")
# visnav children always print to the launch's terminal: output="screen" is what happens anyway
_SILENT_NODE_ATTRS = ("output",)
_IGNORED_NODE_ATTRS = ("cwd", "launch-prefix", "clear_params")
_NODE_ATTRS = (
    "pkg",
    "type",
    "name",
    "ns",
    "args",
    "respawn",
    "respawn_delay",
    "required",
    "if",
    "unless",
    *_SILENT_NODE_ATTRS,
    *_IGNORED_NODE_ATTRS,
)


# --------------------------------------------------------------------------- import state
@dataclass
class _Import:
    """State shared by a roslaunch file and the roslaunch files it includes."""

    params: ParamServer
    include: IncludeLoader
    items: list[RosNode | NodeSpec] = field(default_factory=list)
    issues: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    packages: dict[str, str] = field(default_factory=dict)

    def issue(self, file: str, line: int | None, text: str) -> None:
        self.issues.append(f"{where(file, line)}{text}")


@dataclass
class _RosScope:
    """Namespace and remaps of a group (args are per file in roslaunch, not per group)."""

    ns: str
    remaps: tuple[tuple[str, str], ...]


def _resolve_param(ns: str, name: str, node_fqn: str | None) -> str:
    """roslaunch's names: inside a ``<node>`` relative and ``~`` names are the node's own."""
    if name.startswith("/"):
        return name
    if node_fqn is not None or name.startswith("~"):
        base = node_fqn or ns
        return f"{base.rstrip('/')}/{name.lstrip('~').lstrip('/')}"
    return f"{ns.rstrip('/')}/{name}"


def _ros_remap(name: str) -> str:
    """ROS 1 private names (``~x``) in the ROS 2 rule grammar (``~/x``)."""
    return "~/" + name[1:].lstrip("/") if name.startswith("~") else name


def _guess_type(value: str) -> Any:
    """roslaunch's type guessing for ``<param value=...>`` without ``type``."""
    text = value.strip()
    with contextlib.suppress(ValueError):
        return int(text)
    with contextlib.suppress(ValueError):
        return float(text)
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return value


class _File:
    """Evaluates one roslaunch file."""

    def __init__(
        self,
        state: _Import,
        path: Path,
        given: Mapping[str, str],
        scope: _RosScope,
        ctx: SubstitutionContext,
        chain: tuple[str, ...],
        passed_through: frozenset[str] = frozenset(),
    ) -> None:
        self.passed_through = passed_through
        self.state = state
        self.path = path
        self.source = str(path)
        self.given = dict(given)
        self.declared: dict[str, int] = {}
        self.scope = scope
        self.ctx = replace(ctx, args={}, file=str(path), line=None, virtual_packages=True)
        self.chain = chain

    def at(self, line: int | None) -> str:
        return where(self.source, line)

    def sub(self, text: str, line: int) -> str:
        self.ctx.line = line
        return substitute(text, self.ctx)

    def attr(self, element: XmlElement, name: str, default: str | None = None) -> str | None:
        value = element.attrs.get(name)
        return default if value is None else self.sub(value, element.line)

    def need(self, element: XmlElement, name: str) -> str:
        value = self.attr(element, name)
        if value is None:
            msg = f"{self.at(element.line)}<{element.tag}> needs the attribute {name!r}"
            raise LaunchParseError(msg)
        return value

    def enabled(self, element: XmlElement) -> bool:
        at = self.at(element.line)
        if "if" in element.attrs and not parse_bool(self.attr(element, "if"), "if", at):
            return False
        return not (
            "unless" in element.attrs and parse_bool(self.attr(element, "unless"), "unless", at)
        )

    # ---------------------------------------------------------------- elements
    def run(self, root: XmlElement) -> None:
        if root.tag != "launch":
            msg = f"{self.at(root.line)}the root element is <{root.tag}>: expected <launch>"
            raise LaunchParseError(msg)
        self.children(root, self.scope)
        unused = sorted(set(self.given) - set(self.declared) - self.passed_through)
        if unused:
            name = unused[0]
            close = difflib.get_close_matches(name, list(self.declared), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            declared = ", ".join(sorted(self.declared)) or "none"
            via = f" (included from {self.chain[-1]})" if self.chain else ""
            msg = (
                f"{self.source}: argument {name}:={self.given[name]!r} was given but the file "
                f"declares no <arg name={name!r}>{hint} (declared: {declared}){via}"
            )
            raise LaunchArgError(msg)

    def children(self, element: XmlElement, scope: _RosScope) -> None:
        for child in element.children:
            if not self.enabled(child):
                if child.tag == "arg" and "name" in child.attrs:
                    self.declared.setdefault(child.attrs["name"], child.line)
                continue
            handler = getattr(self, f"on_{child.tag}", None)
            if handler is None:
                self.state.issue(
                    self.source, child.line, f"<{child.tag}> has no visnav counterpart"
                )
                continue
            handler(child, scope)

    def on_arg(self, element: XmlElement, scope: _RosScope) -> None:
        del scope
        name = self.need(element, "name")
        line = element.line
        if name in self.declared:
            first = self.declared[name]
            msg = f"{self.at(line)}<arg name={name!r}> is declared twice (first at line {first})"
            raise LaunchParseError(msg)
        self.declared[name] = line
        if "value" in element.attrs:
            if name in self.given:
                msg = (
                    f"{self.at(line)}arg {name!r} has a fixed value= and cannot be set to "
                    f"{self.given[name]!r}; make it default= to allow that"
                )
                raise LaunchArgError(msg)
            value = self.attr(element, "value") or ""
        elif name in self.given:
            value = self.given[name]
        elif "default" in element.attrs:
            value = self.attr(element, "default") or ""
        else:
            unused = [g for g in self.given if g not in self.declared]
            close = difflib.get_close_matches(name, unused, n=1)
            hint = f"; you gave {close[0]}:=..., did you mean {name}:=...?" if close else ""
            doc = element.attrs.get("doc")
            msg = (
                f"{self.at(line)}missing arg {name!r} (no default"
                + (f": {doc}" if doc else "")
                + f"): give it as {name}:=VALUE{hint}"
            )
            raise LaunchArgError(msg)
        self.ctx.args[name] = value

    def on_group(self, element: XmlElement, scope: _RosScope) -> None:
        inner = replace(scope)  # a copy: <remap> inside the group stays inside it
        if "ns" in element.attrs:
            ns = self.attr(element, "ns") or ""
            inner.ns = join_namespace(scope.ns, ns, self.at(element.line))
        self.children(element, inner)

    def on_remap(self, element: XmlElement, scope: _RosScope) -> None:
        pair = (_ros_remap(self.need(element, "from")), _ros_remap(self.need(element, "to")))
        # scoped to the enclosing element: children() passes the same scope object on
        scope.remaps = (pair, *scope.remaps)

    def on_param(self, element: XmlElement, scope: _RosScope, node_fqn: str | None = None) -> None:
        line = element.line
        name = _resolve_param(scope.ns, self.need(element, "name"), node_fqn)
        value = self.param_value(element)
        if value is not None:
            self.state.params.set(name, value, f"{self.source}:{line}")

    def param_value(self, element: XmlElement) -> Any:
        line = element.line
        kinds = [k for k in ("value", "textfile", "command", "binfile") if k in element.attrs]
        if len(kinds) != 1:
            msg = (
                f"{self.at(line)}<param name={element.attrs.get('name')!r}> needs exactly one of "
                "value=, textfile=, command="
            )
            raise LaunchParseError(msg)
        kind = kinds[0]
        text = self.attr(element, kind) or ""
        if kind == "binfile":
            self.state.issue(
                self.source, line, "<param binfile=...> (binary parameters) is not supported"
            )
            return None
        if kind == "textfile":
            try:
                return read_text(text, what="the <param textfile=...>")
            except TextFileError as exc:
                raise LaunchParseError(f"{self.at(line)}{exc}") from None
        if kind == "command":
            return self.run_command(text, line)
        return self.typed(text, element.attrs.get("type"), line)

    def typed(self, text: str, kind: str | None, line: int) -> Any:
        if kind in (None, "auto"):
            return _guess_type(text)
        if kind in ("str", "string"):
            return text
        try:
            if kind == "int":
                return int(text.strip())
            if kind == "double":
                return float(text.strip())
        except ValueError:
            msg = f"{self.at(line)}<param type={kind!r}> value {text!r} is not a {kind}"
            raise LaunchParseError(msg) from None
        if kind in ("bool", "boolean"):
            return parse_bool(text.strip(), "bool param", self.at(line))
        if kind == "yaml":
            return load_yaml(
                text, source=f"{self.at(line)}<param>", what="its YAML", error=LaunchParseError
            )
        msg = f"{self.at(line)}<param type={kind!r}>: expected str, int, double, bool, yaml or auto"
        raise LaunchParseError(msg)

    def run_command(self, command: str, line: int) -> str | None:
        words = shlex.split(command)
        if words[:3] == ["rosrun", "xacro", "xacro"] or words[:3] == [
            "rosrun",
            "xacro",
            "xacro.py",
        ]:
            words = ["xacro", *words[3:]]
        if not words or Path(words[0]).name not in _XACRO_NAMES:
            self.state.issue(
                self.source,
                line,
                f"<param command={command!r}>: visnav runs only xacro commands "
                "('$(find xacro)/xacro FILE name:=value')",
            )
            return None
        mappings: dict[str, str] = {}
        files: list[str] = []
        for word in words[1:]:
            if ":=" in word:
                key, _, value = word.partition(":=")
                mappings[key] = value
            elif word in ("--inorder", "-i", "--xacro-ns", "--legacy") or word.startswith(
                "--check"
            ):
                continue
            elif word.startswith("-"):
                self.state.issue(self.source, line, f"xacro option {word!r} is not supported")
                return None
            else:
                files.append(word)
        if len(files) != 1:
            msg = f"{self.at(line)}xacro command {command!r}: expected one input file, got {files}"
            raise LaunchParseError(msg)
        from visnav.description.robot import expand_xacro  # noqa: PLC0415 - heavy, only when used

        try:
            return expand_xacro(files[0], args=mappings, packages=dict(self.state.packages))
        except LaunchError:
            raise
        except Exception as exc:  # RobotDescriptionError and friends  # noqa: BLE001
            msg = f"{self.at(line)}{exc}"
            raise LaunchParseError(msg) from None

    def on_rosparam(
        self, element: XmlElement, scope: _RosScope, node_fqn: str | None = None
    ) -> None:
        line = element.line
        command = self.attr(element, "command", "load")
        if command != "load":
            self.state.issue(
                self.source, line, f"<rosparam command={command!r}> (only load is supported)"
            )
            return
        ns_attr = self.attr(element, "ns", "") or ""
        ns = _resolve_param(scope.ns, ns_attr, node_fqn) if ns_attr else (node_fqn or scope.ns)
        if "file" in element.attrs:
            path = self.attr(element, "file") or ""
            try:
                text = read_text(path, what="the <rosparam file=...>")
            except TextFileError as exc:
                raise LaunchParseError(f"{self.at(line)}{exc}") from None
        else:
            text = element.text
            if parse_bool(self.attr(element, "subst_value", "false"), "subst_value", self.at(line)):
                text = self.sub(text, line)
        data = (
            load_yaml(
                text, source=f"{self.at(line)}<rosparam>", what="its YAML", error=LaunchParseError
            )
            if text.strip()
            else None
        )
        if data is None:
            return
        if not isinstance(data, dict):
            if "param" not in element.attrs:
                msg = f"{self.at(line)}<rosparam> without param= must hold a YAML mapping"
                raise LaunchParseError(msg)
            name = _resolve_param(ns, self.attr(element, "param") or "", None)
            self.state.params.set(name, data, f"{self.source}:{line}")
            return
        if "param" in element.attrs:
            ns = _resolve_param(ns, self.attr(element, "param") or "", None)
        self.state.params.load(ns, data, f"{self.source}:{line}")

    def on_include(self, element: XmlElement, scope: _RosScope) -> None:
        line = element.line
        file_text = self.need(element, "file")
        inner = scope
        if "ns" in element.attrs:
            inner = replace(
                scope, ns=join_namespace(scope.ns, self.attr(element, "ns") or "", self.at(line))
            )
        args: dict[str, str] = {}
        at = self.at(line)
        pass_all = parse_bool(self.attr(element, "pass_all_args", "false"), "pass_all_args", at)
        if pass_all:
            args.update(self.ctx.args)
        passed = frozenset(self.ctx.args) if pass_all else frozenset()
        for child in element.children:
            if not self.enabled(child):
                continue
            if child.tag != "arg":
                self.state.issue(
                    self.source,
                    child.line,
                    f"<{child.tag}> inside <include> (only <arg> is mapped)",
                )
                continue
            name = self.need(child, "name")
            value = self.attr(child, "value", self.attr(child, "default"))
            if value is None:
                msg = f"{self.at(child.line)}<arg name={name!r}> in <include> needs value="
                raise LaunchParseError(msg)
            args[name] = value
        chain = (*self.chain, f"{self.source}:{line}")
        if file_text.startswith(VIRTUAL_PACKAGES["gazebo_ros"]):
            self.gazebo_include(file_text, args, inner, line)
            return
        path = Path(file_text)
        if file_text.endswith((".launch", ".xml")):
            # ROS 1 files (also ROBOTIS' includes/description.launch.xml) share this file's
            # parameter server; ROS 2 XML is refused at its first <node exec=...>
            load_roslaunch_file(self.state, path, args, inner, self.ctx, chain, passed)
            return
        yaml_scope = Scope(
            ctx=replace(self.ctx, args={}),
            namespace=inner.ns,
            remaps=inner.remaps,
            passed_through=passed,
        )
        self.state.items.extend(self.state.include(str(path), args, yaml_scope, chain))

    def gazebo_include(
        self, file_text: str, args: dict[str, str], scope: _RosScope, line: int
    ) -> None:
        if file_text != _EMPTY_WORLD:
            shown = file_text.replace(VIRTUAL_PACKAGES["gazebo_ros"], "$(find gazebo_ros)")
            self.state.issue(
                self.source,
                line,
                f"<include file={shown!r}> (of gazebo_ros, only launch/empty_world.launch maps)",
            )
            return
        unknown = sorted(set(args) - set(EMPTY_WORLD_ARGS))
        for name in unknown:
            close = difflib.get_close_matches(name, list(EMPTY_WORLD_ARGS), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            msg = (
                f"{self.at(line)}empty_world.launch declares no arg {name!r}{hint} (it takes "
                f"{', '.join(EMPTY_WORLD_ARGS)})"
            )
            raise LaunchArgError(msg)
        spec, issues, notes = empty_world_node(
            {**EMPTY_WORLD_ARGS, **args}, scope.ns, f"{self.source}:{line}", self.state.params
        )
        for text in issues:
            self.state.issue(self.source, line, text)
        self.state.notes.extend(notes)
        if spec is not None:
            self.state.items.append(spec)

    def on_node(self, element: XmlElement, scope: _RosScope) -> None:
        line = element.line
        if "exec" in element.attrs:
            msg = (
                f"{self.at(line)}<node exec=...> is ROS 2 launch XML: visnav imports ROS 1 "
                "roslaunch XML only; write a visnav YAML launch file instead (docs/launch.md)"
            )
            raise LaunchParseError(msg)
        for attr in element.attrs:
            if attr not in _NODE_ATTRS:
                self.state.issue(self.source, line, f"<node {attr}=...> is not supported")
        ignored = [a for a in _IGNORED_NODE_ATTRS if a in element.attrs]
        pkg, kind = self.need(element, "pkg"), self.need(element, "type")
        name = self.need(element, "name")
        ns = join_namespace(scope.ns, self.attr(element, "ns", "") or "", self.at(line))
        fqn = f"{ns.rstrip('/')}/{name}"
        if ignored:
            self.state.notes.append(f"{self.at(line)}node {fqn}: ignored {', '.join(ignored)}")
        node_scope = replace(scope, ns=ns)
        own_remaps: list[tuple[str, str]] = []
        for child in element.children:
            if not self.enabled(child):
                continue
            if child.tag == "param":
                self.on_param(child, node_scope, fqn)
            elif child.tag == "rosparam":
                self.on_rosparam(child, node_scope, fqn)
            elif child.tag == "remap":
                own_remaps.append(
                    (_ros_remap(self.need(child, "from")), _ros_remap(self.need(child, "to")))
                )
            else:
                self.state.issue(
                    self.source, child.line, f"<{child.tag}> inside <node> is not supported"
                )
        at = self.at(line)
        self.state.items.append(
            RosNode(
                pkg=pkg,
                type=kind,
                name=name,
                namespace=ns,
                args=shlex.split(self.attr(element, "args", "") or ""),
                remaps=(*reversed(own_remaps), *scope.remaps),
                respawn=parse_bool(self.attr(element, "respawn", "false"), "respawn", at),
                respawn_delay=float(self.attr(element, "respawn_delay", "0") or 0),
                required=parse_bool(self.attr(element, "required", "false"), "required", at),
                source=f"{self.source}:{line}",
            )
        )


def load_roslaunch_file(
    state: _Import,
    path: Path,
    args: Mapping[str, str],
    scope: _RosScope,
    ctx: SubstitutionContext,
    chain: tuple[str, ...],
    passed_through: frozenset[str] = frozenset(),
) -> None:
    """Evaluate one roslaunch file into ``state`` (used for the top file and includes)."""
    seen = [c.rsplit(":", 1)[0] for c in chain]
    if str(path) in seen:
        msg = f"{path}: included from itself ({' -> '.join([*chain, str(path)])})"
        raise LaunchParseError(msg)
    try:
        text = read_text(path, what="the launch file")
    except TextFileError as exc:
        via = f" (included from {chain[-1]})" if chain else ""
        raise LaunchParseError(f"{exc}{via}") from None
    own = own_package(path)
    if own is not None:
        state.packages.setdefault(*own)
        if isinstance(ctx.packages, dict):
            ctx.packages.setdefault(*own)
    root = parse_xml(text, str(path))
    file = _File(state, path, args, _RosScope(scope.ns, scope.remaps), ctx, chain, passed_through)
    file.run(root)


def load_roslaunch(
    path: str | os.PathLike[str],
    args: Mapping[str, str],
    scope: Scope,
    *,
    chain: tuple[str, ...],
    include: IncludeLoader,
    description: LaunchDescription | None = None,
    skip_unmapped: bool = False,
) -> list[NodeSpec]:
    """Import a roslaunch XML file (and what it includes) as visnav nodes.

    Args:
        path: the ``.launch`` / ``.xml`` file.
        args: ``name:=value`` arguments for it.
        scope: namespace and remaps it inherits (from a YAML include), and the
            substitution context (packages, environment).
        chain: the include chain so far, for messages.
        include: loads non-roslaunch includes (visnav YAML).
        description: the top-level description (receives notes and args).
        skip_unmapped: leave out what cannot be mapped (each element and each node whose
            translation has a problem becomes one note) instead of refusing the file.

    Raises:
        RoslaunchImportError: elements that cannot be mapped (all of them, in one error).
        LaunchError: the file does not parse, a missing or unknown arg, a bad value.
    """
    packages = {k: str(v) for k, v in scope.ctx.packages.items()}
    ctx = replace(scope.ctx, packages=packages)
    # one dict: packages found by $(find) while loading reach xacro and the simulator
    state = _Import(params=ParamServer(), include=include, packages=packages)
    file = Path(path)
    load_roslaunch_file(
        state,
        file,
        args,
        _RosScope(scope.namespace, scope.remaps),
        ctx,
        chain,
        scope.passed_through,
    )
    translated: dict[int, NodeSpec | None] = {}
    ros_nodes = [(i, n) for i, n in enumerate(state.items) if isinstance(n, RosNode)]
    for i, item in sorted(ros_nodes, key=lambda p: translation_order((p[1].pkg, p[1].type))):
        spec, issues = translate_node(item, state.params, state.packages)
        state.issues.extend(f"{item.source}: {text}" for text in issues)
        translated[i] = None if issues and skip_unmapped else spec
    if skip_unmapped:
        state.notes.extend(f"skipped (--skip-unmapped): {text}" for text in state.issues)
        state.issues.clear()
    state.notes.extend(state.params.notes)
    nodes = [
        spec
        for i, item in enumerate(state.items)
        if (spec := item if isinstance(item, NodeSpec) else translated[i]) is not None
    ]
    if state.issues:
        count = len(state.issues)
        msg = (
            f"{file}: cannot import {count} element{'s' if count > 1 else ''} of this roslaunch "
            f"file: {'; '.join(state.issues)}. visnav maps: {MAPPABLE}"
        )
        raise RoslaunchImportError(msg)
    nodes = fold_spawns(nodes, state.notes)
    known = [f"{k}={v}" for k, v in sorted(state.packages.items()) if "://" not in str(v)]
    if known:  # package:// meshes and model:// of the packages' models, for the simulator
        nodes = [
            replace(n, params={**n.params, "packages": known})
            if n.executable == "sim" and "packages" not in n.params
            else n
            for n in nodes
        ]
    sim_time = state.params.get("/use_sim_time")
    if sim_time is not None:
        use = parse_bool(sim_time, "/use_sim_time", f"{state.params.source('/use_sim_time')}: ")
        nodes = [n if n.use_sim_time is not None else replace(n, use_sim_time=use) for n in nodes]
    unread = state.params.unread()
    if description is not None:
        description.notes.extend(state.notes)
        if unread:
            description.notes.append(
                "parameters no mapped node reads: " + ", ".join(sorted(unread))
            )
    return nodes
