"""One idiom for node parameters: a params dataclass declared on a node.

The dataclass is the only source of a parameter's name, default, type, range and
description. :func:`param` builds a field carrying the description and range
(``dataclasses.field(metadata=...)``); :class:`ParamBinding` declares every field on
a node under a prefix, with an rclpy-shaped :class:`ParameterDescriptor`, builds the
dataclass from the declared values, and rebuilds it when a parameter is set: a value
of the wrong type, out of range, read-only, or refused by the dataclass's own checks
(``__post_init__``) is refused with a reason, as an rclpy ``on_set_parameters_callback``
does.

Example::

    @dataclass(frozen=True)
    class MyParams:
        rate: float = param(10.0, description="loop rate (Hz)", range=(0.1, 1000.0))
        topic: str = param("scan", description="input topic", read_only=True)

    binding = ParamBinding(node, MyParams, prefix="my.")
    binding.value.rate  # 10.0, or the launch file's override
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any, Generic, TypeVar

from visnav.errors import VisnavError
from visnav.graph.errors import ParameterError
from visnav.graph.parameters import Parameter, ParameterType, SetParametersResult

__all__ = [
    "FloatingPointRange",
    "IntegerRange",
    "ParamBinding",
    "ParameterDescriptor",
    "declare_params",
    "param",
]

T = TypeVar("T")

_DESCRIPTION = "visnav.description"
_RANGE = "visnav.range"
_READ_ONLY = "visnav.read_only"


@dataclasses.dataclass(frozen=True)
class IntegerRange:
    """An inclusive integer range (rcl_interfaces IntegerRange; ``step`` 0: any value)."""

    from_value: int
    to_value: int
    step: int = 0


@dataclasses.dataclass(frozen=True)
class FloatingPointRange:
    """An inclusive floating point range (rcl_interfaces FloatingPointRange)."""

    from_value: float
    to_value: float
    step: float = 0.0


@dataclasses.dataclass(frozen=True)
class ParameterDescriptor:
    """What a parameter is (rcl_interfaces ParameterDescriptor, the fields visnav uses)."""

    name: str
    type: ParameterType
    description: str = ""
    read_only: bool = False
    integer_range: IntegerRange | None = None
    floating_point_range: FloatingPointRange | None = None

    def check(self, value: Any) -> str:
        """Return why ``value`` is refused, or ``""`` when it is within the range."""
        rng: IntegerRange | FloatingPointRange | None = (
            self.integer_range or self.floating_point_range
        )
        if rng is None or isinstance(value, bool) or not isinstance(value, int | float):
            return ""
        if not (rng.from_value <= value <= rng.to_value) or (
            isinstance(value, float) and not math.isfinite(value)
        ):
            return (
                f"parameter '{self.name}' is {value!r}: expected a value in "
                f"[{rng.from_value}, {rng.to_value}]"
            )
        if rng.step and value != rng.to_value:
            steps = (value - rng.from_value) / rng.step
            if abs(steps - round(steps)) > 1e-9:
                return (
                    f"parameter '{self.name}' is {value!r}: expected {rng.from_value} plus a "
                    f"multiple of {rng.step}"
                )
        return ""


def param(
    default: Any,
    *,
    description: str = "",
    range: tuple[float, float] | None = None,
    read_only: bool = False,
) -> Any:
    """A dataclass field that is also a node parameter's declaration.

    Args:
        default: The default value (lists are copied per instance).
        description: One line for ``ros2 param describe``.
        range: Inclusive ``(low, high)``; an integer range for int defaults.
        read_only: Refuse changes after declaration (topics, frames read once).

    Returns:
        A ``dataclasses.field``.
    """
    meta = {_DESCRIPTION: description, _RANGE: range, _READ_ONLY: read_only}
    if isinstance(default, list):
        items = list(default)
        return dataclasses.field(default_factory=lambda: list(items), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _default_of(f: dataclasses.Field[Any]) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def _descriptor(name: str, f: dataclasses.Field[Any], value: Any) -> ParameterDescriptor:
    empty = isinstance(value, list | tuple) and not value
    kind = ParameterType.NOT_SET if empty else ParameterType.from_value(value)
    rng = f.metadata.get(_RANGE)
    int_range = float_range = None
    if rng is not None:
        if kind is ParameterType.INTEGER:
            int_range = IntegerRange(int(rng[0]), int(rng[1]))
        else:
            float_range = FloatingPointRange(float(rng[0]), float(rng[1]))
    return ParameterDescriptor(
        name=name,
        type=kind,
        description=str(f.metadata.get(_DESCRIPTION, "")),
        read_only=bool(f.metadata.get(_READ_ONLY, False)),
        integer_range=int_range,
        floating_point_range=float_range,
    )


def _type_problem(descriptor: ParameterDescriptor, value: Any) -> str:
    """Why ``value`` does not fit the declared type (rclpy without dynamic typing), or ``""``."""
    if isinstance(value, list | tuple) and not value:
        if descriptor.type is ParameterType.NOT_SET or descriptor.type.name.endswith("ARRAY"):
            return ""
        return f"parameter '{descriptor.name}' is []: expected a {descriptor.type.name.lower()}"
    kind = ParameterType.from_value(value)
    if descriptor.type in (ParameterType.NOT_SET, kind):
        return ""
    return (
        f"parameter '{descriptor.name}' is {value!r} ({kind.name.lower()}): expected a "
        f"{descriptor.type.name.lower()} value"
    )


def _convert(default: Any, value: Any) -> Any:
    """Give a declared value the default's Python type (float from int, tuple from list)."""
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, tuple) and isinstance(value, list):
        return tuple(value)
    return value


