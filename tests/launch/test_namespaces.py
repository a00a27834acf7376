"""Groups, namespaces and remaps of a launch file resolve topic names as ROS 2 does.

Each case builds real nodes (``launch_test_nodes:Talker``: relative ``chatter`` and
private ``~/status``) from a launch file on a local Context and reads the names
their publishers resolved.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from visnav.graph import Context
from visnav.launch import load_launch
from visnav.node_registry import resolve_node_class

# (entries, node fqn, chatter topic, status topic)
CASES = [
    ("- node: {exec: launch_test_nodes:Talker, name: x}", "/x", "/chatter", "/x/status"),
    (
        "- group: {namespace: a, children: [{node: {exec: launch_test_nodes:Talker, name: x}}]}",
        "/a/x",
        "/a/chatter",
        "/a/x/status",
    ),
    (  # a relative node namespace is pushed onto the group's
        "- group: {namespace: a, children: [{node: {exec: launch_test_nodes:Talker, name: x,"
        " namespace: b}}]}",
        "/a/b/x",
        "/a/b/chatter",
        "/a/b/x/status",
    ),
    (  # an absolute node namespace replaces it
        "- group: {namespace: a, children: [{node: {exec: launch_test_nodes:Talker, name: x,"
        " namespace: /abs}}]}",
        "/abs/x",
        "/abs/chatter",
        "/abs/x/status",
    ),
    (  # nested groups; an absolute inner group namespace starts again from /
        "- group: {namespace: a, children: [{group: {namespace: b, children: [{group: "
        "{namespace: /c, children: [{node: {exec: launch_test_nodes:Talker, name: x}}]}}]}}]}",
        "/c/x",
        "/c/chatter",
        "/c/x/status",
    ),
    (  # a relative remap target resolves in the node's namespace
        "- group: {namespace: a, remap: {chatter: out}, children: "
        "[{node: {exec: launch_test_nodes:Talker, name: x}}]}",
        "/a/x",
        "/a/out",
        "/a/x/status",
    ),
    (  # the node's own remap wins over its group's (rcl: first matching rule)
        "- group: {namespace: a, remap: {chatter: group_out}, children: "
        "[{node: {exec: launch_test_nodes:Talker, name: x, remap: {chatter: /direct}}}]}",
        "/a/x",
        "/direct",
        "/a/x/status",
    ),
    (  # private names remap too
        "- node: {exec: launch_test_nodes:Talker, name: x, namespace: n, remap: {'~/status': /st}}",
        "/n/x",
        "/n/chatter",
        "/st",
    ),
    (  # __ns and __node remaps move the node, as with --ros-args -r
        "- node: {exec: launch_test_nodes:Talker, name: x, namespace: n, "
        "remap: {__ns: /moved, __node: y}}",
        "/moved/y",
        "/moved/chatter",
        "/moved/y/status",
    ),
]


@pytest.mark.parametrize(("entries", "fqn", "chatter", "status"), CASES)
def test_namespaces_and_remaps_resolve_like_ros(
    tmp_path: Path, test_nodes_path: Path, entries: str, fqn: str, chatter: str, status: str
) -> None:
    del test_nodes_path
    f = tmp_path / "ns.yaml"
    f.write_text("launch:\n" + textwrap.indent(entries, "  ") + "\n")
    (spec,) = load_launch(f).nodes
    assert spec.fqn == fqn
    with Context(transport="local") as ctx:
        node = resolve_node_class(spec.executable)(spec.name, context=ctx, **spec.node_kwargs())
        assert node.get_fully_qualified_name() == fqn
        assert node.chatter.topic_name == chatter
        assert node.status.topic_name == status


def test_include_inside_a_group_pushes_both_namespaces(tmp_path: Path) -> None:
    (tmp_path / "inner.yaml").write_text(
        "launch:\n  - group: {namespace: cam, children: [{node: {exec: image_proc}}]}\n"
    )
    (tmp_path / "outer.yaml").write_text(
        "launch:\n  - group:\n      namespace: robot\n      children:\n"
        "        - include: {file: inner.yaml, namespace: front}\n"
    )
    (spec,) = load_launch(tmp_path / "outer.yaml").nodes
    assert spec.fqn == "/robot/front/cam/image_proc"
    with Context(transport="local") as ctx:
        node = resolve_node_class(spec.executable)(spec.name, context=ctx, **spec.node_kwargs())
        topics = sorted(p.topic_name for p in node.publishers)
        assert "/robot/front/cam/image_rect" in topics
