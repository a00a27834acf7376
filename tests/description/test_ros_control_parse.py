"""libgazebo_ros_control.so and URDF <transmission> parsing (gazebo_ros_control's reading)."""

from __future__ import annotations

from xml.sax.saxutils import escape

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.description.gazebo import parse_gazebo_extensions
from visnav.description.gazebo_specs import RosControlSpec, TransmissionSpec
from visnav.description.urdf import RobotDescriptionError, parse_urdf
from visnav.errors import VisnavError

BASE = """<robot name="bot">
  <link name="base_link"/>
  <link name="left"/><link name="right"/><link name="arm"/><link name="tag"/>
  <joint name="left_joint" type="continuous"><parent link="base_link"/><child link="left"/>
    <origin xyz="0 0.2 0"/></joint>
  <joint name="right_joint" type="continuous"><parent link="base_link"/><child link="right"/>
    <origin xyz="0 -0.2 0"/></joint>
  <joint name="arm_joint" type="revolute"><parent link="base_link"/><child link="arm"/>
    <limit lower="-1" upper="1" effort="3" velocity="2"/></joint>
  <joint name="tag_joint" type="fixed"><parent link="base_link"/><child link="tag"/></joint>
  {body}
</robot>"""

PLUGIN = (
    '<gazebo><plugin name="gazebo_ros_control" filename="libgazebo_ros_control.so">{0}'
    "</plugin></gazebo>"
)


def transmission(joint: str, interface: str, *, name: str = "", kind: str = "") -> str:
    kind = kind or "transmission_interface/SimpleTransmission"
    return (
        f'<transmission name="{name or joint + "_trans"}"><type>{kind}</type>'
        f'<joint name="{joint}"><hardwareInterface>{interface}</hardwareInterface></joint>'
        '<actuator name="m"><mechanicalReduction>2</mechanicalReduction></actuator></transmission>'
    )


def parse(body: str) -> tuple[RosControlSpec | None, tuple[str, ...]]:
    urdf = parse_urdf(BASE.format(body=body))
    gz = parse_gazebo_extensions(urdf)
    spec = gz.ros_control[0] if gz.ros_control else None
    return spec, urdf.warnings + gz.warnings


def test_plugin_elements_and_defaults() -> None:
    spec, _ = parse(PLUGIN.format(""))
    assert spec == RosControlSpec(plugin_name="gazebo_ros_control", robot_namespace="/bot")
    spec, warnings = parse(
        PLUGIN.format(
            "<robotNamespace>/</robotNamespace><controlPeriod>0.01</controlPeriod>"
            "<robotSimType>gazebo_ros_control/DefaultRobotHWSim</robotSimType>"
            "<legacyModeNS>true</legacyModeNS><eStopTopic>e_stop</eStopTopic>"
            "<robotParam>my_description</robotParam><bogus/>"
        )
    )
    assert spec is not None
    assert spec.robot_namespace == "/"
    assert spec.control_period == 0.01
    assert spec.e_stop_topic == "e_stop"
    assert spec.robot_param == "my_description"
    assert any("<bogus>" in w and "ignored" in w for w in warnings)
    spec, _ = parse(PLUGIN.format("<robotNamespace>husky</robotNamespace>"))
    assert spec is not None
    assert spec.robot_namespace == "/husky"


@pytest.mark.parametrize(
    ("inner", "needle"),
    [
        ("<robotSimType>my_pkg/MyHWSim</robotSimType>", "DefaultRobotHWSim"),
        ("<controlPeriod>-1</controlPeriod>", "controlPeriod"),
        ("<controlPeriod>fast</controlPeriod>", "controlPeriod"),
        ("<legacyModeNS>maybe</legacyModeNS>", "legacyModeNS"),
    ],
)
def test_bad_plugin_values_are_one_clear_error(inner: str, needle: str) -> None:
    with pytest.raises(RobotDescriptionError, match=needle):
        parse(PLUGIN.format(inner))


def test_transmissions_long_and_short_interface_names() -> None:
    spec, warnings = parse(
        PLUGIN.format("")
        + transmission("left_joint", "hardware_interface/VelocityJointInterface")
        + transmission("right_joint", "VelocityJointInterface")
        + transmission("arm_joint", "hardware_interface/EffortJointInterface")
    )
    assert spec is not None
    assert spec.transmissions == (
        TransmissionSpec(
            name="left_joint_trans", joint="left_joint", interface="VelocityJointInterface",
            mechanical_reduction=2.0,
        ),
        TransmissionSpec(
            name="right_joint_trans", joint="right_joint", interface="VelocityJointInterface",
            mechanical_reduction=2.0,
        ),
        TransmissionSpec(
            name="arm_joint_trans", joint="arm_joint", interface="EffortJointInterface",
            mechanical_reduction=2.0,
        ),
    )  # fmt: skip
    deprecated = [w for w in warnings if "deprecated syntax" in w]
    assert len(deprecated) == 1
    assert "right_joint_trans" in deprecated[0]


