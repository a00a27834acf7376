from __future__ import annotations

import pytest

from visnav.graph import (
    Clock,
    ClockType,
    DurabilityPolicy,
    GraphError,
    Parameter,
    ParameterAlreadyDeclaredError,
    ParameterError,
    ParameterNotDeclaredError,
    QoSProfile,
    ReliabilityPolicy,
    check_qos_compatibility,
    qos_profile_sensor_data,
)
from visnav.graph.parameters import ParameterStore, SetParametersResult
from visnav.graph.qos import HistoryPolicy, to_qos


def test_qos_compatibility_rules() -> None:
    rel, be = QoSProfile(), QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT)
    tl = QoSProfile(durability=DurabilityPolicy.TRANSIENT_LOCAL)
    assert check_qos_compatibility(rel, be)[0]
    ok, why = check_qos_compatibility(be, rel)
    assert not ok
    assert "best_effort" in why
    assert check_qos_compatibility(tl, rel)[0]
    ok, why = check_qos_compatibility(rel, tl)
    assert not ok
    assert "transient_local" in why


def test_qos_depth_and_int_shortcut() -> None:
    assert to_qos(5) == QoSProfile(depth=5)
    assert qos_profile_sensor_data.reliability is ReliabilityPolicy.BEST_EFFORT
    with pytest.raises(GraphError, match="depth"):
        QoSProfile(depth=0)
    assert QoSProfile(depth=0, history=HistoryPolicy.KEEP_ALL).queue_limit is None
    with pytest.raises(GraphError, match="QoSProfile or an int"):
        to_qos("10")  # type: ignore[arg-type]


def test_parameters_declare_override_and_types() -> None:
    store = ParameterStore("/n", {"rate": 5, "name": "cam"})
    assert store.declare("rate", 1.0).value == 5.0  # int override widened to double
    assert store.declare("name", "x").value == "cam"
    assert store.declare("flag", value=False).value is False
    with pytest.raises(ParameterAlreadyDeclaredError):
        store.declare("rate", 2.0)
    with pytest.raises(ParameterNotDeclaredError, match="did you mean rate"):
        store.get("rat")
    with pytest.raises(ParameterError, match="declared as DOUBLE"):
        store.set([Parameter("rate", "fast")])
    assert store.set([Parameter("rate", 7)])[0].successful
    assert store.get("rate").value == 7.0


def test_parameter_callback_can_refuse() -> None:
    store = ParameterStore("/n")
    store.declare("gain", 1.0)
    store.add_on_set_callback(
        lambda ps: SetParametersResult(successful=all(p.value > 0 for p in ps), reason="> 0")
    )
    assert not store.set([Parameter("gain", -1.0)])[0].successful
    assert store.get("gain").value == 1.0


def test_clock_sim_time() -> None:
    c = Clock(ClockType.ROS_TIME)
    assert c.now_ns() > 1_600_000_000 * 10**9
    c.enable_sim_time()
    assert c.now_ns() == 0
    c.set_sim_time_ns(1_500_000_000)
    assert c.now().nanoseconds == 1_500_000_000
    assert c.now().to_msg().sec == 1
    steady = Clock(ClockType.STEADY_TIME)
    steady.enable_sim_time()
    assert not steady.ros_time_is_active


def test_qos_policies_by_short_name_become_the_enums() -> None:
    qos = QoSProfile(depth=1, durability="transient_local", reliability="BEST_EFFORT")  # type: ignore[arg-type]
    assert qos.durability is DurabilityPolicy.TRANSIENT_LOCAL
    assert qos.reliability is ReliabilityPolicy.BEST_EFFORT
    assert qos == QoSProfile(
        depth=1,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
        reliability=ReliabilityPolicy.BEST_EFFORT,
    )


@pytest.mark.parametrize(
    ("field", "value"),
    [("durability", "latched"), ("history", 3), ("reliability", None), ("depth", "10")],
)
def test_qos_refuses_what_is_not_a_policy(field: str, value: object) -> None:
    with pytest.raises(GraphError, match=rf"QoSProfile\.{field} is"):
        QoSProfile(**{field: value})  # type: ignore[arg-type]
