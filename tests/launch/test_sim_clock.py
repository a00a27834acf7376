"""A roslaunch file started beside a running simulation follows its /clock (ROS 1's master)."""

from __future__ import annotations

from visnav.graph import Context, Node
from visnav.launch.description import LaunchDescription, NodeSpec
from visnav.launch.sim_clock import follow_running_clock
from visnav.msgs import get_message_class


def _description(source: str) -> LaunchDescription:
    return LaunchDescription(
        nodes=[
            NodeSpec(executable="amcl", name="amcl"),
            NodeSpec(executable="map_server", name="map_server", use_sim_time=False),
        ],
        source=source,
    )


def test_a_roslaunch_file_follows_a_published_clock(domain: int) -> None:
    clock = get_message_class("rosgraph_msgs/msg/Clock")
    with Context(domain) as ctx:
        sim = Node("gazebo", context=ctx)
        sim.create_publisher(clock, "/clock", 1)
        description = _description("/pkg/launch/turtlebot3_navigation.launch")
        note = follow_running_clock(description, domain=domain)
        yaml = _description("/pkg/nav.launch.yaml")
        assert follow_running_clock(yaml, domain=domain) is None  # YAML files say it themselves
    assert note is not None
    assert "turtlebot3_navigation.launch leaves /use_sim_time unset" in note
    assert [n.use_sim_time for n in description.nodes] == [True, False]  # a set value is kept
    assert [n.use_sim_time for n in yaml.nodes] == [None, False]


def test_without_a_clock_nothing_changes(domain: int) -> None:
    description = _description("/pkg/launch/turtlebot3_navigation.launch")
    assert follow_running_clock(description, domain=domain) is None
    assert [n.use_sim_time for n in description.nodes] == [None, False]
