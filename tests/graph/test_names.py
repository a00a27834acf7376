"""Tests of visnav.graph.names: tables from the ROS 2 design article and rcl, and properties."""

from __future__ import annotations

import pickle
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.graph.names import (
    NAMESPACE_MAX_LENGTH,
    NODE_NAME_MAX_LENGTH,
    TOPIC_NAME_MAX_LENGTH,
    InvalidNameError,
    RemapKind,
    Remapping,
    RemapRule,
    as_remapping,
    demangle_name,
    expand_topic_name,
    is_hidden_name,
    join_namespace,
    mangle_name,
    namespace_of,
    normalize_namespace,
    parse_remap_rule,
    resolve_node_name_and_namespace,
    resolve_topic_name,
    split_name,
    validate_full_topic_name,
    validate_namespace,
    validate_node_name,
    validate_topic_name,
)

# --------------------------------------------------------------------------- strategies

tokens = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,7}", fullmatch=True)
# Tokens remap rules accept (rcl's lexer): no leading digit, no "__".
rule_tokens = st.from_regex(r"(?:[A-Za-z]_?|_)(?:[0-9A-Za-z]_?){0,5}", fullmatch=True)
full_names = st.lists(tokens, min_size=1, max_size=5).map(lambda ts: "/" + "/".join(ts))
namespaces = st.lists(tokens, min_size=0, max_size=4).map(lambda ts: "/" + "/".join(ts))
relative_names = st.lists(tokens, min_size=1, max_size=4).map("/".join)
rule_names = st.lists(rule_tokens, min_size=1, max_size=3).map("/".join)


def _check(func, name: str, rule: str, index: int | None) -> InvalidNameError:
    with pytest.raises(InvalidNameError) as info:
        func(name)
    assert info.value.rule == rule, str(info.value)
    assert info.value.index == index, str(info.value)
    assert info.value.name == name
    return info.value


# --------------------------------------------------------------------------- validation tables

# "ROS 2 Name Examples" of the design article plus rcl's corner cases (test_validate_topic_name).
VALID_TOPIC_NAMES = [
    "foo", "abc123", "_foo", "Foo", "BAR", "~", "foo/bar", "~/foo", "{foo}_bar",
    "foo/{ping}/bar", "foo/_bar", "foo_/bar", "foo_", "/foo", "/bar/baz", "/_private/thing",
    "/public_namespace/_private/thing", "{foo1}", "{foo_bar}", "{_bar}", "/{node}", "a__b",
]  # fmt: skip

# (name, rule, index): the rcl test table, then three names visnav rejects earlier than rcl.
INVALID_TOPIC_NAMES = [
    ("123abc", "token_starts_with_number", 0),
    ("123", "token_starts_with_number", 0),
    (" ", "unallowed_characters", 0),
    ("foo bar", "unallowed_characters", 3),
    ("/~", "misplaced_tilde", 1),
    ("~foo", "tilde_not_followed_by_slash", 1),
    ("foo~", "misplaced_tilde", 3),
    ("foo~/bar", "misplaced_tilde", 3),
    ("foo/~bar", "misplaced_tilde", 4),
    ("foo/~/bar", "misplaced_tilde", 4),
    ("foo/", "ends_with_slash", 3),
    ("", "empty", 0),
    ("foo/123bar", "token_starts_with_number", 4),
    ("foo/bar}/baz", "unmatched_curly_brace", 7),
    ("foo/{bar", "unmatched_curly_brace", 4),
    ("{$}", "substitution_unallowed_characters", 1),
    ("{{bar}_baz}", "substitution_unallowed_characters", 1),
    ("foo/{bar/baz}", "substitution_unallowed_characters", 8),
    ("{1foo}", "substitution_starts_with_number", 1),
    # rcl lets these through validation; they can never expand to a valid name.
    ("foo//bar", "repeated_slash", 4),
    ("{}", "empty_substitution", 0),
    ("~f", "tilde_not_followed_by_slash", 1),
]


@pytest.mark.parametrize("name", VALID_TOPIC_NAMES)
def test_valid_topic_names(name: str) -> None:
    validate_topic_name(name)


@pytest.mark.parametrize(("name", "rule", "index"), INVALID_TOPIC_NAMES)
def test_invalid_topic_names(name: str, rule: str, index: int) -> None:
    _check(validate_topic_name, name, rule, index)


