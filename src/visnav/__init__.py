"""visnav: simulated robot perception and navigation with ROS-standard data, no ROS install.

Subpackages (imports point downward): :mod:`visnav.msgs` (messages and
conversions), :mod:`visnav.graph` (names, QoS, nodes, topics, time),
:mod:`visnav.tf` (transforms with tf2 semantics), :mod:`visnav.perception`,
:mod:`visnav.sim` and the command line in :mod:`visnav.cli`.

Importing ``visnav`` has no side effects: it opens no sockets and starts no threads.
"""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["VisnavError", "__version__"]

__version__ = "0.1.0"
