"""Node parameters with rclpy's shape: declare, get, set, overrides and typed values.

A parameter's type is fixed by its declared default (or override), as in ROS 2 with
``dynamic_typing`` off: setting a value of another type is refused. Integers are
accepted where a double is declared (widened), as ``ros2 param set`` users expect.
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from visnav.graph.errors import (
    ParameterAlreadyDeclaredError,
    ParameterError,
    ParameterNotDeclaredError,
)

__all__ = ["Parameter", "ParameterStore", "ParameterType", "SetParametersResult"]


class ParameterType(enum.Enum):
    """The value type of a parameter (rcl_interfaces ParameterType)."""

    NOT_SET = 0
    BOOL = 1
    INTEGER = 2
    DOUBLE = 3
    STRING = 4
    BYTE_ARRAY = 5
    BOOL_ARRAY = 6
    INTEGER_ARRAY = 7
    DOUBLE_ARRAY = 8
    STRING_ARRAY = 9

    @classmethod
    def from_value(cls, value: Any) -> ParameterType:
        """Infer the type of a Python value.

        Raises:
            ParameterError: the value has no parameter type.
        """
        if value is None:
            return cls.NOT_SET
        if isinstance(value, bool):
            return cls.BOOL
        if isinstance(value, int):
            return cls.INTEGER
        if isinstance(value, float):
            return cls.DOUBLE
        if isinstance(value, str):
            return cls.STRING
        if isinstance(value, bytes | bytearray):
            return cls.BYTE_ARRAY
        if isinstance(value, list | tuple):
            return _array_type(value)
        msg = (
            f"parameter value {value!r} has type {type(value).__name__}: expected bool, int, "
            "float, str, bytes or a list of one of those"
        )
        raise ParameterError(msg)


def _array_type(values: Sequence[Any]) -> ParameterType:
    if all(isinstance(v, bool) for v in values):
        return ParameterType.BOOL_ARRAY
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return ParameterType.INTEGER_ARRAY
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return ParameterType.DOUBLE_ARRAY
    if all(isinstance(v, str) for v in values):
        return ParameterType.STRING_ARRAY
    msg = f"parameter list {list(values)!r} mixes types: expected all bool, int, float or str"
    raise ParameterError(msg)


@dataclasses.dataclass(frozen=True)
class Parameter:
    """A named parameter value (rclpy's ``Parameter``)."""

    name: str
    value: Any = None

    @property
    def type_(self) -> ParameterType:
        """The value's parameter type."""
        return ParameterType.from_value(self.value)


@dataclasses.dataclass(frozen=True)
class SetParametersResult:
    """The outcome of a set (rcl_interfaces SetParametersResult)."""

    successful: bool
    reason: str = ""


def _coerce(name: str, declared: ParameterType, value: Any) -> Any:
    new = ParameterType.from_value(value)
    if declared in (ParameterType.NOT_SET, new) or new is ParameterType.NOT_SET:
        return list(value) if isinstance(value, tuple) else value
    if declared is ParameterType.DOUBLE and new is ParameterType.INTEGER:
        return float(value)
    if declared is ParameterType.DOUBLE_ARRAY and new is ParameterType.INTEGER_ARRAY:
        return [float(v) for v in value]
    msg = (
        f"parameter '{name}' is declared as {declared.name} but was given {value!r} "
        f"({new.name}); pass a {declared.name.lower()} value"
    )
    raise ParameterError(msg)


class ParameterStore:
    """The parameters of one node.

    Args:
        node_name: fully qualified node name, for error messages.
        overrides: values that replace declared defaults (launch files, ``parameter_overrides``).
    """

    def __init__(self, node_name: str, overrides: Mapping[str, Any] | None = None) -> None:
        self._node = node_name
        self._overrides = dict(overrides or {})
        self._values: dict[str, Any] = {}
        self._types: dict[str, ParameterType] = {}
        self._descriptions: dict[str, str] = {}
        self._callbacks: list[Callable[[list[Parameter]], SetParametersResult]] = []

    def declare(
        self,
        name: str,
        value: Any = None,
        *,
        description: str = "",
        ignore_override: bool = False,
    ) -> Parameter:
        """Declare a parameter; an override for it replaces the default.

        Raises:
            ParameterAlreadyDeclaredError: declared before.
            ParameterError: the override's type does not match the default's.
        """
        if name in self._values:
            msg = f"parameter '{name}' of node {self._node} is already declared"
            raise ParameterAlreadyDeclaredError(msg)
        declared = ParameterType.from_value(value)
        if isinstance(value, list | tuple) and not value:
            declared = ParameterType.NOT_SET  # no element type yet: take the override's
        if not ignore_override and name in self._overrides:
            value = _coerce(name, declared, self._overrides[name])
            declared = (
                ParameterType.from_value(value) if declared is ParameterType.NOT_SET else declared
            )
        self._values[name] = list(value) if isinstance(value, tuple) else value
        self._types[name] = declared
        self._descriptions[name] = description
        return Parameter(name, self._values[name])

    def declare_many(self, namespace: str, params: Iterable[tuple[str, Any]]) -> list[Parameter]:
        """Declare several parameters under ``namespace`` (``ns.name``)."""
        prefix = f"{namespace}." if namespace else ""
        return [self.declare(prefix + n, v) for n, v in params]

    def has(self, name: str) -> bool:
        """Return whether ``name`` is declared."""
        return name in self._values

    def get(self, name: str) -> Parameter:
        """Return a declared parameter.

        Raises:
            ParameterNotDeclaredError: not declared (the message suggests close names).
        """
        if name not in self._values:
            close = difflib.get_close_matches(name, list(self._values), n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            msg = (
                f"parameter '{name}' of node {self._node} is not declared: call "
                f"declare_parameter('{name}', default) first{hint}"
            )
            raise ParameterNotDeclaredError(msg)
        return Parameter(name, self._values[name])

    def get_or(self, name: str, alternative: Any = None) -> Parameter:
        """Return the parameter, or ``Parameter(name, alternative)`` if undeclared."""
        return self.get(name) if name in self._values else Parameter(name, alternative)

    def info(self, name: str) -> tuple[ParameterType, str]:
        """The declared type and description of a parameter.

        Raises:
            ParameterNotDeclaredError: not declared.
        """
        self.get(name)
        return self._types[name], self._descriptions.get(name, "")

    def names(self) -> list[str]:
        """Return the declared names, sorted."""
        return sorted(self._values)

    def add_on_set_callback(
        self, callback: Callable[[list[Parameter]], SetParametersResult]
    ) -> None:
        """Register a validator called before values change; it may refuse them."""
        self._callbacks.append(callback)

    def set(self, params: Sequence[Parameter]) -> list[SetParametersResult]:
        """Set parameters atomically per call; callbacks may refuse.

        Raises:
            ParameterNotDeclaredError: a name is not declared.
            ParameterError: a value has the wrong type.
        """
        coerced = [
            Parameter(p.name, _coerce(p.name, self._types[self.get(p.name).name], p.value))
            for p in params
        ]
        for cb in self._callbacks:
            result = cb(coerced)
            if not result.successful:
                return [result for _ in coerced]
        for p in coerced:
            self._values[p.name] = p.value
        return [SetParametersResult(successful=True) for _ in coerced]

    def items(self) -> dict[str, Any]:
        """Return a copy of all values."""
        return dict(self._values)