@pytest.mark.parametrize(
    "name",
    ["/foo", "/bar/baz", "/_private/thing", "/public_namespace/_private/thing", "/a__b", "/a_"],
)
def test_valid_full_topic_names(name: str) -> None:
    validate_full_topic_name(name)


@pytest.mark.parametrize(
    ("name", "rule", "index"),
    [
        ("", "empty", 0),
        ("foo", "not_absolute", 0),
        ("~/foo", "not_absolute", 0),
        ("/", "ends_with_slash", 0),
        ("/foo/", "ends_with_slash", 4),
        ("/foo bar", "unallowed_characters", 4),
        ("/~/foo", "unallowed_characters", 1),
        ("/{node}", "unallowed_characters", 1),
        ("/foo//bar", "repeated_slash", 5),
        ("/1foo", "token_starts_with_number", 1),
        ("/foo/2", "token_starts_with_number", 5),
        ("/" + "a" * TOPIC_NAME_MAX_LENGTH, "too_long", TOPIC_NAME_MAX_LENGTH - 1),
    ],
)
def test_invalid_full_topic_names(name: str, rule: str, index: int) -> None:
    _check(validate_full_topic_name, name, rule, index)


def test_full_topic_name_length_limit_is_inclusive() -> None:
    validate_full_topic_name("/" + "a" * (TOPIC_NAME_MAX_LENGTH - 1))


@pytest.mark.parametrize("name", ["my_node", "_n", "N1", "talker", "a" * NODE_NAME_MAX_LENGTH])
def test_valid_node_names(name: str) -> None:
    validate_node_name(name)


@pytest.mark.parametrize(
    ("name", "rule", "index"),
    [
        ("", "empty", 0),
        ("my/node", "unallowed_characters", 2),
        ("/invalid_node", "unallowed_characters", 0),
        ("~node", "unallowed_characters", 0),
        ("node-1", "unallowed_characters", 4),
        ("nöde", "unallowed_characters", 1),
        ("1node", "token_starts_with_number", 0),
        ("a" * (NODE_NAME_MAX_LENGTH + 1), "too_long", NODE_NAME_MAX_LENGTH - 1),
    ],
)
def test_invalid_node_names(name: str, rule: str, index: int) -> None:
    _check(validate_node_name, name, rule, index)


def test_node_name_with_slash_suggests_namespace() -> None:
    err = _check(validate_node_name, "robot/camera", "unallowed_characters", 5)
    assert "name 'camera' with namespace '/robot'" in err.fix


@pytest.mark.parametrize(
    "ns", ["/", "/ns", "/a/b_c", "/_hidden", "/" + "a" * (NAMESPACE_MAX_LENGTH - 1)]
)
def test_valid_namespaces(ns: str) -> None:
    validate_namespace(ns)


@pytest.mark.parametrize(
    ("ns", "rule", "index"),
    [
        ("", "empty", 0),
        ("ns", "not_absolute", 0),
        ("/ns/", "ends_with_slash", 3),
        ("//", "ends_with_slash", 1),
        ("/a//b", "repeated_slash", 3),
        ("/1a", "token_starts_with_number", 1),
        ("/a b", "unallowed_characters", 2),
        ("white space", "not_absolute", 0),
        ("/" + "a" * NAMESPACE_MAX_LENGTH, "too_long", NAMESPACE_MAX_LENGTH - 1),
    ],
)
def test_invalid_namespaces(ns: str, rule: str, index: int) -> None:
    _check(validate_namespace, ns, rule, index)


def test_error_message_names_value_rule_and_fix() -> None:
    err = _check(validate_full_topic_name, "/foo//bar", "repeated_slash", 5)
    text = str(err)
    assert "'/foo//bar'" in text
    assert "must not contain '//'" in text
    assert "fix: remove the repeated '/': '/foo/bar'" in text
    err = _check(validate_topic_name, "foo/", "ends_with_slash", 3)
    assert "must not end with '/'" in str(err)
    assert "'foo'" in err.fix
    err = _check(validate_topic_name, "foo/1bar", "token_starts_with_number", 4)
    assert "tokens must not start with a digit" in str(err)
    assert "'_1bar'" in err.fix
    err = _check(validate_topic_name, "foo bar", "unallowed_characters", 3)
    assert "alphanumerics, '_', '/', a leading '~' and '{' '}' substitutions" in str(err)
    assert "'foo_bar'" in err.fix


