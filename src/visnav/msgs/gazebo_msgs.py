"""``gazebo_msgs`` types the simulator publishes, added to visnav's type store.

The ROS 2 Humble store of ``rosbags`` has no ``gazebo_msgs``; these definitions are the
package's ``.msg`` files (identical in ROS 1 noetic and ROS 2), so the types hash (RIHS01)
and, for the ROS 1 bridge, checksum (MD5) as gazebo_ros' own:

* ``gazebo_msgs/msg/ModelState`` and ``ModelStates`` (``/gazebo/model_states``);
* ``gazebo_msgs/msg/LinkState`` and ``LinkStates`` (``/gazebo/link_states``).

:data:`GAZEBO_SERVICES` holds the ``gazebo_msgs`` services the simulator serves
(``GetModelState``, ``SetModelState``, ``SpawnModel``, ``DeleteModel``: the ROS 1 noetic
``.srv`` files, ``Header`` spelled ``std_msgs/Header`` as in the ROS 2 package);
:mod:`visnav.msgs.srv` registers them with the other services.

:func:`visnav.msgs.serde.typestore` registers them when it creates the store; look the
classes up with :func:`visnav.msgs.get_message_class` (``"gazebo_msgs/msg/ModelStates"``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rosbags.typesys import get_types_from_msg

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ["GAZEBO_MSGS", "GAZEBO_SERVICES", "register_gazebo_msgs"]

GAZEBO_MSGS: dict[str, str] = {
    "gazebo_msgs/msg/ModelState": (
        "string model_name\n"
        "geometry_msgs/Pose pose\n"
        "geometry_msgs/Twist twist\n"
        "string reference_frame\n"
    ),
    "gazebo_msgs/msg/ModelStates": (
        "string[] name\ngeometry_msgs/Pose[] pose\ngeometry_msgs/Twist[] twist\n"
    ),
    "gazebo_msgs/msg/LinkState": (
        "string link_name\n"
        "geometry_msgs/Pose pose\n"
        "geometry_msgs/Twist twist\n"
        "string reference_frame\n"
    ),
    "gazebo_msgs/msg/LinkStates": (
        "string[] name\ngeometry_msgs/Pose[] pose\ngeometry_msgs/Twist[] twist\n"
    ),
}
"""Type name -> ``.msg`` text (comments left out; they change neither hash nor MD5)."""

GAZEBO_SERVICES: dict[str, str] = {
    "gazebo_msgs/srv/GetModelState": (
        "string model_name\nstring relative_entity_name\n---\n"
        "std_msgs/Header header\ngeometry_msgs/Pose pose\ngeometry_msgs/Twist twist\n"
        "bool success\nstring status_message\n"
    ),
    "gazebo_msgs/srv/SetModelState": (
        "gazebo_msgs/ModelState model_state\n---\nbool success\nstring status_message\n"
    ),
    "gazebo_msgs/srv/SpawnModel": (
        "string model_name\nstring model_xml\nstring robot_namespace\n"
        "geometry_msgs/Pose initial_pose\nstring reference_frame\n---\n"
        "bool success\nstring status_message\n"
    ),
    "gazebo_msgs/srv/DeleteModel": (
        "string model_name\n---\nbool success\nstring status_message\n"
    ),
}
"""Service type name -> ``.srv`` text (request ``---`` response), comments left out."""


def register_gazebo_msgs(store: Typestore) -> None:
    """Add the :data:`GAZEBO_MSGS` types to ``store`` (a no-op for types it already has)."""
    types = {}
    for name, text in GAZEBO_MSGS.items():
        if name not in store.fielddefs:
            types.update(get_types_from_msg(text, name))
    if types:
        store.register(types)
