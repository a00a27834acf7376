"""The resolved launch description: the nodes to start, each fully specified.

Both front ends (the YAML format and the roslaunch XML import) produce a
:class:`LaunchDescription`; the supervisor starts it. Every substitution, arg,
group and include has been applied: a :class:`NodeSpec` holds final values.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from visnav.graph.errors import ParameterError
from visnav.graph.names import InvalidNameError, resolve_node_name_and_namespace
from visnav.graph.parameters import ParameterType
from visnav.launch.errors import LaunchParseError

__all__ = [
    "ON_ERROR",
    "PROCESS_KINDS",
    "ArgInfo",
    "LaunchDescription",
    "NodeSpec",
    "check_param_value",
    "default_process",
]

PROCESS_KINDS = ("shared", "own")
OWN_PROCESS_EXECUTABLES = frozenset({"viz"})
"""Node types that run in a process of their own unless their entry says ``process: shared``:
the viewer, whose TF placement, image encoding and Rerun calls would otherwise compete with
the shared nodes (and a lock-step simulation) for one interpreter."""


def default_process(executable: str) -> str:
    """The process kind of a node entry that does not name one: ``own`` or ``shared``."""
    return "own" if executable in OWN_PROCESS_EXECUTABLES else "shared"


ON_ERROR = ("log", "restart", "shutdown")
"""What an exception in a node's callback does: log it and go on, restart the node's
process, or stop the launch."""


def check_param_value(name: str, value: Any, where: str = "") -> Any:
    """Return ``value`` as a parameter value (tuples become lists).

    Raises:
        LaunchParseError: the value is not a bool, int, float, str, bytes or a list of one
            of those.
    """
    if isinstance(value, tuple):
        value = list(value)
    try:
        ParameterType.from_value(value)
    except ParameterError as exc:
        msg = f"{where}parameter {name!r}: {exc}"
        raise LaunchParseError(msg) from None
    return value


@dataclass(frozen=True)
class NodeSpec:
    """One node to start.

    Attributes:
        executable: a built-in node name (:data:`visnav.node_registry.BUILTIN_NODES`) or
            ``module:Class``.
        name: the node name.
        namespace: the node's absolute namespace.
        params: parameter overrides (flat names, ``a.b`` for nested ones).
        remaps: remap rules ``(from, to)`` in match order (the node's own first).
        use_sim_time: the ``use_sim_time`` parameter (None: the node's default, false).
        process: ``"shared"`` (one process, one Context, zero copy) or ``"own"``.
        respawn: restart the process when it exits (``own`` only).
        respawn_delay: seconds to wait before a restart.
        respawn_max_retries: restarts allowed (None: no limit).
        required: stop the whole launch when this node's process exits.
        on_error: an exception in a callback is logged and the node goes on (``"log"``),
            ends its process, which is restarted as with ``respawn`` (``"restart"``, ``own``
            only), or stops the launch as with ``required`` (``"shutdown"``).
        source: ``file:line`` where the node was declared.
    """

    executable: str
    name: str
    namespace: str = "/"
    params: Mapping[str, Any] = field(default_factory=dict)
    remaps: tuple[tuple[str, str], ...] = ()
    use_sim_time: bool | None = None
    process: str = "shared"
    respawn: bool = False
    respawn_delay: float = 0.0
    respawn_max_retries: int | None = None
    required: bool = False
    on_error: str = "log"
    source: str = ""

    @property
    def fqn(self) -> str:
        """The fully qualified node name (after ``__node`` / ``__ns`` remaps)."""
        name, ns = resolve_node_name_and_namespace(self.name, self.namespace, self.remap_rules())
        return f"{ns.rstrip('/')}/{name}"

    def remap_rules(self) -> list[str]:
        """The remaps as ``from:=to`` rule strings."""
        return [f"{a}:={b}" for a, b in self.remaps]

    def node_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for the node class (besides ``context``)."""
        kwargs: dict[str, Any] = {
            "namespace": self.namespace,
            "parameter_overrides": dict(self.params),
            "remappings": self.remap_rules(),
        }
        if self.use_sim_time is not None:
            kwargs["use_sim_time"] = self.use_sim_time
        return kwargs

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict (for the runner of ``own`` processes)."""
        return {
            "executable": self.executable,
            "name": self.name,
            "namespace": self.namespace,
            "params": dict(self.params),
            "remaps": [list(r) for r in self.remaps],
            "use_sim_time": self.use_sim_time,
            "process": self.process,
            "respawn": self.respawn,
            "respawn_delay": self.respawn_delay,
            "respawn_max_retries": self.respawn_max_retries,
            "required": self.required,
            "on_error": self.on_error,
            "source": self.source,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> NodeSpec:
        """Inverse of :meth:`to_json`."""
        fields = dict(data)
        fields["remaps"] = tuple((str(a), str(b)) for a, b in fields.get("remaps", ()))
        fields["params"] = dict(fields.get("params", {}))
        return cls(**fields)


@dataclass(frozen=True)
class ArgInfo:
    """A declared launch argument of the top-level file.

    Attributes:
        name: the argument name.
        value: its value in this launch.
        default: its default (None: required).
        description: the help text.
    """

    name: str
    value: str
    default: str | None = None
    description: str = ""


@dataclass
class LaunchDescription:
    """Everything one launch starts.

    Attributes:
        nodes: the nodes, in declaration order.
        args: the top-level file's arguments.
        notes: things the front end ignored or translated (the roslaunch import says what
            it did with ``gui``, tf's period, ...).
        source: the top-level launch file.
    """

    nodes: list[NodeSpec] = field(default_factory=list)
    args: dict[str, ArgInfo] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    source: str = ""

    def validate(self) -> None:
        """Check names, process kinds and unique node names.

        Raises:
            LaunchParseError: an invalid name or namespace, an unknown process kind,
                ``respawn`` or ``on_error: restart`` on a shared node, an unknown ``on_error``,
                two nodes with one fully qualified name.
        """
        seen: dict[str, NodeSpec] = {}
        for spec in self.nodes:
            at = f"{spec.source}: " if spec.source else ""
            try:
                fqn = spec.fqn
            except InvalidNameError as exc:
                raise LaunchParseError(f"{at}node {spec.name!r}: {exc}") from None
            if spec.process not in PROCESS_KINDS:
                msg = f"{at}node {fqn}: process is {spec.process!r}: expected 'own' or 'shared'"
                raise LaunchParseError(msg)
            if spec.on_error not in ON_ERROR:
                msg = (
                    f"{at}node {fqn}: on_error is {spec.on_error!r}: expected one of "
                    f"{', '.join(ON_ERROR)}"
                )
                raise LaunchParseError(msg)
            if spec.on_error == "restart" and spec.process != "own":
                msg = (
                    f"{at}node {fqn}: on_error: restart needs its own process: set "
                    "'process: own' (a shared process holds other nodes too)"
                )
                raise LaunchParseError(msg)
            if spec.respawn and spec.process != "own":
                msg = (
                    f"{at}node {fqn}: respawn needs its own process: set 'process: own' "
                    "(a shared process holds other nodes too)"
                )
                raise LaunchParseError(msg)
            if spec.respawn_delay < 0 or (
                spec.respawn_max_retries is not None and spec.respawn_max_retries < 0
            ):
                msg = f"{at}node {fqn}: respawn_delay and respawn_max_retries must be >= 0"
                raise LaunchParseError(msg)
            if fqn in seen:
                other = seen[fqn].source or "?"
                msg = (
                    f"{at}two nodes are named {fqn} (the other is at {other}): give one a "
                    "different name or namespace"
                )
                raise LaunchParseError(msg)
            seen[fqn] = spec
            for key, value in spec.params.items():
                check_param_value(key, value, at)

    def dumps(self) -> str:
        """The description as JSON (``visnav launch --print --json``)."""
        return json.dumps(
            {
                "source": self.source,
                "args": {k: vars(v) for k, v in self.args.items()},
                "nodes": [n.to_json() for n in self.nodes],
                "notes": self.notes,
            },
            indent=2,
        )

    def format(self) -> str:
        """A readable listing of args, nodes and notes (``visnav launch --print``)."""
        lines: list[str] = [f"launch {self.source}"]
        if self.args:
            lines.append("args:")
            lines.extend(
                f"  {a.name} = {a.value!r}" + (f"  ({a.description})" if a.description else "")
                for a in self.args.values()
            )
        lines.append(f"nodes ({len(self.nodes)}):")
        for spec in self.nodes:
            lines.extend(_format_node(spec))
        if self.notes:
            lines.append("notes:")
            lines.extend(f"  - {n}" for n in self.notes)
        return "\n".join(lines)


def _format_node(spec: NodeSpec) -> Sequence[str]:
    flags = [f"process={spec.process}"]
    if spec.use_sim_time is not None:
        flags.append(f"use_sim_time={str(spec.use_sim_time).lower()}")
    if spec.respawn:
        retries = "" if spec.respawn_max_retries is None else f", max {spec.respawn_max_retries}"
        flags.append(f"respawn(delay {spec.respawn_delay:g} s{retries})")
    if spec.required:
        flags.append("required")
    if spec.on_error != "log":
        flags.append(f"on_error={spec.on_error}")
    out = [f"  {spec.fqn}  [{spec.executable}]  {' '.join(flags)}"]
    for key, value in spec.params.items():
        text = repr(value)
        if len(text) > 70:
            text = f"{text[:60]}... ({len(text)} chars)"
        out.append(f"      param {key} = {text}")
    out.extend(f"      remap {a} -> {b}" for a, b in spec.remaps)
    if spec.source:
        out.append(f"      from {spec.source}")
    return out