def test_error_is_value_error_and_visnav_error_and_pickles() -> None:
    err = _check(validate_namespace, "ns", "not_absolute", 0)
    assert isinstance(err, ValueError)
    assert isinstance(err, VisnavError)
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is InvalidNameError
    assert (back.kind, back.name, back.rule, back.index, str(back)) == (
        err.kind,
        err.name,
        err.rule,
        err.index,
        str(err),
    )


@pytest.mark.parametrize(
    "func", [validate_topic_name, validate_full_topic_name, validate_node_name, validate_namespace]
)
def test_non_string_is_type_error(func) -> None:
    with pytest.raises(TypeError, match="must be a str"):
        func(b"/foo")


# Reference validators written independently from the scanning implementation.
_REF_SUB = r"\{[A-Za-z_][A-Za-z0-9_]*\}"
_REF_TOKEN = rf"(?:[A-Za-z_]|{_REF_SUB})(?:[A-Za-z0-9_]|{_REF_SUB})*"
_REF_TOPIC = re.compile(rf"~|~/{_REF_TOKEN}(?:/{_REF_TOKEN})*|/?{_REF_TOKEN}(?:/{_REF_TOKEN})*")
_REF_FULL = re.compile(r"(?:/[A-Za-z_][A-Za-z0-9_]*)+")


def _is_valid(func, name: str) -> bool:
    try:
        func(name)
    except InvalidNameError:
        return False
    return True


@given(st.text(alphabet="a1_/~{}$ ", max_size=12))
def test_validate_topic_name_matches_reference_grammar(name: str) -> None:
    assert _is_valid(validate_topic_name, name) == bool(_REF_TOPIC.fullmatch(name))


@given(st.text(alphabet="aZ1_/~{} %", max_size=12))
def test_validate_full_topic_name_matches_reference_grammar(name: str) -> None:
    assert _is_valid(validate_full_topic_name, name) == bool(_REF_FULL.fullmatch(name))


@given(st.text(alphabet="aZ1_/ ", max_size=10))
def test_validate_namespace_matches_reference_grammar(ns: str) -> None:
    assert _is_valid(validate_namespace, ns) == (ns == "/" or bool(_REF_FULL.fullmatch(ns)))


# --------------------------------------------------------------------------- expansion

# rcl's test_expand_topic_name table (input, node, namespace, expected).
EXPANSIONS = [
    ("/chatter", "my_node", "/my_ns", "/chatter"),
    ("chatter", "my_node", "/my_ns", "/my_ns/chatter"),
    ("{node}/chatter", "my_node", "/my_ns", "/my_ns/my_node/chatter"),
    ("/{node}", "my_node", "/my_ns", "/my_node"),
    ("{node}", "my_node", "/my_ns", "/my_ns/my_node"),
    ("{ns}", "my_node", "/my_ns", "/my_ns"),
    ("{namespace}", "my_node", "/my_ns", "/my_ns"),
    ("{namespace}/{node}/chatter", "my_node", "/my_ns", "/my_ns/my_node/chatter"),
    ("ping", "my_node", "/", "/ping"),
    ("ping", "my_node", "/my_ns", "/my_ns/ping"),
    ("/ping", "my_node", "/", "/ping"),
    ("/ping", "my_node", "/my_ns", "/ping"),
    ("~", "my_node", "/", "/my_node"),
    ("~", "my_node", "/my_ns", "/my_ns/my_node"),
    ("~/ping", "my_node", "/", "/my_node/ping"),
    ("~/ping", "my_node", "/my_ns", "/my_ns/my_node/ping"),
    ("~/{node}", "n", "/a/b", "/a/b/n/n"),
    ("{node}_{node}", "n", "/", "/n_n"),
]


@pytest.mark.parametrize(("name", "node", "ns", "expected"), EXPANSIONS)
def test_expand_topic_name(name: str, node: str, ns: str, expected: str) -> None:
    assert expand_topic_name(name, node, ns) == expected


