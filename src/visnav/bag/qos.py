"""QoS as bags store it: the publishers' offered profiles, written and read the way rosbag2 does.

rosbag2 keeps, per topic, the QoS profiles its publishers offered (``offered_qos_profiles``,
a YAML string in Humble's ``metadata.yaml`` and in each MCAP channel's metadata) and uses
them on playback. ROS 1 bags only know ``latching``, which maps to transient local.
"""

from __future__ import annotations

from collections.abc import Sequence

import yaml
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

from visnav.graph.graph_cache import EndpointInfo
from visnav.graph.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_latched,
)

__all__ = ["endpoint_qos", "latched_qos", "playback_qos", "qos_from_profile", "qos_to_yaml"]

_INFINITE = QosTime(2147483647, 4294967295)  # rmw's "infinite" duration, as rosbag2 writes it


def qos_from_profile(profile: QoSProfile) -> Qos:
    """Return the rosbags :class:`~rosbags.interfaces.Qos` of a visnav profile."""
    keep_all = profile.history is HistoryPolicy.KEEP_ALL
    return Qos(
        QosHistory.KEEP_ALL if keep_all else QosHistory.KEEP_LAST,
        0 if keep_all else profile.depth,
        QosReliability.BEST_EFFORT
        if profile.reliability is ReliabilityPolicy.BEST_EFFORT
        else QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL
        if profile.durability is DurabilityPolicy.TRANSIENT_LOCAL
        else QosDurability.VOLATILE,
        _INFINITE,
        _INFINITE,
        QosLiveliness.AUTOMATIC,
        _INFINITE,
        avoid_ros_namespace_conventions=False,
    )


def endpoint_qos(endpoint: EndpointInfo) -> Qos:
    """Return the profile a publisher in the graph offered, as a bag stores it."""
    return qos_from_profile(
        QoSProfile(
            depth=max(1, endpoint.depth),
            reliability=ReliabilityPolicy(endpoint.reliability),
            durability=DurabilityPolicy(endpoint.durability),
        )
    )


def latched_qos() -> Qos:
    """The profile a latched ROS 1 topic maps to (transient local, depth 1)."""
    return qos_from_profile(qos_profile_latched)


def qos_to_yaml(profiles: Sequence[Qos]) -> str:
    """Serialize offered profiles as Humble's rosbag2 does (a YAML list with integer enums).

    Returns:
        The YAML text; ``""`` for no profiles.
    """
    if not profiles:
        return ""
    items = [
        {
            "history": q.history.value,
            "depth": q.depth,
            "reliability": q.reliability.value,
            "durability": q.durability.value,
            "deadline": {"sec": q.deadline.sec, "nsec": q.deadline.nsec},
            "lifespan": {"sec": q.lifespan.sec, "nsec": q.lifespan.nsec},
            "liveliness": q.liveliness.value,
            "liveliness_lease_duration": {
                "sec": q.liveliness_lease_duration.sec,
                "nsec": q.liveliness_lease_duration.nsec,
            },
            "avoid_ros_namespace_conventions": q.avoid_ros_namespace_conventions,
        }
        for q in profiles
    ]
    return yaml.safe_dump(items, sort_keys=False, default_flow_style=False).rstrip("\n")


def playback_qos(profiles: Sequence[Qos], *, default_depth: int = 10) -> QoSProfile:
    """Return the profile to republish a topic with, from the profiles its publishers offered.

    Like ``ros2 bag play``: reliable unless a publisher was best effort, transient local only
    if every publisher was (so ``/tf_static`` stays latched), depth the largest offered.

    Args:
        profiles: the recorded offered profiles (may be empty).
        default_depth: depth when the bag records none.

    Returns:
        The publisher profile.
    """
    if not profiles:
        return QoSProfile(depth=default_depth)
    best_effort = any(q.reliability is QosReliability.BEST_EFFORT for q in profiles)
    transient = all(q.durability is QosDurability.TRANSIENT_LOCAL for q in profiles)
    depth = max([q.depth for q in profiles if q.depth > 0] or [default_depth])
    return QoSProfile(
        depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
    )
