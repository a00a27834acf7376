"""Tests of visnav.graph.keys against rmw_zenoh's docs/design.md examples, and round trips."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.graph.keys import (
    TYPE_HASH_NOT_SUPPORTED,
    EntityKind,
    KeyExpressionError,
    LivelinessToken,
    TokenQoS,
    TopicKey,
    dds_type_to_ros,
    keyexpr_to_qos,
    liveliness_key_pattern,
    liveliness_token,
    parse_liveliness_token,
    parse_topic_key,
    qos_to_keyexpr,
    ros_type_to_dds,
    topic_key,
)

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"
STRING_DDS = "std_msgs::msg::dds_::String_"
ADD_TWO_INTS_DDS = "example_interfaces::srv::dds_::AddTwoInts_"

# --------------------------------------------------------------------------- type names


@pytest.mark.parametrize(
    ("ros", "dds"),
    [
        ("std_msgs/msg/String", STRING_DDS),
        ("sensor_msgs/msg/PointCloud2", "sensor_msgs::msg::dds_::PointCloud2_"),
        ("example_interfaces/srv/AddTwoInts", ADD_TWO_INTS_DDS),
        (
            "example_interfaces/action/Fibonacci_GetResult",
            "example_interfaces::action::dds_::Fibonacci_GetResult_",
        ),
    ],
)
def test_type_name_conversion(ros: str, dds: str) -> None:
    assert ros_type_to_dds(ros) == dds
    assert dds_type_to_ros(dds) == ros
    assert ros_type_to_dds(dds) == dds  # a DDS name passes through


@pytest.mark.parametrize("bad", ["std_msgs/String", "String", "std_msgs/idl/String", "a/msg/", ""])
def test_bad_ros_type_names(bad: str) -> None:
    with pytest.raises(KeyExpressionError, match=r"e\.g\. 'std_msgs/msg/String'"):
        ros_type_to_dds(bad)


@pytest.mark.parametrize(
    "bad",
    [
        "std_msgs::msg::String",
        "std_msgs::msg::dds_::String",
        "std_msgs/msg/String",
        "dds_::String_",
    ],
)
def test_bad_dds_type_names(bad: str) -> None:
    with pytest.raises(KeyExpressionError, match="not 'package::msg::dds_::Name_'"):
        dds_type_to_ros(bad)


# --------------------------------------------------------------------------- data keys


@pytest.mark.parametrize(
    ("domain", "topic", "type_name", "type_hash", "key"),
    [
        (
            0,
            "/chatter",
            "std_msgs/msg/String",
            STRING_HASH,
            f"0/chatter/{STRING_DDS}/{STRING_HASH}",
        ),
        (
            0,
            "/robot1/chatter",
            "std_msgs/msg/String",
            STRING_HASH,
            f"0/robot1/chatter/{STRING_DDS}/{STRING_HASH}",
        ),
        (
            2,
            "/add_two_ints",
            "example_interfaces/srv/AddTwoInts",
            ADD_TWO_INTS_HASH,
            f"2/add_two_ints/{ADD_TWO_INTS_DDS}/{ADD_TWO_INTS_HASH}",
        ),
        (
            0,
            "/chatter",
            "std_msgs/msg/Int32",
            TYPE_HASH_NOT_SUPPORTED,
            "0/chatter/std_msgs::msg::dds_::Int32_/TypeHashNotSupported",
        ),
    ],
)
def test_topic_key(domain: int, topic: str, type_name: str, type_hash: str, key: str) -> None:
    assert topic_key(domain, topic, type_name, type_hash) == key
    parsed = parse_topic_key(key)
    assert parsed == TopicKey(domain, topic, type_name, type_hash)
    assert parsed.to_key() == key


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((0, "chatter", "std_msgs/msg/String", STRING_HASH), "must start with '/'"),
        ((0, "/a//b", "std_msgs/msg/String", STRING_HASH), "must not contain '//'"),
        ((-1, "/chatter", "std_msgs/msg/String", STRING_HASH), "domain id is -1"),
        ((True, "/chatter", "std_msgs/msg/String", STRING_HASH), "domain id is True"),
        ((0, "/chatter", "std_msgs/String", STRING_HASH), "std_msgs/msg/String"),
        ((0, "/chatter", "std_msgs/msg/String", "RIHS01_abc"), "64 lowercase hex"),
        ((0, "/chatter", "std_msgs/msg/String", STRING_HASH.upper()), "64 lowercase hex"),
        ((0, "/chatter", "std_msgs/msg/String", ""), "TypeHashNotSupported"),
    ],
)
def test_topic_key_errors(args: tuple[object, ...], match: str) -> None:
    with pytest.raises(KeyExpressionError, match=match):
        topic_key(*args)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "key",
    [
        "chatter/std_msgs::msg::dds_::String_/TypeHashNotSupported",
        "0/std_msgs::msg::dds_::String_/TypeHashNotSupported",
        "x/chatter/std_msgs::msg::dds_::String_/TypeHashNotSupported",
        "0/chatter/std_msgs/TypeHashNotSupported",
        "0/chatter/std_msgs::msg::dds_::String_/nohash",
        "0/1chatter/std_msgs::msg::dds_::String_/TypeHashNotSupported",
    ],
)
def test_parse_topic_key_errors(key: str) -> None:
    with pytest.raises(KeyExpressionError):
        parse_topic_key(key)


# --------------------------------------------------------------------------- QoS chunk


class _Reliability(enum.Enum):
    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class _Durability(enum.Enum):
    VOLATILE = "volatile"
    TRANSIENT_LOCAL = "transient_local"


@dataclass(frozen=True)
class _Profile:
    reliability: _Reliability = _Reliability.RELIABLE
    durability: _Durability = _Durability.VOLATILE
    depth: int = 10
    history: str = "keep_last"


@pytest.mark.parametrize(
    ("qos", "text"),
    [
        (("reliable", "volatile", 10), "::,10:,:,:,,"),
        (("reliable", "volatile", 7), "::,7:,:,:,,"),
        (("best_effort", "volatile", 5), "2::,5:,:,:,,"),
        (("reliable", "transient_local", 1), ":1:,1:,:,:,,"),
        (("reliable", "volatile", 42), "::,:,:,:,,"),
        (("reliable", "volatile", 0), "::,:,:,:,,"),  # depth 0 = rmw_zenoh's default 42
        (("system_default", "system_default", 10, "system_default"), "::,10:,:,:,,"),
        (("reliable", "volatile", 10, "keep_all"), "::2,10:,:,:,,"),
        (("best_available", "best_available", 3), "4:4:,3:,:,:,,"),
        (("RELIABLE", "Transient_Local", 3), ":1:,3:,:,:,,"),
        ((2, 1, 3, 1), "2:1:,3:,:,:,,"),  # rmw's integer codes
        (TokenQoS("best_effort", "transient_local", 1), "2:1:,1:,:,:,,"),
        (_Profile(_Reliability.BEST_EFFORT, _Durability.TRANSIENT_LOCAL, 1), "2:1:,1:,:,:,,"),
        ((_Reliability.RELIABLE, _Durability.VOLATILE, 10), "::,10:,:,:,,"),
        (_Profile(history="keep_all"), "::2,10:,:,:,,"),
    ],
)
def test_qos_to_keyexpr(qos: object, text: str) -> None:
    assert qos_to_keyexpr(qos) == text


@pytest.mark.parametrize(
    ("text", "qos"),
    [
        ("::,10:,:,:,,", TokenQoS("reliable", "volatile", 10, "keep_last")),
        (
            "1:2:1,10:,:,:,,",
            TokenQoS("reliable", "volatile", 10, "keep_last"),
        ),  # defaults spelled out
        ("2:1:2,5:,:,:,,", TokenQoS("best_effort", "transient_local", 5, "keep_all")),
        ("::,:,:,:,,", TokenQoS("reliable", "volatile", 42, "keep_last")),
        ("::,10:1,0:5,0:3,1,0", TokenQoS("reliable", "volatile", 10, "keep_last")),
    ],
)
def test_keyexpr_to_qos(text: str, qos: TokenQoS) -> None:
    assert keyexpr_to_qos(text) == qos


@pytest.mark.parametrize(
    "text",
    [
        "1:2:1,10",  # the pre-2024 short layout
        "::,10:,:,:,,:",
        "::,10:,:,:,",
        "x::,10:,:,:,,",
        "::,-1:,:,:,,",
        "3::,10:,:,:,,",  # RELIABILITY_UNKNOWN
        ":::,10:,:,:,,",
        "",
    ],
)
def test_keyexpr_to_qos_errors(text: str) -> None:
    with pytest.raises(KeyExpressionError):
        keyexpr_to_qos(text)


@pytest.mark.parametrize(
    ("qos", "match"),
    [
        (("reliable", "volatile"), "expected \\(reliability, durability, depth\\)"),
        (("sometimes", "volatile", 1), "reliability is 'sometimes'"),
        (("reliable", "forever", 1), "durability is 'forever'"),
        (("reliable", "volatile", -1), "qos depth is -1"),
        (("reliable", "volatile", 1.5), "qos depth is 1.5"),
        (("reliable", "volatile", 1, "keep_some"), "history is 'keep_some'"),
        (object(), "expected \\(reliability"),
    ],
)
def test_qos_to_keyexpr_errors(qos: object, match: str) -> None:
    with pytest.raises(KeyExpressionError, match=match):
        qos_to_keyexpr(qos)


# --------------------------------------------------------------------------- liveliness tokens

LISTENER_ZID = "aac3178e146ba6f1fc6e6a4085e77f21"
TALKER_ZID = "8b20917502ee955ac4476e0266340d5c"


def test_design_doc_node_token() -> None:
    key = liveliness_token(2, LISTENER_ZID, 0, 0, "NN", "/", "listener")
    assert key == f"@ros2_lv/2/{LISTENER_ZID}/0/0/NN/%/%/listener"
    token = parse_liveliness_token(key)
    assert token.kind == "NN"
    assert token.kind is EntityKind.NODE
    assert (token.namespace, token.node_name, token.enclave) == ("/", "listener", "/")
    assert token.topic is None
    assert token.qos is None
    assert token.to_key() == key


@pytest.mark.parametrize(
    ("zid", "kind", "node", "topic", "type_name", "type_hash", "depth", "key_tail"),
    [
        (
            LISTENER_ZID,
            "MS",
            "listener",
            "/chatter",
            "std_msgs/msg/String",
            STRING_HASH,
            10,
            f"MS/%/%/listener/%chatter/{STRING_DDS}/{STRING_HASH}/::,10:,:,:,,",
        ),
        (
            TALKER_ZID,
            "MP",
            "talker",
            "/chatter",
            "std_msgs/msg/String",
            STRING_HASH,
            7,
            f"MP/%/%/talker/%chatter/{STRING_DDS}/{STRING_HASH}/::,7:,:,:,,",
        ),
        (
            "f9980ee0495eaafb3e38f0d19e2eae12",
            "SS",
            "add_two_ints_server",
            "/add_two_ints",
            "example_interfaces/srv/AddTwoInts",
            ADD_TWO_INTS_HASH,
            10,
            f"SS/%/%/add_two_ints_server/%add_two_ints/{ADD_TWO_INTS_DDS}/{ADD_TWO_INTS_HASH}/::,10:,:,:,,",
        ),
        (
            "e1dc8d1b45ae8717fce78689cc655685",
            "SC",
            "add_two_ints_client",
            "/add_two_ints",
            "example_interfaces/srv/AddTwoInts",
            ADD_TWO_INTS_HASH,
            10,
            f"SC/%/%/add_two_ints_client/%add_two_ints/{ADD_TWO_INTS_DDS}/{ADD_TWO_INTS_HASH}/::,10:,:,:,,",
        ),
    ],
)
def test_design_doc_endpoint_tokens(
    zid: str,
    kind: str,
    node: str,
    topic: str,
    type_name: str,
    type_hash: str,
    depth: int,
    key_tail: str,
) -> None:
    key = liveliness_token(
        2, zid, 0, 10, kind, "/", node, topic, type_name, type_hash, ("reliable", "volatile", depth)
    )
    assert key == f"@ros2_lv/2/{zid}/0/10/{key_tail}"
    token = parse_liveliness_token(key)
    assert token.kind == kind
    assert (token.topic, token.type_name, token.type_hash) == (topic, type_name, type_hash)
    assert (token.reliability, token.durability, token.depth) == ("reliable", "volatile", depth)
    assert token.to_key() == key


def test_humble_token_from_another_implementation() -> None:
    key = (
        "@ros2_lv/0/c40c0137f1e48f6cfee1f90b51ffd9aa/0/5/MP/%/%/mrm_handler/"
        "%system%fail_safe%mrm_state/std_msgs::msg::dds_::Int32_/TypeHashNotSupported/1:2:1,10:,:,:,,"
    )
    token = parse_liveliness_token(key)
    assert token.topic == "/system/fail_safe/mrm_state"
    assert token.type_name == "std_msgs/msg/Int32"
    assert token.type_hash == TYPE_HASH_NOT_SUPPORTED
    assert token.qos == TokenQoS("reliable", "volatile", 10, "keep_last")
    # visnav writes the defaults as empty fields, as rmw_zenoh does.
    assert token.to_key() == key.replace("1:2:1,10:", "::,10:")


def test_namespace_enclave_and_extra_chunks() -> None:
    key = liveliness_token(
        0,
        "0",
        3,
        4,
        EntityKind.PUBLISHER,
        "/robot1/sensors",
        "cam",
        "/robot1/sensors/cam/image_raw",
        "sensor_msgs/msg/Image",
        TYPE_HASH_NOT_SUPPORTED,
        ("best_effort", "volatile", 5),
        enclave="/secure",
    )
    assert key == (
        "@ros2_lv/0/0/3/4/MP/%secure/%robot1%sensors/cam/%robot1%sensors%cam%image_raw/"
        "sensor_msgs::msg::dds_::Image_/TypeHashNotSupported/2::,5:,:,:,,"
    )
    token = parse_liveliness_token(key)
    assert (token.enclave, token.namespace) == ("/secure", "/robot1/sensors")
    assert token.node_fully_qualified_name == "/robot1/sensors/cam"
    # Chunks a newer rmw_zenoh may append after the QoS are kept.
    extended = parse_liveliness_token(key + "/backend1")
    assert extended.extra == ("backend1",)
    assert extended.to_key() == key + "/backend1"


def test_liveliness_token_accepts_profile_objects_and_keeps_history() -> None:
    key = liveliness_token(
        0,
        "1",
        0,
        1,
        "MS",
        "/",
        "n",
        "/x",
        "std_msgs/msg/String",
        STRING_HASH,
        _Profile(history="keep_all"),
    )
    assert parse_liveliness_token(key).history == "keep_all"


def test_liveliness_key_pattern() -> None:
    assert liveliness_key_pattern(0) == "@ros2_lv/0/**"
    with pytest.raises(KeyExpressionError):
        liveliness_key_pattern(-3)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"zid": "XYZ"}, "lowercase hex"),
        ({"zid": "0" * 33}, "lowercase hex"),
        ({"kind": "XX"}, "entity kind 'XX'"),
        ({"node_id": -1}, "node id is -1"),
        ({"entity_id": 1}, "node id as entity id"),
        ({"namespace": "ns"}, "namespace"),
        ({"namespace": "/a%b"}, "namespace"),
        ({"node_name": "a/b"}, "node name"),
        ({"enclave": ""}, "enclave"),
        ({"topic": "/chatter"}, "no topic, type, hash or QoS"),
        ({"domain": "0"}, "domain id is '0'"),
    ],
)
def test_node_token_errors(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {
        "domain": 0,
        "zid": "1",
        "node_id": 0,
        "entity_id": 0,
        "kind": "NN",
        "namespace": "/",
        "node_name": "n",
    }
    args.update(kwargs)
    with pytest.raises(KeyExpressionError, match=match):
        liveliness_token(**args)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"qos": None}, "missing \\['qos'\\]"),
        ({"topic": None, "type_hash": None}, "missing \\['topic', 'type_hash'\\]"),
        ({"topic": "chatter"}, "must start with '/'"),
        ({"type_name": "String"}, "std_msgs/msg/String"),
        ({"type_hash": "md5"}, "REP 2016"),
        ({"qos": ("reliable", "sometimes", 1)}, "durability"),
    ],
)
def test_endpoint_token_errors(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {
        "domain": 0,
        "zid": "1",
        "node_id": 0,
        "entity_id": 1,
        "kind": "MP",
        "namespace": "/",
        "node_name": "n",
        "topic": "/chatter",
        "type_name": "std_msgs/msg/String",
        "type_hash": STRING_HASH,
        "qos": ("reliable", "volatile", 1),
    }
    args.update(kwargs)
    with pytest.raises(KeyExpressionError, match=match):
        liveliness_token(**args)  # type: ignore[arg-type]


GOOD_MP = f"@ros2_lv/0/1/0/1/MP/%/%/n/%chatter/{STRING_DDS}/{STRING_HASH}/::,1:,:,:,,"


@pytest.mark.parametrize(
    "key",
    [
        GOOD_MP.replace("@ros2_lv", "@ros2_xx"),
        GOOD_MP.replace("/MP/", "/XX/"),
        GOOD_MP.replace("@ros2_lv/0/", "@ros2_lv/zero/"),
        GOOD_MP.replace("/0/1/MP/", "/0/-1/MP/"),
        GOOD_MP.replace("/%/n/", "//n/"),
        GOOD_MP.rsplit("/", 1)[0],
        GOOD_MP.replace("::,1:", "::,1"),
        GOOD_MP.replace(STRING_DDS, "std_msgs/msg/String".replace("/", "%")),
        GOOD_MP.replace("/%/%/n/", "/%/%/a%b/"),
        "@ros2_lv/0/1/0/0/NN/%/%",
        "@ros2_lv/0/1/0/0/NN/%/%/n/%chatter",
        "0/chatter/std_msgs::msg::dds_::String_/TypeHashNotSupported",
        "",
    ],
)
def test_parse_liveliness_token_errors(key: str) -> None:
    assert parse_liveliness_token(GOOD_MP).to_key() == GOOD_MP
    with pytest.raises(KeyExpressionError):
        parse_liveliness_token(key)


def test_key_errors_are_value_errors() -> None:
    # The graph cache skips foreign tokens by catching ValueError.
    with pytest.raises(ValueError) as info:  # noqa: PT011
        parse_liveliness_token("@ros2_lv/nope")
    assert isinstance(info.value, VisnavError)


# --------------------------------------------------------------------------- properties

tokens = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,7}", fullmatch=True)
full_names = st.lists(tokens, min_size=1, max_size=4).map(lambda ts: "/" + "/".join(ts))
namespaces = st.lists(tokens, min_size=0, max_size=3).map(lambda ts: "/" + "/".join(ts))
type_names = st.tuples(
    st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True),
    st.sampled_from(["msg", "srv", "action"]),
    st.from_regex(r"[A-Z][A-Za-z0-9_]{0,8}", fullmatch=True),
).map("/".join)
type_hashes = st.one_of(
    st.just(TYPE_HASH_NOT_SUPPORTED),
    st.binary(min_size=32, max_size=32).map(lambda b: "RIHS01_" + b.hex()),
)
qos_fields = st.tuples(
    st.sampled_from(["reliable", "best_effort", "best_available"]),
    st.sampled_from(["volatile", "transient_local", "best_available"]),
    st.integers(min_value=1, max_value=10_000),
    st.sampled_from(["keep_last", "keep_all"]),
)
zids = st.from_regex(r"[0-9a-f]{1,32}", fullmatch=True)
ids = st.integers(min_value=0, max_value=10**6)


@given(st.integers(0, 232), full_names, type_names, type_hashes)
def test_topic_key_round_trip(domain: int, topic: str, type_name: str, type_hash: str) -> None:
    key = topic_key(domain, topic, type_name, type_hash)
    assert parse_topic_key(key) == TopicKey(domain, topic, type_name, type_hash)


@given(qos_fields)
def test_qos_round_trip(fields: tuple[str, str, int, str]) -> None:
    assert keyexpr_to_qos(qos_to_keyexpr(fields)) == TokenQoS(*fields)


@given(st.integers(0, 232), zids, ids, tokens, namespaces, tokens.map(lambda t: "/" + t))
def test_node_token_round_trip(
    domain: int, zid: str, node_id: int, name: str, ns: str, enclave: str
) -> None:
    key = liveliness_token(domain, zid, node_id, node_id, "NN", ns, name, enclave=enclave)
    token = parse_liveliness_token(key)
    assert token == LivelinessToken(
        domain, zid, node_id, node_id, EntityKind.NODE, ns, name, enclave
    )
    assert token.to_key() == key
    assert key.count("/") == 8


@given(
    st.integers(0, 232),
    zids,
    ids,
    ids,
    st.sampled_from(["MP", "MS", "SS", "SC"]),
    namespaces,
    tokens,
    full_names,
    type_names,
    type_hashes,
    qos_fields,
)
def test_endpoint_token_round_trip(
    domain: int,
    zid: str,
    node_id: int,
    entity_id: int,
    kind: str,
    ns: str,
    name: str,
    topic: str,
    type_name: str,
    type_hash: str,
    qos: tuple[str, str, int, str],
) -> None:
    key = liveliness_token(
        domain, zid, node_id, entity_id, kind, ns, name, topic, type_name, type_hash, qos
    )
    token = parse_liveliness_token(key)
    assert (token.domain, token.zid, token.node_id, token.entity_id) == (
        domain,
        zid,
        node_id,
        entity_id,
    )
    assert (token.kind, token.namespace, token.node_name) == (kind, ns, name)
    assert (token.topic, token.type_name, token.type_hash) == (topic, type_name, type_hash)
    assert token.qos == TokenQoS(*qos)
    assert token.to_key() == key
    assert key.count("/") == 12