def test_expand_can_produce_rcls_invalid_names_without_validation() -> None:
    # rcl's own table has this case: expansion succeeds, full validation fails.
    assert (
        expand_topic_name("/foo/{namespace}", "my_node", "/my_ns", validate=False) == "/foo//my_ns"
    )
    with pytest.raises(InvalidNameError) as info:
        expand_topic_name("/foo/{namespace}", "my_node", "/my_ns")
    assert info.value.rule == "repeated_slash"
    assert info.value.kind == "expanded topic name"
    assert "expanded from '/foo/{namespace}'" in str(info.value)


def test_ns_substitution_in_root_namespace_explains_fix() -> None:
    assert expand_topic_name("{ns}/x", "n", "/", validate=False) == "//x"
    with pytest.raises(InvalidNameError, match="write the relative name 'x' instead"):
        expand_topic_name("{ns}/x", "n", "/")
    assert expand_topic_name("{ns}/x", "n", "/robot") == "/robot/x"


def test_expand_custom_and_unknown_substitutions() -> None:
    assert (
        expand_topic_name("{ping}", "my_node", "/my_ns", substitutions={"ping": "pong"})
        == "/my_ns/pong"
    )
    assert expand_topic_name("{r}/x", "n", "/", substitutions={"r": "/abs/robot"}) == "/abs/robot/x"
    with pytest.raises(InvalidNameError) as info:
        expand_topic_name("{doesnotexist}", "my_node", "/my_ns")
    assert info.value.rule == "unknown_substitution"
    assert info.value.index == 0
    assert "{node}, {ns}, {namespace}" in info.value.fix


@pytest.mark.parametrize(
    "subs",
    [{"node": "x"}, {"ns": "/x"}, {"1a": "x"}, {"a": ""}, {"a": "x y"}, {"a": "{b}"}, {"a": "~/x"}],
)
def test_expand_rejects_bad_substitutions(subs: dict[str, str]) -> None:
    with pytest.raises(InvalidNameError) as info:
        expand_topic_name("{a}", "n", "/", substitutions=subs)
    assert info.value.rule == "bad_substitution"


@pytest.mark.parametrize(
    ("name", "node", "ns", "kind"),
    [
        ("white space", "my_node", "/my_ns", "topic name"),
        ("{node}/chatter", "/invalid_node", "/my_ns", "node name"),
        ("{node}/chatter", "my_node", "white space", "namespace"),
        ("{node}/chatter", "my_node", "", "namespace"),
    ],
)
def test_expand_validates_inputs(name: str, node: str, ns: str, kind: str) -> None:
    with pytest.raises(InvalidNameError) as info:
        expand_topic_name(name, node, ns)
    assert info.value.kind == kind


def test_expanded_name_too_long() -> None:
    ns = "/" + "n" * 200
    with pytest.raises(InvalidNameError) as info:
        expand_topic_name("x" * 60, "node", ns)
    assert info.value.rule == "too_long"


@given(full_names, tokens, namespaces)
def test_expanding_an_absolute_name_is_identity(name: str, node: str, ns: str) -> None:
    assert expand_topic_name(name, node, ns) == name


@given(relative_names, tokens, namespaces)
def test_relative_and_private_names_land_under_the_node(name: str, node: str, ns: str) -> None:
    assert expand_topic_name(name, node, ns) == join_namespace(ns, name)
    private = expand_topic_name("~/" + name, node, ns)
    assert private == join_namespace(join_namespace(ns, node), name)
    assert namespace_of(expand_topic_name("~", node, ns)) == ns


# --------------------------------------------------------------------------- helpers


@pytest.mark.parametrize(
    ("ns", "name", "expected"),
    [
        ("/a", "b/c", "/a/b/c"),
        ("/", "b", "/b"),
        ("", "b", "/b"),
        ("/ns", "talker", "/ns/talker"),
        ("/ns", "", "/ns"),
        ("/", "", "/"),
    ],
)
def test_join_namespace(ns: str, name: str, expected: str) -> None:
    assert join_namespace(ns, name) == expected


