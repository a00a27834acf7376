"""Tests of visnav.graph.param_dataclass: one params dataclass declared on a node."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.graph import Context, Node
from visnav.graph.errors import ParameterError
from visnav.graph.param_dataclass import (
    FloatingPointRange,
    IntegerRange,
    ParamBinding,
    ParameterDescriptor,
    declare_params,
    param,
)
from visnav.graph.parameters import Parameter, ParameterType


@dataclass(frozen=True)
class Demo:
    rate: float = param(10.0, description="loop rate (Hz)", range=(0.1, 100.0))
    count: int = param(3, description="samples", range=(1, 50))
    topic: str = param("scan", description="input", read_only=True)
    enabled: bool = param(True, description="on")
    low: float = 0.0
    high: float = 1.0
    names: list[str] = param(["a", "b"], description="names")  # noqa: RUF009

    def __post_init__(self) -> None:
        if not self.low <= self.high:  # NaN too: a double parameter may be NaN
            msg = f"low {self.low} > high {self.high}; expected low <= high"
            raise VisnavError(msg)


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def test_declares_every_field_with_its_default_and_descriptor(ctx: Context) -> None:
    node = Node("n", context=ctx)
    binding = ParamBinding(node, Demo, prefix="demo.")
    assert binding.value == Demo()
    assert node.get_parameter("demo.rate").value == 10.0
    assert node.get_parameter("demo.names").value == ["a", "b"]
    d = binding.descriptors["demo.rate"]
    assert d == ParameterDescriptor(
        name="demo.rate",
        type=ParameterType.DOUBLE,
        description="loop rate (Hz)",
        floating_point_range=FloatingPointRange(0.1, 100.0),
    )
    assert binding.descriptors["demo.count"].integer_range == IntegerRange(1, 50)
    assert binding.descriptors["demo.topic"].read_only
    assert binding.descriptors["demo.low"].description == ""


def test_overrides_win_over_caller_defaults_over_dataclass(ctx: Context) -> None:
    node = Node("n", context=ctx, parameter_overrides={"rate": 5, "topic": "front"})
    p = declare_params(node, Demo, defaults={"rate": 20.0, "count": 7})
    assert p.rate == 5.0
    assert isinstance(p.rate, float)  # an int override of a double is widened
    assert p.count == 7
    assert p.topic == "front"


def test_out_of_range_override_names_the_parameter(ctx: Context) -> None:
    node = Node("n", context=ctx, parameter_overrides={"demo.count": 0})
    with pytest.raises(ParameterError, match=r"'demo.count' is 0: expected a value in \[1, 50\]"):
        declare_params(node, Demo, prefix="demo.")


def test_dataclass_refusal_at_declaration_is_a_parameter_error(ctx: Context) -> None:
    node = Node("n", context=ctx, parameter_overrides={"low": 2.0})
    with pytest.raises(ParameterError, match=r"Demo refuses the declared parameters.*low 2\.0"):
        declare_params(node, Demo)


def test_unknown_default_and_non_dataclass_are_refused(ctx: Context) -> None:
    node = Node("n", context=ctx)
    with pytest.raises(ParameterError, match="defaults for speed: Demo has no such parameter"):
        declare_params(node, Demo, defaults={"speed": 1.0})
    with pytest.raises(ParameterError, match="needs a dataclass"):
        declare_params(node, dict)


def test_names_and_fixed_select_fields(ctx: Context) -> None:
    node = Node("n", context=ctx)
    p = declare_params(node, Demo, names=["rate"], fixed={"high": 4.0})
    assert node.parameters.keys() == {"use_sim_time", "rate"}
    assert p.high == 4.0


def test_declare_params_refuses_later_sets_with_a_reason(ctx: Context) -> None:
    node = Node("n", context=ctx)
    p = declare_params(node, Demo)
    (result,) = node.set_parameters([Parameter("rate", 20.0)])
    assert not result.successful
    assert "'rate' is read once at start" in result.reason
    assert node.get_parameter("rate").value == p.rate == 10.0


def test_set_rebuilds_the_dataclass_and_calls_on_change(ctx: Context) -> None:
    node = Node("n", context=ctx)
    seen: list[Demo] = []
    binding = ParamBinding(node, Demo, on_change=seen.append)
    results = node.set_parameters([Parameter("rate", 50.0), Parameter("high", 3.0)])
    assert all(r.successful for r in results)
    assert binding.value.rate == 50.0
    assert binding.value.high == 3.0
    assert seen == [binding.value]


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("rate", 1000.0, r"'rate' is 1000.0: expected a value in \[0.1, 100.0\]"),
        ("count", 51, r"'count' is 51"),
        ("topic", "other", r"'topic' is read-only"),
        ("low", 5.0, r"Demo refuses the new parameters.*low 5.0 > high 1.0"),
    ],
)
def test_set_refuses_with_a_reason_and_keeps_the_value(
    ctx: Context, name: str, value: Any, reason: str
) -> None:
    node = Node("n", context=ctx)
    binding = ParamBinding(node, Demo)
    (result,) = node.set_parameters([Parameter(name, value)])
    assert not result.successful
    assert result.reason is not None
    assert __import__("re").search(reason, result.reason)
    assert binding.value == Demo()
    assert node.get_parameter(name).value == getattr(Demo(), name)


def test_set_to_none_is_refused_with_a_reason(ctx: Context) -> None:
    node = Node("n", context=ctx)
    binding = ParamBinding(node, Demo)
    (result,) = node.set_parameters([Parameter("rate", None)])
    assert not result.successful
    assert "'rate' is None (not_set): expected a double value" in result.reason
    assert binding.value.rate == 10.0


def test_set_of_wrong_type_is_a_parameter_error(ctx: Context) -> None:
    node = Node("n", context=ctx)
    ParamBinding(node, Demo)
    with pytest.raises(ParameterError, match="'count' is declared as INTEGER"):
        node.set_parameters([Parameter("count", "three")])


def test_other_parameters_pass_through(ctx: Context) -> None:
    node = Node("n", context=ctx)
    binding = ParamBinding(node, Demo, prefix="a.")
    node.declare_parameter("other", 1)
    (result,) = node.set_parameters([Parameter("other", 2)])
    assert result.successful
    assert binding.value == Demo()


_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**40), 2**40),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.lists(st.integers(-5, 5), max_size=3),
    st.lists(st.text(max_size=2), max_size=3),
)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["rate", "count", "topic", "enabled", "low", "high", "names"]), _VALUES
        ),
        min_size=1,
        max_size=3,
    )
)
def test_fuzz_set_only_visnav_errors_and_value_stays_valid(
    changes: list[tuple[str, Any]],
) -> None:
    with Context(transport="local") as ctx:
        node = Node("n", context=ctx)
        binding = ParamBinding(node, Demo)
        with contextlib.suppress(VisnavError):
            node.set_parameters([Parameter(n, v) for n, v in changes])
        p = binding.value
        assert 0.1 <= p.rate <= 100.0
        assert math.isfinite(p.rate)
        assert 1 <= p.count <= 50
        assert p.topic == "scan"
        assert p.low <= p.high
        for name in ("rate", "count", "low", "high", "enabled", "names"):
            assert node.get_parameter(name).value == getattr(p, name)


@settings(max_examples=100, deadline=None)
@given(st.dictionaries(st.sampled_from(["rate", "count", "low", "names", "topic"]), _VALUES))
def test_fuzz_overrides_only_visnav_errors(overrides: dict[str, Any]) -> None:
    with Context(transport="local") as ctx:
        node = Node("n", context=ctx, parameter_overrides=overrides)
        try:
            p = declare_params(node, Demo)
        except VisnavError:
            return
        assert 0.1 <= p.rate <= 100.0
        assert p.low <= p.high