def test_skipped_transmissions_warn_as_default_robot_hw_sim_logs() -> None:
    old_style = (
        '<transmission name="old" type="pr2_mechanism_model/SimpleTransmission">'
        '<joint name="left_joint"/><actuator name="m"/></transmission>'
    )
    on_actuator = (
        '<transmission name="act"><type>transmission_interface/SimpleTransmission</type>'
        '<joint name="right_joint"/><actuator name="m">'
        "<hardwareInterface>PositionJointInterface</hardwareInterface></actuator></transmission>"
    )
    no_interface = (
        '<transmission name="bare"><type>transmission_interface/SimpleTransmission</type>'
        '<joint name="left_joint"/></transmission>'
    )
    spec, warnings = parse(
        PLUGIN.format("")
        + old_style
        + no_interface
        + transmission("arm_joint", "hardware_interface/EffortJointInterface", kind="x/Other")
        + on_actuator
        + transmission("right_joint", "hardware_interface/VelocityJointInterface", name="again")
    )
    assert spec is not None
    assert [(t.name, t.interface) for t in spec.transmissions] == [
        ("arm_joint_trans", "EffortJointInterface"),  # DefaultRobotHWSim ignores the type
        ("act", "PositionJointInterface"),
    ]
    joined = "\n".join(warnings)
    for needle in (
        "'old' has no <type>",
        "'bare': joint 'left_joint' has no <hardwareInterface>",
        "inside <actuator> is deprecated",
        "'again': joint 'right_joint' already has transmission 'act'",
    ):
        assert needle in joined


@pytest.mark.parametrize(("joint", "needle"), [("nope", "does not exist"), ("tag_joint", "fixed")])
def test_transmission_of_a_joint_gazebo_cannot_move_is_an_error(joint: str, needle: str) -> None:
    with pytest.raises(RobotDescriptionError, match=needle) as info:
        parse(PLUGIN.format("") + transmission(joint, "VelocityJointInterface"))
    assert "left_joint" in str(info.value)  # the fix lists the moving joints


def test_an_unknown_hardware_interface_is_an_error() -> None:
    with pytest.raises(RobotDescriptionError, match="ImaginaryInterface") as info:
        parse(
            PLUGIN.format("") + transmission("left_joint", "hardware_interface/ImaginaryInterface")
        )
    assert "hardware_interface/VelocityJointInterface" in str(info.value)


def test_transmissions_without_the_plugin_only_warn() -> None:
    spec, warnings = parse(transmission("left_joint", "VelocityJointInterface"))
    assert spec is None
    assert any("left_joint_trans" in w and "no libgazebo_ros_control.so" in w for w in warnings)


_TAGS = st.sampled_from(
    ["robotNamespace", "controlPeriod", "robotSimType", "legacyModeNS", "eStopTopic", "x"]
)
_TEXT = st.one_of(
    st.sampled_from(["", "/", "0.01", "-3", "nan", "true", "maybe", "ns/a", "inf", "1e400"]),
    st.text(max_size=12),
)
_INTERFACES = st.one_of(
    st.sampled_from(
        [
            "hardware_interface/VelocityJointInterface",
            "EffortJointInterface",
            "PositionJointInterface",
            "hardware_interface/Nope",
            "",
        ]
    ),
    st.text(max_size=10),
)
_JOINTS = st.sampled_from(["left_joint", "right_joint", "arm_joint", "tag_joint", "nope", ""])


@st.composite
def _bodies(draw: st.DrawFn) -> str:
    elements = draw(st.lists(st.tuples(_TAGS, _TEXT), max_size=5))
    inner = "".join(f"<{tag}>{escape(text)}</{tag}>" for tag, text in elements)
    body = PLUGIN.format(inner) if draw(st.booleans()) else ""
    for joint, interface, kind, reduction in draw(
        st.lists(
            st.tuples(
                _JOINTS,
                _INTERFACES,
                st.sampled_from(["transmission_interface/SimpleTransmission", "other", ""]),
                _TEXT,
            ),
            max_size=4,
        )
    ):
        body += (
            f'<transmission name="t"><type>{escape(kind)}</type><joint name="{joint}">'
            f"<hardwareInterface>{escape(interface)}</hardwareInterface></joint>"
            f'<actuator name="m"><mechanicalReduction>{escape(reduction)}'
            "</mechanicalReduction></actuator></transmission>"
        )
    return body


@settings(max_examples=150, deadline=None)
@given(_bodies())
def test_fuzzed_plugins_and_transmissions_raise_only_visnav_errors(body: str) -> None:
    try:
        spec, _ = parse(body)
    except VisnavError:
        return
    if spec is not None:
        assert spec.control_period >= 0.0
        assert spec.robot_namespace.startswith("/")
        for t in spec.transmissions:
            assert t.joint in ("left_joint", "right_joint", "arm_joint")