def test_join_namespace_rejects_absolute_name_and_relative_namespace() -> None:
    with pytest.raises(InvalidNameError, match="absolute"):
        join_namespace("/a", "/b")
    with pytest.raises(InvalidNameError, match="must start with '/'"):
        join_namespace("a", "b")


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("/a/b/c", ("/a/b", "c")),
        ("/c", ("/", "c")),
        ("a/b", ("a", "b")),
        ("c", ("", "c")),
        ("/", ("/", "")),
    ],
)
def test_split_name_and_namespace_of(name: str, expected: tuple[str, str]) -> None:
    assert split_name(name) == expected
    assert namespace_of(name) == expected[0]


@given(full_names)
def test_split_then_join_round_trips(name: str) -> None:
    ns, base = split_name(name)
    assert join_namespace(ns, base) == name


@pytest.mark.parametrize(("ns", "expected"), [("", "/"), ("/", "/"), ("a", "/a"), ("/a/b", "/a/b")])
def test_normalize_namespace(ns: str, expected: str) -> None:
    assert normalize_namespace(ns) == expected


@pytest.mark.parametrize(
    ("name", "hidden"),
    [("/a/_b", True), ("/_a/b", True), ("_x", True), ("/a/b", False), ("/a_/b", False)],
)
def test_is_hidden_name(name: str, hidden: bool) -> None:
    assert is_hidden_name(name) is hidden


@pytest.mark.parametrize(
    ("name", "mangled"),
    [("/a/b", "%a%b"), ("/", "%"), ("/robot1", "%robot1"), ("talker", "talker")],
)
def test_mangle_name(name: str, mangled: str) -> None:
    assert mangle_name(name) == mangled
    assert demangle_name(mangled) == name


def test_mangle_rejects_percent() -> None:
    with pytest.raises(InvalidNameError) as info:
        mangle_name("/a%b")
    assert (info.value.rule, info.value.index) == ("contains_percent", 2)


@given(st.one_of(full_names, namespaces, tokens))
def test_valid_names_round_trip_through_mangling(name: str) -> None:
    mangled = mangle_name(name)
    assert "/" not in mangled
    assert demangle_name(mangled) == name


# --------------------------------------------------------------------------- remap rules

# rcl's test_arguments: remap rules it accepts ...
VALID_RULES = [
    ("__node:=node_name", RemapKind.NODE_NAME, None, "node_name", None),
    ("old_name:__node:=node_name", RemapKind.NODE_NAME, None, "node_name", "old_name"),
    ("old_name:__node:=nodename123", RemapKind.NODE_NAME, None, "nodename123", "old_name"),
    ("__node:=nodename123", RemapKind.NODE_NAME, None, "nodename123", None),
    ("__name:=ros1_style", RemapKind.NODE_NAME, None, "ros1_style", None),
    ("__ns:=/foo/bar", RemapKind.NAMESPACE, None, "/foo/bar", None),
    ("__ns:=/", RemapKind.NAMESPACE, None, "/", None),
    ("_:=kq", RemapKind.NAME, "_", "kq", None),
    ("nodename:__ns:=/foobar", RemapKind.NAMESPACE, None, "/foobar", "nodename"),
    ("foo:=bar", RemapKind.NAME, "foo", "bar", None),
    ("~/foo:=~/bar", RemapKind.NAME, "~/foo", "~/bar", None),
    ("/foo/bar:=bar", RemapKind.NAME, "/foo/bar", "bar", None),
    ("foo:=/bar", RemapKind.NAME, "foo", "/bar", None),
    ("/foo123:=/bar123", RemapKind.NAME, "/foo123", "/bar123", None),
    ("node:/foo123:=/bar123", RemapKind.NAME, "/foo123", "/bar123", "node"),
    ("rostopic:=/foo/bar", RemapKind.NAME, "rostopic", "/foo/bar", None),
    ("rosservice:=baz", RemapKind.NAME, "rosservice", "baz", None),
    ("rostopic://rostopic:=rosservice", RemapKind.TOPIC, "rostopic", "rosservice", None),
    ("rostopic:///rosservice:=rostopic", RemapKind.TOPIC, "/rosservice", "rostopic", None),
    ("rostopic:///foo/bar:=baz", RemapKind.TOPIC, "/foo/bar", "baz", None),
    ("rosservice://foo:=bar", RemapKind.SERVICE, "foo", "bar", None),
    ("n:rosservice://foo:=bar", RemapKind.SERVICE, "foo", "bar", "n"),
]

