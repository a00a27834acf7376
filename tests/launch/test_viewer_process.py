"""The viewer node of a launch file runs in a process of its own unless the entry says otherwise."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from visnav.launch import LaunchParseError, load_launch
from visnav.launch.description import default_process


def _yaml(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "view.launch.yaml"
    path.write_text(textwrap.dedent(body))
    return path


def test_default_process_of_node_types() -> None:
    assert default_process("viz") == "own"
    assert default_process("image_proc") == "shared"


def test_yaml_viewer_own_by_default_shared_when_asked(tmp_path: Path) -> None:
    path = _yaml(
        tmp_path,
        """
        launch:
          - node: {exec: viz, name: viewer}
          - node: {exec: viz, name: inproc, process: shared}
          - node: {exec: image_proc, name: rectify}
          - group:
              process: shared
              children:
                - node: {exec: viz, name: grouped}
        """,
    )
    nodes = {n.fqn: n.process for n in load_launch(path).nodes}
    assert nodes == {
        "/viewer": "own",
        "/inproc": "shared",
        "/rectify": "shared",
        "/grouped": "shared",
    }


def test_roslaunch_rviz_runs_in_its_own_process(tmp_path: Path) -> None:
    path = tmp_path / "view.launch"
    path.write_text(
        '<launch>\n  <node pkg="rviz" type="rviz" name="rviz" args="-f odom"/>\n'
        '  <node pkg="rviz" type="rviz" name="rviz2" respawn="true"/>\n</launch>\n'
    )
    nodes = {n.fqn: n for n in load_launch(path).nodes}
    assert (nodes["/rviz"].executable, nodes["/rviz"].process) == ("viz", "own")
    assert (nodes["/rviz2"].process, nodes["/rviz2"].respawn) == ("own", True)


@pytest.mark.parametrize("kind", ["thread", "own process"])
def test_unknown_process_kind_still_rejected(tmp_path: Path, kind: str) -> None:
    from visnav.launch.description import PROCESS_KINDS

    assert kind not in PROCESS_KINDS
    path = _yaml(tmp_path, f"launch:\n  - node: {{exec: viz, process: {kind}}}\n")
    with pytest.raises(LaunchParseError, match="expected 'shared' or 'own'"):
        load_launch(path)


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_launched_viewer_runs_in_a_child_process(
    domain: int, test_nodes_path: Path, tmp_path: Path
) -> None:
    import os
    import threading

    pytest.importorskip("rerun")
    from visnav.graph import Context, Node
    from visnav.launch import Launcher

    del test_nodes_path
    path = _yaml(
        tmp_path,
        """
        launch:
          - node: {exec: "launch_test_nodes:Talker", name: talker, params: {rate: 5}}
          - node: {exec: viz, name: viewer, params: {port: 0, grpc_port: 0}}
        """,
    )
    launcher = Launcher(load_launch(path), domain=domain, sigterm_timeout=5.0)
    stop = threading.Event()
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(launcher.run(stop)), daemon=True)
    thread.start()
    try:
        with Context(domain) as ctx:
            probe = Node("probe", context=ctx)
            names = probe.get_node_names
            assert ctx.spin_until(lambda: {"viewer", "talker"} <= set(names()), 90.0), names()
        pid = launcher.pids["/viewer"]
        assert pid != os.getpid()
        os.kill(pid, 0)  # alive
        assert [n.get_name() for n in launcher.shared_nodes] == ["talker"]
    finally:
        stop.set()
        thread.join(60.0)
    assert not thread.is_alive()
    assert codes == [0]
    assert [e.kind for e in launcher.events if e.name == "/viewer"][:1] == ["started"]
