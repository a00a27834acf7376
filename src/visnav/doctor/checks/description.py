"""Description checks: what ``robot_description`` declares against what the graph publishes.

* ``description.sensor_unpublished``: a sensor or plugin of the ``<gazebo>`` blocks
  declares topics (camera images, a scan, odometry, joint states ...) that nobody
  publishes. Live graphs only: a bag may hold a selection of the topics.
* ``description.sensor_ignored``: a ``<sensor>`` or ``<plugin>`` the description parser
  ignored (a type visnav does not simulate, no ROS plugin): nothing is published for it.
  An error on a live graph (the simulation is visnav's); a warning in a bag, which may
  come from Gazebo, where it works.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from visnav.doctor.checks.topics import namespace_variants
from visnav.doctor.context import CheckContext
from visnav.doctor.declared import DeclaredSensor
from visnav.doctor.findings import Finding, Severity

__all__ = ["check_declared_sensors"]


def _published(ctx: CheckContext, topic: str) -> bool:
    data = ctx.obs.topics.get(topic)
    if data is not None and data.count > 0:
        return True
    return bool(ctx.endpoints(topic, "publisher"))


def _unpublished(ctx: CheckContext, sensor: DeclaredSensor) -> Iterator[Finding]:
    missing = [t for t in sensor.topics if not _published(ctx, t)]
    if not missing:
        return
    published = [t for t in sensor.topics if t not in missing]
    source = ctx.declared.description_topic or "robot_description"
    what = "sensor" if sensor.declared_as.startswith("<sensor") else "plugin"
    topics = ", ".join(missing)
    waiting = sorted({e.node_fqn for t in missing for e in ctx.endpoints(t, "subscription")})
    evidence: dict[str, object] = {
        what: sensor.name,
        "declared_as": sensor.declared_as,
        "unpublished_topics": missing,
        "robot_description": source,
    }
    if published:
        evidence["published_topics"] = published
    if waiting:
        evidence["subscribers_waiting"] = waiting
    others = {t for t in ctx.all_topic_names() if _published(ctx, t)}
    variants = [v for t in missing for v in namespace_variants(t, others)]
    if variants:
        evidence["exists_under_other_namespace"] = variants
        fix = (
            f"the data are published as {variants[0]}: the robot_description is published "
            "in another namespace than the sensor's topics (spawn both in one namespace, or "
            "remap)"
        )
    else:
        fix = (
            "start the simulation (or driver) that owns this robot_description in this "
            "domain; if it runs, its log names the sensor or plugin it skipped, and `visnav "
            "topic list` shows under which name its data went (a <ros><namespace> or remapping)"
        )
    it = "it" if len(missing) == 1 else "them"
    yield Finding(
        Severity.ERROR,
        "description.sensor_unpublished",
        f"{what} '{sensor.name}' ({sensor.declared_as}) in {source} declares {topics}; "
        f"nobody publishes {it}",
        evidence,
        fix,
        missing[0],
    )


def check_declared_sensors(ctx: CheckContext) -> Iterator[Finding]:
    """``description.sensor_unpublished`` and ``description.sensor_ignored``."""
    declared = ctx.declared
    if ctx.has_graph:
        for sensor in declared.sensors:
            yield from _unpublished(ctx, sensor)
    source = declared.description_topic or "robot_description"
    for ignored in declared.ignored:
        named = re.search(r"'([^']*)'", ignored.text)
        subject = named.group(1) if named else ignored.tag
        yield Finding(
            Severity.ERROR if ctx.has_graph else Severity.WARNING,
            "description.sensor_ignored",
            f"<{ignored.tag}> in {source} is not simulated by visnav: {ignored.text}",
            {"tag": ignored.tag, "robot_description": source, "parser": ignored.text},
            "nothing is published for it: use a sensor type and gazebo_ros plugin visnav "
            "simulates (listed in the docs of visnav.description.gazebo), or remove it from "
            "the description",
            subject,
        )