# ... and rejects (plus wildcards, back-references and substitutions rcl does not implement).
INVALID_RULES = [
    ":=", "foo:=", ":=bar", "__ns:=", "__node:=", "__node:=/foo/bar", "__ns:=foo",
    ":__node:=nodename", "~:__node:=nodename", "}foo:=/bar", "f oo:=/bar", "foo:=/b ar",
    "f{oo:=/bar", "foo:=/b}ar", "rostopic://:=rosservice", "rostopic::=rosservice",
    "__param:=file_name.yaml", "foo", "~:=x", "/a/*:=b", "**:=b", "foo:=\\1", "{node}:=x",
    "a__b:=c", "1a:=b", "foo:=rostopic://bar", "a:=b:=c", "__ns:=/a//b",
]  # fmt: skip


@pytest.mark.parametrize(("text", "kind", "match", "replacement", "node"), VALID_RULES)
def test_parse_valid_remap_rules(
    text: str, kind: RemapKind, match: str | None, replacement: str, node: str | None
) -> None:
    rule = parse_remap_rule(text)
    assert (rule.kind, rule.match, rule.replacement, rule.node) == (kind, match, replacement, node)
    assert parse_remap_rule(str(rule)) == rule


@pytest.mark.parametrize("text", INVALID_RULES)
def test_parse_invalid_remap_rules(text: str) -> None:
    with pytest.raises(InvalidNameError) as info:
        parse_remap_rule(text)
    assert info.value.rule == "invalid_remap_rule"
    assert info.value.name == text
    assert "fix:" in str(info.value)


def test_remap_rule_construction_is_validated() -> None:
    assert RemapRule(RemapKind.NAME, "bar", match="foo") == parse_remap_rule("foo:=bar")
    with pytest.raises(InvalidNameError):
        RemapRule(RemapKind.NAME, "bar", match="fo o")
    with pytest.raises(InvalidNameError):
        RemapRule(RemapKind.NODE_NAME, "x", match="y")
    with pytest.raises(TypeError):
        RemapRule("name", "bar", match="foo")  # type: ignore[arg-type]


rule_texts = st.one_of(
    st.tuples(
        st.sampled_from(["", "rostopic://", "rosservice://"]),
        st.sampled_from(["", "/", "~/"]),
        rule_names,
        st.sampled_from(["", "/", "~/"]),
        rule_names,
    ).map(lambda t: f"{t[0]}{t[1]}{t[2]}:={t[3]}{t[4]}"),
    rule_tokens.map(lambda t: f"__node:={t}"),
    namespaces.filter(lambda ns: "__" not in ns).map(lambda ns: f"__ns:={ns}"),
)


@given(st.one_of(rule_tokens.map(lambda n: n + ":"), st.just("")), rule_texts)
def test_remap_rule_text_round_trips(prefix: str, text: str) -> None:
    rule = parse_remap_rule(prefix + text)
    assert str(rule) == (prefix + text).replace("__name:=", "__node:=")
    assert parse_remap_rule(str(rule)) == rule


# ------------------------------------------------------------------------ remapping (rcl's tests)


def test_absolute_topic_rule() -> None:
    rules = Remapping(["/bar/foo:=/foo/bar"])
    assert rules.remap_topic_name("/bar/foo", "NodeName", "/") == "/foo/bar"
    assert rules.remap_topic_name("/foo/bar", "NodeName", "/") is None
    assert rules.remap_topic_name("/bar/foo", "NodeName", "/", is_service=True) == "/foo/bar"


def test_relative_rule_is_matched_after_expansion() -> None:
    rules = Remapping("foo:=bar")
    assert rules.remap_topic_name("/ns/foo", "NodeName", "/ns") == "/ns/bar"
    assert rules.remap_topic_name("/foo", "NodeName", "/ns") is None


def test_private_rule() -> None:
    rules = Remapping(["~/x:=y"])
    assert rules.remap_topic_name("/ns/n/x", "n", "/ns") == "/ns/y"
    assert rules.remap_topic_name("/ns/x", "n", "/ns") is None


