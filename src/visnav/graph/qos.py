"""Quality-of-service profiles with ROS 2 names, presets and compatibility rules.

The subset of DDS QoS that visnav honours: history (keep last N / keep all), depth,
reliability and durability. ``/tf_static`` and latched topics use transient local:
a late-joining subscription receives the last ``depth`` messages of each publisher.

The ``qos_profile_*`` presets are rclpy's, plus two of visnav's own (rclpy has neither
name): ``qos_profile_latched`` (depth 1, reliable, transient local: ROS 1's
``latch=True``, what map_server's ``map``, ``robot_description`` and status topics use)
and ``qos_profile_tf_static`` (the same values: tf2_ros's ``StaticBroadcasterQoS``).
"""

from __future__ import annotations

import dataclasses
import enum

from visnav.graph.errors import GraphError

__all__ = [
    "DurabilityPolicy",
    "HistoryPolicy",
    "QoSProfile",
    "ReliabilityPolicy",
    "check_qos_compatibility",
    "qos_profile_latched",
    "qos_profile_parameters",
    "qos_profile_sensor_data",
    "qos_profile_services_default",
    "qos_profile_system_default",
    "qos_profile_tf_static",
    "to_qos",
]


class HistoryPolicy(enum.Enum):
    """How many samples a queue keeps."""

    KEEP_LAST = "keep_last"
    KEEP_ALL = "keep_all"


class ReliabilityPolicy(enum.Enum):
    """Whether delivery is retried (reliable) or may drop samples (best effort)."""

    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class DurabilityPolicy(enum.Enum):
    """Whether late-joining subscriptions receive earlier samples."""

    VOLATILE = "volatile"
    TRANSIENT_LOCAL = "transient_local"


@dataclasses.dataclass(frozen=True)
class QoSProfile:
    """A QoS profile (rclpy's ``QoSProfile`` fields).

    Attributes:
        depth: queue size for keep-last history (>= 1); ignored for keep-all.
        history: keep-last or keep-all.
        reliability: reliable or best effort.
        durability: volatile or transient local.
    """

    depth: int = 10
    history: HistoryPolicy = HistoryPolicy.KEEP_LAST
    reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE
    durability: DurabilityPolicy = DurabilityPolicy.VOLATILE

    def __post_init__(self) -> None:
        # rclpy's QoSProfile refuses what is not its enum; visnav also takes the policy's
        # short name (rclpy's ``get_from_short_key``), e.g. "transient_local", and refuses
        # anything else instead of keeping a string no comparison would ever match
        for name, policy in _POLICY_FIELDS:
            value = getattr(self, name)
            if not isinstance(value, policy):
                object.__setattr__(self, name, _policy_from(name, policy, value))
        if isinstance(self.depth, bool) or not isinstance(self.depth, int):
            msg = f"QoSProfile.depth is {self.depth!r}: expected an int (e.g. depth=10)"
            raise GraphError(msg)
        if self.history is HistoryPolicy.KEEP_LAST and self.depth < 1:
            msg = (
                f"QoSProfile.depth is {self.depth}: keep-last history needs depth >= 1 "
                "(use history=KEEP_ALL for an unbounded queue)"
            )
            raise GraphError(msg)

    @property
    def queue_limit(self) -> int | None:
        """The queue bound, or None for keep-all."""
        return None if self.history is HistoryPolicy.KEEP_ALL else self.depth

    def short(self) -> str:
        """Return a compact text form, e.g. ``reliable/volatile/keep_last(10)``."""
        hist = "keep_all" if self.history is HistoryPolicy.KEEP_ALL else f"keep_last({self.depth})"
        return f"{self.reliability.value}/{self.durability.value}/{hist}"


_POLICY_FIELDS: tuple[tuple[str, type[enum.Enum]], ...] = (
    ("history", HistoryPolicy),
    ("reliability", ReliabilityPolicy),
    ("durability", DurabilityPolicy),
)


def _policy_from(name: str, policy: type[enum.Enum], value: object) -> enum.Enum:
    """Return ``policy``'s member named by ``value`` (its short name), or raise GraphError."""
    if isinstance(value, str):
        key = value.strip().lower()
        for member in policy:
            if key in (member.value, member.name.lower()):
                return member
    choices = ", ".join(f"{policy.__name__}.{m.name} ({m.value!r})" for m in policy)
    msg = f"QoSProfile.{name} is {value!r}: expected one of {choices}"
    raise GraphError(msg)


qos_profile_system_default = QoSProfile()
qos_profile_sensor_data = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_services_default = QoSProfile()
qos_profile_parameters = QoSProfile(depth=1000)
qos_profile_latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""visnav's: the last message reaches late subscribers (ROS 1 ``latch=True``)."""
qos_profile_tf_static = qos_profile_latched
"""tf2_ros's ``StaticBroadcasterQoS``: ``qos_profile_latched``."""


def to_qos(qos: QoSProfile | int) -> QoSProfile:
    """Return a profile for rclpy's ``qos_profile_or_depth`` argument.

    Args:
        qos: a profile, or an int depth meaning keep-last(depth), reliable, volatile.

    Returns:
        The profile.

    Raises:
        GraphError: not a profile or a positive int.
    """
    if isinstance(qos, QoSProfile):
        return qos
    if isinstance(qos, int) and not isinstance(qos, bool):
        return QoSProfile(depth=qos)
    msg = f"qos is {qos!r}: expected a QoSProfile or an int queue depth"
    raise GraphError(msg)


def check_qos_compatibility(publisher: QoSProfile, subscription: QoSProfile) -> tuple[bool, str]:
    """Check whether a publisher and a subscription can communicate (DDS request/offer rules).

    Args:
        publisher: the offered profile.
        subscription: the requested profile.

    Returns:
        ``(compatible, reason)``; ``reason`` is empty when compatible.
    """
    if (
        publisher.reliability is ReliabilityPolicy.BEST_EFFORT
        and subscription.reliability is ReliabilityPolicy.RELIABLE
    ):
        return False, (
            "publisher offers best_effort reliability but the subscription requests reliable; "
            "make the subscription best_effort (e.g. qos_profile_sensor_data) "
            "or the publisher reliable"
        )
    if (
        publisher.durability is DurabilityPolicy.VOLATILE
        and subscription.durability is DurabilityPolicy.TRANSIENT_LOCAL
    ):
        return False, (
            "publisher offers volatile durability but the subscription requests transient_local; "
            "make the publisher transient_local or the subscription volatile"
        )
    return True, ""
