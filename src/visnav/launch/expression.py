"""``$(eval EXPR)``: roslaunch's expression language, evaluated without Python's ``eval``.

roslaunch (ROS 1) evaluates ``$(eval ...)`` with Python's ``eval`` and a small namespace;
visnav parses the text with :mod:`ast` (parsing only) and walks a whitelist of node types,
so only these constructs mean anything:

* literals: numbers, strings, ``True`` / ``False`` (also ``true`` / ``false``), ``None``,
  lists and tuples;
* names: ``arg('x')`` and a bare ``x`` are the launch argument, converted as roslaunch does
  (``'2'`` -> 2, ``'0.5'`` -> 0.5, ``'true'`` -> True, anything else a string);
  ``find('pkg')``, ``env('X')``, ``optenv('X', 'default')``, ``anon('name')``,
  ``dirname()``; ``str``, ``int``, ``float``, ``bool``, ``list``; ``math``'s constants
  and common functions (``pi``, ``sqrt``, ``sin``, ``atan2``, ``radians``, ...);
* operators: ``+ - * / // % **``, unary ``- + not``, comparisons (``== != < <= > >=``,
  ``in``, ``not in``, chained), ``and`` / ``or``, ``x if c else y``, indexing and slices;
* string methods: ``lower upper strip lstrip rstrip startswith endswith replace split
  join find count zfill title capitalize isdigit isalpha`` (not ``format``: a format
  string from an arg could reach attributes).

Anything else (attribute access other than those methods, keyword arguments, lambdas,
comprehensions, f-strings, ``__`` anywhere, ...) is a :class:`LaunchEvalError` naming the
expression and the construct. Sizes are bounded (integers of at most 4096 bits, strings
and lists of at most 100,000 items, expressions of at most 4,000 characters), so no
expression can exhaust memory or time; every failure, Python's own included (a division
by zero, a type mismatch), is a :class:`LaunchEvalError`.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from visnav.launch.errors import LaunchError, LaunchParseError

__all__ = [
    "EvalFunctions",
    "LaunchEvalError",
    "auto_value",
    "evaluate_expression",
    "format_value",
]

_MAX_TEXT = 4000
_MAX_DEPTH = 60
_MAX_INT_BITS = 4096
_MAX_LENGTH = 100_000


class LaunchEvalError(LaunchParseError):
    """A ``$(eval ...)`` expression is not valid, uses an unsupported construct or fails."""


class _Fail(Exception):  # noqa: N818 - internal signal, turned into LaunchEvalError
    """Why an expression failed (the text of the message)."""


class _Unsupported(_Fail):
    """A construct outside the language (the text names it)."""


def auto_value(text: str) -> Any:
    """Convert an arg value as roslaunch's ``convert_value(value, 'auto')`` does.

    A value with a ``.`` that parses as a float is a float, one without that parses as
    an int is an int, ``true`` / ``false`` (any case) are bools, anything else stays a
    string.
    """
    try:
        return float(text) if "." in text else int(text)
    except ValueError:
        pass
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return text


def format_value(value: Any) -> str:
    """The text of an expression's value (Python's ``str``, as roslaunch returns it)."""
    return str(value)


@dataclass(frozen=True)
class EvalFunctions:
    """The launch functions an expression may call (the substitutions' own lookups).

    Attributes:
        arg: launch argument name -> its string value (raises for an unknown one).
        find: package name -> directory.
        env: environment variable -> value (raises if unset).
        optenv: ``(name, default)`` -> value or default.
        anon: name -> the launch's anonymous name for it.
        dirname: the directory of the current launch file.
    """

    arg: Callable[[str], str]
    find: Callable[[str], str]
    env: Callable[[str], str]
    optenv: Callable[[str, str], str]
    anon: Callable[[str], str]
    dirname: Callable[[], str]


_MATH_CONSTANTS: Mapping[str, float] = {
    "pi": math.pi,
    "e": math.e,
    "tau": math.tau,
    "inf": math.inf,
    "nan": math.nan,
}
_MATH_FUNCTIONS: Mapping[str, Callable[..., Any]] = {
    name: getattr(math, name)
    for name in (
        "sqrt",
        "sin",
        "cos",
        "tan",
        "asin",
        "acos",
        "atan",
        "atan2",
        "sinh",
        "cosh",
        "tanh",
        "radians",
        "degrees",
        "floor",
        "ceil",
        "trunc",
        "fabs",
        "exp",
        "log",
        "log10",
        "log2",
        "hypot",
        "copysign",
        "fmod",
        "isclose",
        "isfinite",
        "isnan",
    )
}
_CONSTANTS: Mapping[str, Any] = {"true": True, "false": False, **_MATH_CONSTANTS}
_STR_METHODS = frozenset(
    {
        "lower",
        "upper",
        "strip",
        "lstrip",
        "rstrip",
        "startswith",
        "endswith",
        "replace",
        "split",
        "rsplit",
        "join",
        "find",
        "rfind",
        "count",
        "zfill",
        "title",
        "capitalize",
        "isdigit",
        "isalpha",
        "isalnum",
    }
)
_BINARY: Mapping[type[ast.operator], Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.FloorDiv: operator.floordiv,
    ast.Mod: operator.mod,
    ast.Pow: operator.pow,
}
_COMPARE: Mapping[type[ast.cmpop], Callable[[Any, Any], Any]] = {
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.In: lambda a, b: a in b,
    ast.NotIn: lambda a, b: a not in b,
}
_WHAT: Mapping[type[ast.AST], str] = {
    ast.Lambda: "a lambda",
    ast.ListComp: "a list comprehension",
    ast.SetComp: "a set comprehension",
    ast.DictComp: "a dict comprehension",
    ast.GeneratorExp: "a generator expression",
    ast.JoinedStr: "an f-string",
    ast.NamedExpr: "an assignment expression (:=)",
    ast.Await: "await",
    ast.Yield: "yield",
    ast.YieldFrom: "yield",
    ast.Dict: "a dict literal",
    ast.Set: "a set literal",
    ast.Starred: "a starred argument",
    ast.Attribute: "attribute access",
}
_SUPPORTED = (
    "literals, launch args (arg('x') or x), find() env() optenv() anon() dirname(), "
    "str() int() float() bool() list(), math functions, + - * / // % **, comparisons, "
    "in, and/or/not, x if c else y, indexing, string methods"
)


def _describe(node: ast.AST) -> str:
    for kind, text in _WHAT.items():
        if isinstance(node, kind):
            return text
    if isinstance(node, ast.BinOp):
        return f"the operator {type(node.op).__name__}"
    if isinstance(node, ast.UnaryOp):
        return f"the unary operator {type(node.op).__name__}"
    if isinstance(node, ast.Compare):
        return "the comparison " + ", ".join(type(op).__name__ for op in node.ops)
    return type(node).__name__


def _total(value: Any, budget: int = _MAX_LENGTH) -> int:
    """Items in ``value`` (string characters, nested lists counted); stops past ``budget``."""
    if isinstance(value, str):
        return len(value)
    if isinstance(value, list | tuple):
        count = len(value)
        for item in value:
            if count > budget:
                break
            count += _total(item, budget - count) if isinstance(item, str | list | tuple) else 0
        return count
    return 1


def _check_size(value: Any) -> Any:
    if isinstance(value, bool):
        return value
    if isinstance(value, complex):
        msg = f"the result {value!r} is a complex number"
        raise _Fail(msg)
    if isinstance(value, int) and value.bit_length() > _MAX_INT_BITS:
        msg = f"the result is an integer of {value.bit_length()} bits (at most {_MAX_INT_BITS})"
        raise _Fail(msg)
    if isinstance(value, str | list | tuple) and _total(value) > _MAX_LENGTH:
        msg = f"the result is a {type(value).__name__} of more than {_MAX_LENGTH} items"
        raise _Fail(msg)
    return value


def _binary(op: ast.operator, left: Any, right: Any) -> Any:
    kind = type(op)
    if kind is ast.Mult:
        # sequence repetition: check the size before building it
        seq, count = (left, right) if isinstance(right, int) else (right, left)
        sequence = isinstance(count, int) and isinstance(seq, str | list | tuple)
        if sequence and count * _total(seq) > _MAX_LENGTH:
            size = f"{count} x {_total(seq)}"
            msg = f"a repetition of {size} items is too large (at most {_MAX_LENGTH})"
            raise _Fail(msg)
    if kind is ast.Pow and isinstance(left, int) and isinstance(right, int):
        bits = max(abs(left).bit_length(), 1) * abs(right)
        if right > 0 and abs(left) > 1 and bits > _MAX_INT_BITS:
            msg = f"{left} ** {right} is too large (integers of at most {_MAX_INT_BITS} bits)"
            raise _Fail(msg)
    if kind is ast.Mod and isinstance(left, str):
        msg = "'%' string formatting (use +)"
        raise _Unsupported(msg)
    function = _BINARY.get(kind)
    if function is None:
        msg = f"the operator {kind.__name__}"
        raise _Unsupported(msg)
    return function(left, right)


def _text_arg(name: str, values: Sequence[Any], index: int) -> str:
    value = values[index]
    if not isinstance(value, str):
        msg = f"{name}() takes text, got {value!r}"
        raise _Fail(msg)
    return value


class _Evaluator:
    """Walks the parsed expression; only the node types below are evaluated."""

    def __init__(self, functions: EvalFunctions) -> None:
        self.fn = functions
        self.depth = 0

    def call_launch(self, name: str, args: list[Any]) -> Any:
        counts = {
            "arg": (1, 1),
            "find": (1, 1),
            "env": (1, 1),
            "optenv": (1, 2),
            "anon": (1, 1),
            "dirname": (0, 0),
        }
        low, high = counts[name]
        if not low <= len(args) <= high:
            want = str(low) if low == high else f"{low} or {high}"
            msg = f"{name}() takes {want} argument(s), got {len(args)}"
            raise _Fail(msg)
        texts = [_text_arg(name, args, i) for i in range(len(args))]
        if name == "arg":
            return auto_value(self.fn.arg(texts[0]))
        if name == "find":
            return self.fn.find(texts[0])
        if name == "env":
            return self.fn.env(texts[0])
        if name == "optenv":
            return self.fn.optenv(texts[0], texts[1] if len(texts) > 1 else "")
        if name == "anon":
            return self.fn.anon(texts[0])
        return self.fn.dirname()

    def name(self, node: ast.Name) -> Any:
        if node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        if node.id in _MATH_FUNCTIONS or node.id in _BUILTINS or node.id in _LAUNCH:
            msg = f"{node.id} is a function: call it, e.g. {node.id}(...)"
            raise _Fail(msg)
        return auto_value(self.fn.arg(node.id))  # roslaunch: a bare name is an arg

    def call(self, node: ast.Call) -> Any:
        if node.keywords:
            msg = "keyword arguments"
            raise _Unsupported(msg)
        args = [self.eval(a) for a in node.args]
        func = node.func
        if isinstance(func, ast.Name):
            if func.id in _LAUNCH:
                return self.call_launch(func.id, args)
            if func.id in _BUILTINS:
                return _BUILTINS[func.id](*args)
            if func.id in _MATH_FUNCTIONS:
                for value in args:
                    if not isinstance(value, int | float):
                        msg = f"{func.id}() takes numbers, got {value!r}"
                        raise _Fail(msg)
                return _MATH_FUNCTIONS[func.id](*args)
            msg = f"the function {func.id}()"
            raise _Unsupported(msg)
        if isinstance(func, ast.Attribute):
            target = self.eval(func.value)
            if not isinstance(target, str):
                msg = f"the method .{func.attr}() of {type(target).__name__}"
                raise _Unsupported(msg)
            if func.attr not in _STR_METHODS:
                msg = f"the string method .{func.attr}()"
                raise _Unsupported(msg)
            if func.attr == "join":
                if len(args) != 1 or not isinstance(args[0], list | tuple):
                    msg = ".join() takes one list of strings"
                    raise _Fail(msg)
                total = _total(args[0]) + len(target) * len(args[0])
                if total > _MAX_LENGTH:
                    msg = f"a joined string of {total} characters (at most {_MAX_LENGTH})"
                    raise _Fail(msg)
            if func.attr == "zfill" and args and isinstance(args[0], int) and args[0] > _MAX_LENGTH:
                msg = f".zfill({args[0]}) (at most {_MAX_LENGTH})"
                raise _Fail(msg)
            if func.attr == "replace" and len(args) >= 2 and isinstance(args[1], str):
                grown = (len(target) + 1) * (len(args[1]) + 1)
                if grown > _MAX_LENGTH:
                    msg = f"a replacement that may grow to {grown} characters"
                    raise _Fail(msg)
            return getattr(target, func.attr)(*args)
        msg = f"calling {_describe(func)}"
        raise _Unsupported(msg)

    def eval(self, node: ast.AST) -> Any:
        self.depth += 1
        if self.depth > _MAX_DEPTH:
            msg = f"nesting deeper than {_MAX_DEPTH}"
            raise _Fail(msg)
        try:
            return _check_size(self._eval(node))
        finally:
            self.depth -= 1

    def _eval(self, node: ast.AST) -> Any:
        if isinstance(node, ast.Expression):
            return self.eval(node.body)
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool | int | float | str) or node.value is None:
                return node.value
            msg = f"the literal {node.value!r}"
            raise _Unsupported(msg)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.List | ast.Tuple):
            items = [self.eval(e) for e in node.elts]
            return items if isinstance(node, ast.List) else tuple(items)
        if isinstance(node, ast.BinOp):
            return _binary(node.op, self.eval(node.left), self.eval(node.right))
        if isinstance(node, ast.UnaryOp):
            value = self.eval(node.operand)
            if isinstance(node.op, ast.Not):
                return not value
            if isinstance(node.op, ast.USub):
                return -value
            if isinstance(node.op, ast.UAdd):
                return +value
            raise _Unsupported(_describe(node))
        if isinstance(node, ast.BoolOp):
            is_and = isinstance(node.op, ast.And)
            value = None
            for operand in node.values:
                value = self.eval(operand)
                if bool(value) != is_and:  # and: stop at a false one; or: at a true one
                    return value
            return value
        if isinstance(node, ast.Compare):
            left = self.eval(node.left)
            for op, comparator in zip(node.ops, node.comparators, strict=True):
                right = self.eval(comparator)
                compare = _COMPARE.get(type(op))
                if compare is None:
                    raise _Unsupported(_describe(node))
                if not compare(left, right):
                    return False
                left = right
            return True
        if isinstance(node, ast.IfExp):
            return self.eval(node.body) if self.eval(node.test) else self.eval(node.orelse)
        if isinstance(node, ast.Call):
            return self.call(node)
        if isinstance(node, ast.Subscript):
            return self.subscript(node)
        raise _Unsupported(_describe(node))

    def subscript(self, node: ast.Subscript) -> Any:
        target = self.eval(node.value)
        if not isinstance(target, str | list | tuple):
            msg = f"indexing a {type(target).__name__}"
            raise _Unsupported(msg)
        index = node.slice
        if isinstance(index, ast.Slice):
            parts = [None if p is None else self.eval(p) for p in (index.lower, index.upper)]
            step = None if index.step is None else self.eval(index.step)
            for part in (*parts, step):
                if part is not None and (not isinstance(part, int) or isinstance(part, bool)):
                    msg = f"a slice bound {part!r} (expected an integer)"
                    raise _Fail(msg)
            return target[parts[0] : parts[1] : step]
        position = self.eval(index)
        if not isinstance(position, int) or isinstance(position, bool):
            msg = f"an index {position!r} (expected an integer)"
            raise _Fail(msg)
        return target[position]


def _to_bool(value: Any) -> bool:
    return bool(value)


def _to_list(value: Any) -> list[Any]:
    if not isinstance(value, str | list | tuple):
        msg = f"list() of {type(value).__name__}"
        raise _Unsupported(msg)
    return list(value)


_BUILTINS: Mapping[str, Callable[..., Any]] = {
    "str": str,
    "int": int,
    "float": float,
    "bool": _to_bool,
    "list": _to_list,
}
_LAUNCH = frozenset({"arg", "find", "env", "optenv", "anon", "dirname"})


def evaluate_expression(expression: str, functions: EvalFunctions, *, prefix: str = "") -> Any:
    """Evaluate a ``$(eval ...)`` expression (see the module docstring for the language).

    Args:
        expression: the text between ``$(eval`` and its ``)``.
        functions: what ``arg()``, ``find()``, ... look up.
        prefix: ``file:line: `` for messages.

    Returns:
        The value (bool, int, float, str, list, tuple or None).

    Raises:
        LaunchEvalError: a syntax error, an unsupported construct, or a failure while
            evaluating (named with the expression).
        LaunchError: what ``arg()`` / ``find()`` / ``env()`` raise (unknown arg, ...).
    """
    shown = expression.strip()
    shown = shown if len(shown) <= 200 else shown[:200] + "..."

    def fail(reason: str) -> LaunchEvalError:
        return LaunchEvalError(f"{prefix}$(eval {shown}): {reason}")

    if len(expression) > _MAX_TEXT:
        msg = f"the expression is {len(expression)} characters long (at most {_MAX_TEXT})"
        raise fail(msg)
    if "__" in expression:
        msg = "'__' is not allowed in an expression (roslaunch refuses it too)"
        raise fail(msg)
    try:
        tree = ast.parse(expression.strip(), mode="eval")
    except SyntaxError as exc:
        msg = f"not a valid expression ({exc.msg}); supported: {_SUPPORTED}"
        raise fail(msg) from None
    except (ValueError, MemoryError, RecursionError):
        msg = f"the expression cannot be parsed (nested too deeply?); supported: {_SUPPORTED}"
        raise fail(msg) from None
    try:
        return _Evaluator(functions).eval(tree)
    except LaunchError:
        raise
    except _Unsupported as exc:
        msg = f"{exc} is not supported; supported: {_SUPPORTED}"
        raise fail(msg) from None
    except _Fail as exc:
        raise fail(str(exc)) from None
    except (ArithmeticError, TypeError, ValueError, IndexError, KeyError) as exc:
        msg = f"evaluation failed: {type(exc).__name__}: {exc}"
        raise fail(msg) from None
    except RecursionError:
        msg = "nested too deeply"
        raise fail(msg) from None