def test_node_targeted_rules() -> None:
    rules = Remapping(["Node1:/foo:=/foo/bar", "Node2:/foo:=/this_one", "Node3:/foo:=/bar/foo"])
    assert rules.remap_topic_name("/foo", "Node1", "/") == "/foo/bar"
    assert rules.remap_topic_name("/foo", "Node2", "/") == "/this_one"
    assert rules.remap_topic_name("/foo", "Node3", "/") == "/bar/foo"
    assert rules.remap_topic_name("/foo", "Node4", "/") is None


def test_local_rules_before_global_and_first_match_wins() -> None:
    local = Remapping(["/bar/foo:=/foo/local_args"])
    global_ = Remapping(["/bar/foo:=/foo/global_args"])
    assert (local + global_).remap_topic_name("/bar/foo", "NodeName", "/") == "/foo/local_args"
    assert (global_ + local).remap_topic_name("/bar/foo", "NodeName", "/") == "/foo/global_args"
    extra = ["__ns:=/x"]
    assert (local + extra).rules[-1] == parse_remap_rule("__ns:=/x")


def test_other_rules_before_the_topic_rule() -> None:
    rules = Remapping(["__ns:=/namespace", "__node:=remap_name", "/foobar:=/foo/bar"])
    assert rules.remap_topic_name("/foobar", "NodeName", "/") == "/foo/bar"


def test_url_scheme_rules() -> None:
    service_only = Remapping(["rosservice://foo:=bar"])
    assert service_only.remap_topic_name("/ns/foo", "NodeName", "/ns", is_service=True) == "/ns/bar"
    assert service_only.remap_topic_name("/ns/foo", "NodeName", "/ns") is None
    topic_only = Remapping(["rostopic://foo:=bar"])
    assert topic_only.remap_topic_name("/ns/foo", "NodeName", "/ns") == "/ns/bar"
    assert topic_only.remap_topic_name("/ns/foo", "NodeName", "/ns", is_service=True) is None


def test_node_name_rules() -> None:
    assert Remapping(["__node:=globalname"]).remap_node_name("NodeName") == "globalname"
    assert (
        Remapping(["__node:=firstname", "__node:=secondname"]).remap_node_name("N") == "firstname"
    )
    rules = Remapping(["/foobar:=/foo", "__ns:=/namespace", "__node:=remap_name"])
    assert rules.remap_node_name("NodeName") == "remap_name"
    assert Remapping(["other:__node:=x"]).remap_node_name("NodeName") is None
    assert Remapping().remap_node_name("NodeName") is None


def test_namespace_rules() -> None:
    rules = Remapping(["Node1:__ns:=/foo/bar", "Node2:__ns:=/this_one", "Node3:__ns:=/bar/foo"])
    assert rules.remap_namespace("Node1") == "/foo/bar"
    assert rules.remap_namespace("Node2") == "/this_one"
    assert rules.remap_namespace("Node3") == "/bar/foo"
    assert rules.remap_namespace("Node4") is None
    assert Remapping(["/foobar:=/foo/bar", "__ns:=/namespace"]).remap_namespace("N") == "/namespace"


def test_remapping_inputs_and_container_behaviour() -> None:
    from_mapping = Remapping({"chatter": "/talk", "__ns": "/robot1", "talker:x": "y"})
    from_strings = Remapping(["chatter:=/talk", "__ns:=/robot1", "talker:x:=y"])
    assert from_mapping == from_strings
    assert hash(from_mapping) == hash(from_strings)
    assert len(from_mapping) == 3
    assert [str(r) for r in from_mapping] == ["chatter:=/talk", "__ns:=/robot1", "talker:x:=y"]
    assert "chatter:=/talk" in repr(from_mapping)
    assert as_remapping(None) == Remapping()
    assert as_remapping(from_mapping) is from_mapping
    assert as_remapping("a:=b") == Remapping(["a:=b"])
    assert as_remapping([parse_remap_rule("a:=b")]) == Remapping(["a:=b"])


# --------------------------------------------------------------------------- resolution