class ParamBinding(Generic[T]):
    """A params dataclass declared on a node and rebuilt when its parameters change.

    Args:
        node: The node (anything with rclpy's ``declare_parameter`` and
            ``add_on_set_parameters_callback``).
        cls: The params dataclass.
        prefix: Prepended to every field name (``"DWAPlannerROS."``).
        defaults: Defaults replacing the dataclass's (a caller's configuration; launch
            file overrides still win).
        names: Declare only these fields (the others keep the dataclass default).
        fixed: Values of undeclared fields (derived by the caller from other parameters).
        on_change: Called with the new dataclass after an accepted set.
        static: The caller reads the values once: refuse every later set with a reason
            (instead of accepting a value nothing would apply).

    Attributes:
        value: The current dataclass.
        descriptors: Full parameter name -> :class:`ParameterDescriptor`.

    Raises:
        ParameterError: An override is of the wrong type or out of range, or the
            dataclass refuses the declared values (the message names the parameter).
    """

    def __init__(
        self,
        node: Any,
        cls: type[T],
        *,
        prefix: str = "",
        defaults: Mapping[str, Any] | None = None,
        names: Iterable[str] | None = None,
        fixed: Mapping[str, Any] | None = None,
        on_change: Callable[[T], None] | None = None,
        static: bool = False,
    ) -> None:
        if not dataclasses.is_dataclass(cls):
            msg = f"ParamBinding needs a dataclass: {cls!r} is not one"
            raise ParameterError(msg)
        self._cls = cls
        self._prefix = prefix
        self._on_change = on_change
        self._static = static
        wanted = None if names is None else set(names)
        extra = dict(defaults or {})
        fields = [f for f in dataclasses.fields(cls) if wanted is None or f.name in wanted]
        unknown = sorted(set(extra) - {f.name for f in fields})
        if unknown:
            msg = f"defaults for {', '.join(unknown)}: {cls.__name__} has no such parameter"
            raise ParameterError(msg)
        self._fields = {prefix + f.name: f for f in fields}
        self._fixed = dict(fixed or {})
        self.descriptors: dict[str, ParameterDescriptor] = {}
        values: dict[str, Any] = {}
        self._defaults: dict[str, Any] = {}
        for full, f in self._fields.items():
            default = extra.get(f.name, _default_of(f))
            self._defaults[f.name] = default
            descriptor = _descriptor(full, f, default)
            value = node.declare_parameter(full, default, description=descriptor.description).value
            if descriptor.type is ParameterType.NOT_SET and value not in (None, []):
                descriptor = dataclasses.replace(descriptor, type=ParameterType.from_value(value))
            reason = _type_problem(descriptor, value) or descriptor.check(value)
            if reason:
                raise ParameterError(f"{reason}; fix the override")
            self.descriptors[full] = descriptor
            register = getattr(node, "set_parameter_descriptor", None)
            if register is not None:
                register(descriptor)
            values[f.name] = value
        self._values = values
        self.value: T = self._build(values, where="declared")
        node.add_on_set_parameters_callback(self._on_set)

    def _build(self, values: Mapping[str, Any], *, where: str) -> T:
        kwargs = {k: _convert(self._defaults.get(k), v) for k, v in values.items()}
        kwargs.update(self._fixed)
        try:
            return self._cls(**kwargs)
        except (VisnavError, ValueError, TypeError) as exc:
            if isinstance(exc, ParameterError):
                raise
            name = self._cls.__name__
            msg = f"{name} refuses the {where} parameters under '{self._prefix}': {exc}"
            raise ParameterError(msg) from exc

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        mine = [p for p in params if p.name in self._fields]
        if not mine:
            return SetParametersResult(successful=True)
        values = dict(self._values)
        for p in mine:
            descriptor = self.descriptors[p.name]
            if self._static:
                return SetParametersResult(
                    successful=False,
                    reason=(
                        f"parameter '{p.name}' is read once at start: set it in the launch "
                        "file or as an override, and restart the node"
                    ),
                )
            if descriptor.read_only:
                return SetParametersResult(
                    successful=False, reason=f"parameter '{p.name}' is read-only"
                )
            reason = _type_problem(descriptor, p.value) or descriptor.check(p.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
            values[self._fields[p.name].name] = p.value
        try:
            built = self._build(values, where="new")
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self._values = values
        self.value = built
        if self._on_change is not None:
            self._on_change(built)
        return SetParametersResult(successful=True)


def declare_params(
    node: Any,
    cls: type[T],
    *,
    prefix: str = "",
    defaults: Mapping[str, Any] | None = None,
    names: Iterable[str] | None = None,
    fixed: Mapping[str, Any] | None = None,
) -> T:
    """Declare ``cls``'s fields on ``node`` and return the dataclass (see :class:`ParamBinding`).

    For nodes that read their parameters once: a later ``set_parameters`` of any of them
    is refused with a reason (use :class:`ParamBinding` with ``on_change`` to apply changes).

    Raises:
        ParameterError: As :class:`ParamBinding`.
    """
    binding = ParamBinding(
        node, cls, prefix=prefix, defaults=defaults, names=names, fixed=fixed, static=True
    )
    return binding.value
