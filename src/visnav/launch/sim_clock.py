"""A roslaunch file started beside a running simulation follows its ``/clock``.

ROS 1 keeps ``/use_sim_time`` on the master: ``turtlebot3_world.launch`` (gazebo_ros's
``empty_world.launch``) sets it, and a launch file started later in another terminal
(``turtlebot3_navigation.launch``, ``turtlebot3_slam.launch``) inherits it although it
never mentions it. visnav has no parameter server that outlives a launch, so a roslaunch
file that leaves ``/use_sim_time`` unset looks at the graph instead: when a node of the
domain publishes ``/clock`` as the launch starts, its nodes run on sim time, as they would
under ROS 1. A node whose ``use_sim_time`` the file sets keeps it.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from visnav.graph.context import Context
from visnav.graph.introspect import wait_for_discovery
from visnav.launch.description import LaunchDescription

__all__ = ["ROSLAUNCH_SUFFIXES", "follow_running_clock"]

ROSLAUNCH_SUFFIXES = (".launch", ".xml")


def _clock_published(domain: int | str | None) -> bool:
    with Context(domain) as ctx:
        wait_for_discovery(ctx)
        return any(e.kind == "publisher" for e in ctx.graph.endpoints("/clock"))


def follow_running_clock(
    description: LaunchDescription, *, domain: int | str | None = None
) -> str | None:
    """Put a roslaunch file's unset ``use_sim_time`` on sim time when ``/clock`` runs.

    Args:
        description: the loaded launch (changed in place).
        domain: the graph domain the launch starts in (None: ``VISNAV_DOMAIN``).

    Returns:
        A note saying what was done, or None when nothing changed (a YAML launch file,
        every node's ``use_sim_time`` set, or no ``/clock`` publisher).
    """
    if Path(description.source).suffix not in ROSLAUNCH_SUFFIXES:
        return None
    unset = [n for n in description.nodes if n.use_sim_time is None]
    if not unset or not _clock_published(domain):
        return None
    description.nodes = [
        n if n.use_sim_time is not None else replace(n, use_sim_time=True)
        for n in description.nodes
    ]
    return (
        f"{Path(description.source).name} leaves /use_sim_time unset and a node of this domain "
        f"publishes /clock: its {len(unset)} node(s) run on sim time (ROS 1's master would "
        "hand them the /use_sim_time the simulation's launch set)"
    )