@pytest.mark.parametrize(
    ("name", "node", "ns", "rules", "expected"),
    [
        ("chatter", "talker", "/", None, "/chatter"),
        ("chatter", "talker", "/ns", ["chatter:=/talk"], "/talk"),
        ("chatter", "talker", "/ns", ["listener:chatter:=/talk"], "/ns/chatter"),
        ("chatter", "talker", "/ns", ["talker:chatter:=/talk"], "/talk"),
        ("/ns/chatter", "talker", "/ns", ["chatter:=talk"], "/ns/talk"),
        ("~/x", "talker", "/ns", {"~/x": "y"}, "/ns/y"),
        ("~/x", "talker", "/ns", {"x": "y"}, "/ns/talker/x"),
        ("image", "cam", "/robot", ["image:=~/raw"], "/robot/cam/raw"),
        ("{node}/x", "cam", "/", ["/cam/x:=/y"], "/y"),
    ],
)
def test_resolve_topic_name(name: str, node: str, ns: str, rules, expected: str) -> None:
    assert resolve_topic_name(name, node, ns, rules) == expected


def test_resolve_service_name_uses_service_rules() -> None:
    rules = ["rosservice://srv:=other", "rostopic://srv:=topic_other"]
    assert resolve_topic_name("srv", "n", "/", rules, is_service=True) == "/other"
    assert resolve_topic_name("srv", "n", "/", rules) == "/topic_other"


def test_resolve_reports_invalid_remap_result() -> None:
    long_ns = "/" + "a" * 200
    rules = [f"x:={'b' * 60}"]
    with pytest.raises(InvalidNameError) as info:
        resolve_topic_name("x", "n", long_ns, rules)
    assert info.value.kind == "remapped topic name"
    assert info.value.rule == "too_long"
    assert "x:=" in info.value.problem


def test_resolve_with_substitutions() -> None:
    assert (
        resolve_topic_name(
            "{robot}/odom", "n", "/", ["/r1/odom:=/odom"], substitutions={"robot": "r1"}
        )
        == "/odom"
    )


node_rules = st.lists(
    st.tuples(st.sampled_from(["", "me:", "other:"]), rule_texts).map("".join), max_size=4
)


@given(
    st.one_of(
        full_names,
        relative_names,
        st.just("~"),
        relative_names.map(lambda n: "~/" + n),
        relative_names.map(lambda n: "{node}/" + n),
    ),
    namespaces,
    node_rules,
    st.booleans(),
)
def test_resolution_output_always_validates(
    name: str, ns: str, rules: list[str], is_service: bool
) -> None:
    resolved = resolve_topic_name(name, "me", ns, rules, is_service=is_service)
    validate_full_topic_name(resolved)


@given(tokens, namespaces, node_rules)
def test_resolved_node_name_and_namespace_always_validate(
    name: str, ns: str, rules: list[str]
) -> None:
    new_name, new_ns = resolve_node_name_and_namespace(name, ns, rules)
    validate_node_name(new_name)
    validate_namespace(new_ns)


@pytest.mark.parametrize(
    ("name", "ns", "rules", "expected"),
    [
        ("talker", "/", None, ("talker", "/")),
        ("talker", "", None, ("talker", "/")),
        ("talker", "demo", None, ("talker", "/demo")),
        ("talker", "/", ["__node:=t2"], ("t2", "/")),
        ("talker", "/", ["__name:=t2"], ("t2", "/")),
        ("talker", "/", ["__ns:=/robot1"], ("talker", "/robot1")),
        ("talker", "/a", ["__ns:=/"], ("talker", "/")),
        ("talker", "/", ["__ns:=/robot1/"], ("talker", "/robot1")),
        ("talker", "/", ["__node:=t2", "t2:__ns:=/x"], ("t2", "/x")),
        ("talker", "/", ["__node:=t2", "talker:__ns:=/x"], ("t2", "/")),
        ("talker", "/", ["listener:__node:=l2", "__ns:=/x"], ("talker", "/x")),
        ("talker", "/", {"chatter": "/talk"}, ("talker", "/")),
    ],
)
def test_resolve_node_name_and_namespace(
    name: str, ns: str, rules, expected: tuple[str, str]
) -> None:
    assert resolve_node_name_and_namespace(name, ns, rules) == expected


@pytest.mark.parametrize(
    ("name", "ns"), [("a/b", "/"), ("talker", "/a/"), ("1x", "/"), ("talker", "/a b")]
)
def test_resolve_node_name_and_namespace_validates_inputs(name: str, ns: str) -> None:
    with pytest.raises(InvalidNameError):
        resolve_node_name_and_namespace(name, ns)
