"""Launch files: start many nodes, in one process or several, from one file.

* :func:`load_launch` reads visnav's YAML launch format or imports a roslaunch
  (ROS 1) XML file into a :class:`LaunchDescription` (every arg, substitution,
  include and group applied).
* :class:`Launcher` runs it: ``shared`` nodes on one Context in this process,
  ``own`` nodes in child processes (:mod:`visnav.launch.runner`), with respawn and
  an orderly SIGINT -> SIGTERM -> SIGKILL shutdown.

The format is documented in docs/launch.md. Submodules are imported explicitly
where heavy; importing this package starts nothing.
"""

from __future__ import annotations

from visnav.launch.description import ArgInfo, LaunchDescription, NodeSpec
from visnav.launch.errors import (
    LaunchArgError,
    LaunchError,
    LaunchParseError,
    LaunchProcessError,
    RoslaunchImportError,
)
from visnav.launch.loader import (
    builtin_launch_files,
    find_launch_file,
    load_launch,
    parse_launch_args,
)
from visnav.launch.supervisor import Launcher, ProcessEvent, describe_exit

__all__ = [
    "ArgInfo",
    "LaunchArgError",
    "LaunchDescription",
    "LaunchError",
    "LaunchParseError",
    "LaunchProcessError",
    "Launcher",
    "NodeSpec",
    "ProcessEvent",
    "RoslaunchImportError",
    "builtin_launch_files",
    "describe_exit",
    "find_launch_file",
    "load_launch",
    "parse_launch_args",
]
