"""Service types: ``pkg/srv/Name`` as a Request / Response message pair (rclpy's shape).

The ROS 2 Humble store of ``rosbags`` holds messages only; a service travels as two
CDR messages, its request and its response. This module adds the services visnav
serves and calls (their ``.srv`` interface definitions, comments left out) to the
type store as ``pkg/srv/Name_Request`` and ``pkg/srv/Name_Response`` messages, plus
the ``Name_Event`` message and the ``pkg/srv/Name`` struct (``request_message``,
``response_message``, ``event_message``) that REP 2016 hashes to name a service
type (the ``RIHS01_`` hash in a service's key, as rmw_zenoh on Jazzy writes it).

:func:`get_service_type` returns a :class:`ServiceType` with ``Request`` and
``Response`` classes, as ``from std_srvs.srv import Trigger`` does in rclpy::

    Trigger = get_service_type("std_srvs/srv/Trigger")
    request = Trigger.Request()
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
from typing import TYPE_CHECKING, Any

from rosbags.typesys import get_types_from_msg

from visnav.msgs.errors import UnknownMessageTypeError
from visnav.msgs.gazebo_msgs import GAZEBO_SERVICES

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "SERVICE_DEFINITIONS",
    "ServiceType",
    "get_service_type",
    "register_services",
    "service_type_names",
]

SERVICE_DEFINITIONS: dict[str, str] = {
    "std_srvs/srv/Empty": "---\n",
    "std_srvs/srv/Trigger": "---\nbool success\nstring message\n",
    "std_srvs/srv/SetBool": "bool data\n---\nbool success\nstring message\n",
    "nav_msgs/srv/GetMap": "---\nnav_msgs/OccupancyGrid map\n",
    "nav_msgs/srv/GetPlan": (
        "geometry_msgs/PoseStamped start\ngeometry_msgs/PoseStamped goal\nfloat32 tolerance\n"
        "---\nnav_msgs/Path plan\n"
    ),
    "nav_msgs/srv/SetMap": (
        "nav_msgs/OccupancyGrid map\ngeometry_msgs/PoseWithCovarianceStamped initial_pose\n"
        "---\nbool success\n"
    ),
    "nav_msgs/srv/LoadMap": (
        "string map_url\n---\n"
        "uint8 RESULT_SUCCESS=0\nuint8 RESULT_MAP_DOES_NOT_EXIST=1\n"
        "uint8 RESULT_INVALID_MAP_DATA=2\nuint8 RESULT_INVALID_MAP_METADATA=3\n"
        "uint8 RESULT_UNDEFINED_FAILURE=255\n"
        "nav_msgs/OccupancyGrid map\nuint8 result\n"
    ),
    "rcl_interfaces/srv/ListParameters": (
        "uint64 DEPTH_RECURSIVE=0\nstring[] prefixes\nuint64 depth\n---\n"
        "rcl_interfaces/ListParametersResult result\n"
    ),
    "rcl_interfaces/srv/GetParameters": (
        "string[] names\n---\nrcl_interfaces/ParameterValue[] values\n"
    ),
    "rcl_interfaces/srv/SetParameters": (
        "rcl_interfaces/Parameter[] parameters\n---\nrcl_interfaces/SetParametersResult[] results\n"
    ),
    "rcl_interfaces/srv/SetParametersAtomically": (
        "rcl_interfaces/Parameter[] parameters\n---\nrcl_interfaces/SetParametersResult result\n"
    ),
    "rcl_interfaces/srv/DescribeParameters": (
        "string[] names\n---\nrcl_interfaces/ParameterDescriptor[] descriptors\n"
    ),
    "rcl_interfaces/srv/GetParameterTypes": "string[] names\n---\nuint8[] types\n",
    "action_msgs/srv/CancelGoal": (
        "action_msgs/GoalInfo goal_info\n---\n"
        "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\n"
        "int8 ERROR_GOAL_TERMINATED=3\n"
        "int8 return_code\naction_msgs/GoalInfo[] goals_canceling\n"
    ),
    **GAZEBO_SERVICES,  # the simulator's (visnav.sim.gazebo_services); needs gazebo_msgs' msgs
}
"""Service type name -> ``.srv`` text (request ``---`` response)."""

_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"
_EVENT_INFO_TEXT = (
    "uint8 REQUEST_SENT=0\nuint8 REQUEST_RECEIVED=1\nuint8 RESPONSE_SENT=2\n"
    "uint8 RESPONSE_RECEIVED=3\n"
    "uint8 event_type\nbuiltin_interfaces/Time stamp\nuint8[16] client_gid\nint64 sequence_number\n"
)
_EMPTY = "uint8 structure_needs_at_least_one_member\n"


def _as_srv(types: dict[str, Any], pkg: str) -> dict[str, Any]:
    """Rename ``pkg/msg/X`` keys that rosbags made from ``pkg/srv/X`` back to ``pkg/srv/X``."""
    return {k.replace(f"{pkg}/msg/", f"{pkg}/srv/", 1): v for k, v in types.items()}


def _parse(text: str, name: str) -> dict[str, Any]:
    pkg, _, short = name.split("/")
    parsed = get_types_from_msg(text if text.strip() else _EMPTY, f"{pkg}/msg/{short}")
    return _as_srv(parsed, pkg)


def _service_parts(name: str, text: str) -> dict[str, Any]:
    request, sep, response = text.partition("---")
    if not sep:  # pragma: no cover - the table above always has one
        msg = f"service definition of {name} has no '---' line"
        raise UnknownMessageTypeError(msg)
    pkg, _, short = name.split("/")
    types = _parse(request, f"{name}_Request")
    types.update(_parse(response, f"{name}_Response"))
    types.update(
        _parse(
            f"service_msgs/ServiceEventInfo info\n{pkg}/srv/{short}_Request[<=1] request\n"
            f"{pkg}/srv/{short}_Response[<=1] response\n",
            f"{name}_Event",
        )
    )
    types.update(
        _parse(
            f"{pkg}/srv/{short}_Request request_message\n"
            f"{pkg}/srv/{short}_Response response_message\n"
            f"{pkg}/srv/{short}_Event event_message\n",
            name,
        )
    )
    return types


def _fix_refs(types: dict[str, Any]) -> dict[str, Any]:
    """Point references that rosbags wrote as ``pkg/msg/X_*`` at the ``pkg/srv/`` names."""
    srv = {k for k in types if "/srv/" in k}
    wrong = {k.replace("/srv/", "/msg/", 1): k for k in srv}

    def fix(desc: Any) -> Any:
        if isinstance(desc, tuple):
            return tuple(fix(d) for d in desc)
        if isinstance(desc, str):
            desc = desc.replace("/srv/msg/", "/srv/", 1)
            return wrong.get(desc, desc)
        return desc

    return {k: (consts, [(f, fix(d)) for f, d in fields]) for k, (consts, fields) in types.items()}


def register_services(store: Typestore) -> None:
    """Add :data:`SERVICE_DEFINITIONS` (and their event types) to ``store`` (idempotent)."""
    types: dict[str, Any] = {}
    if _EVENT_INFO not in store.fielddefs:
        types.update(get_types_from_msg(_EVENT_INFO_TEXT, _EVENT_INFO))
    for name, text in SERVICE_DEFINITIONS.items():
        if f"{name}_Request" not in store.fielddefs:
            types.update(_service_parts(name, text))
    if types:
        store.register(_fix_refs(types))


@dataclasses.dataclass(frozen=True)
class ServiceType:
    """A service type: its name and its request and response message classes.

    Attributes:
        name: e.g. ``std_srvs/srv/Trigger``.
        Request: the request message class (``std_srvs/srv/Trigger_Request``).
        Response: the response message class.
    """

    name: str
    Request: type[Any]
    Response: type[Any]

    @property
    def request_type_name(self) -> str:
        """``pkg/srv/Name_Request``."""
        return f"{self.name}_Request"

    @property
    def response_type_name(self) -> str:
        """``pkg/srv/Name_Response``."""
        return f"{self.name}_Response"

    def __repr__(self) -> str:
        return f"ServiceType({self.name!r})"


def service_type_names() -> list[str]:
    """Every service type the store knows, sorted (``pkg/srv/Name``).

    Request/response pairs under ``pkg/action/`` (an action's ``Name_SendGoal``,
    ``Name_GetResult`` services, once registered) count as service types too.
    """
    from visnav.msgs.serde import typestore  # noqa: PLC0415 - serde imports this module

    suffix = "_Request"
    return sorted(
        k[: -len(suffix)]
        for k in typestore().fielddefs
        if ("/srv/" in k or "/action/" in k)
        and k.endswith(suffix)
        and f"{k[: -len(suffix)]}_Response" in typestore().fielddefs
    )


def _known(name: str) -> bool:
    from visnav.msgs.serde import typestore  # noqa: PLC0415 - serde imports this module

    defs = typestore().fielddefs
    return f"{name}_Request" in defs and f"{name}_Response" in defs


@functools.cache
def _lookup(name: str) -> ServiceType:
    from visnav.msgs.serde import typestore  # noqa: PLC0415 - serde imports this module

    types = typestore().types
    return ServiceType(name, types[f"{name}_Request"], types[f"{name}_Response"])


def get_service_type(type_name: str | ServiceType) -> ServiceType:
    """Look a service type up by name.

    Args:
        type_name: ``pkg/srv/Name`` (or the ROS 1 spelling ``pkg/Name``), or a
            :class:`ServiceType` (returned as it is).

    Returns:
        The service type with its ``Request`` and ``Response`` classes.

    Raises:
        UnknownMessageTypeError: no such service; the message suggests close names.
    """
    if isinstance(type_name, ServiceType):
        return type_name
    name = str(type_name).strip()
    parts = name.split("/")
    if len(parts) == 2:
        name = f"{parts[0]}/srv/{parts[1]}"
    if ("/srv/" in name or "/action/" in name) and _known(name):
        return _lookup(name)
    known = service_type_names()
    if name not in known:
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = (
            f"unknown service type {type_name!r}: expected a name like 'std_srvs/srv/Trigger'{hint}"
        )
        raise UnknownMessageTypeError(msg)
    return _lookup(name)
