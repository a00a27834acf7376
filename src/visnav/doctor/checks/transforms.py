"""TF checks: the chains consumers need, cycles, two parents, quaternions, timing, statics.

The raw records (every transform received) show what a tf2 buffer hides: a second
parent, a refused quaternion, a constant transform repeated on ``/tf``. Chains and
extrapolation are checked on a :class:`~visnav.tf.Buffer` filled with every valid
transform, as a consumer's buffer would be.
"""

from __future__ import annotations

import difflib
import math
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from visnav.doctor.context import SENSOR_TYPES, CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.doctor.observation import NO_STAMP, TfRecord, TopicData
from visnav.tf.errors import (
    ConnectivityException,
    ExtrapolationException,
    LookupException,
    TransformException,
)

__all__ = [
    "check_tf_chains",
    "check_tf_structure",
    "check_tf_timing",
    "data_frames",
    "find_cycles",
]

ODOMETRY = "nav_msgs/msg/Odometry"
_NO_FRAME_TYPES = frozenset(
    {ODOMETRY, "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage", "rosgraph_msgs/msg/Clock"}
)
_WORLD_FRAMES = frozenset({"map", "world", "odom", "earth"})
_HUGE_OFFSET_S = 1.0e5  # wall vs sim time: reported by the time checks


def data_frames(ctx: CheckContext) -> dict[str, list[TopicData]]:
    """Header frame_id -> the topics stamped in it (sensor data and other stamped data)."""
    out: dict[str, list[TopicData]] = defaultdict(list)
    for t in ctx.obs.topics.values():
        if t.type_name in _NO_FRAME_TYPES or not t.count:
            continue
        frame = t.frame_id.lstrip("/")
        if frame:
            out[frame].append(t)
    return dict(out)


# ---------------------------------------------------------------------- structure


def find_cycles(edges: set[tuple[str, str]]) -> list[list[str]]:
    """Cycles of the ``child -> parent`` graph, each as a frame list starting at its min frame."""
    graph: dict[str, set[str]] = defaultdict(set)
    for child, parent in edges:
        graph[child].add(parent)
    cycles: set[tuple[str, ...]] = set()

    def visit(node: str, path: list[str], on_path: set[str]) -> None:
        for nxt in sorted(graph.get(node, ())):
            if nxt in on_path:
                cyc = path[path.index(nxt) :]
                i = cyc.index(min(cyc))
                cycles.add(tuple(cyc[i:] + cyc[:i]))
            elif len(path) < 64:
                visit(nxt, [*path, nxt], on_path | {nxt})

    for start in sorted(graph):
        visit(start, [start], {start})
    return [list(c) for c in sorted(cycles)]


def check_tf_structure(ctx: CheckContext) -> Iterator[Finding]:
    """``tf.quaternion``, ``tf.two_parents``, ``tf.cycle``, ``tf.static_on_tf``."""
    records = ctx.obs.tf
    if not records:
        return
    yield from _quaternions(records)
    parents: dict[str, dict[str, list[TfRecord]]] = defaultdict(lambda: defaultdict(list))
    for r in records:
        parents[r.child.lstrip("/")][r.parent.lstrip("/")].append(r)
    for child, by_parent in sorted(parents.items()):
        if len(by_parent) < 2:
            continue
        detail = {
            p: {
                "authorities": sorted({r.authority or "unknown" for r in rs}),
                "transforms": len(rs),
                "static": any(r.is_static for r in rs),
            }
            for p, rs in sorted(by_parent.items())
        }
        yield Finding(
            Severity.ERROR,
            "tf.two_parents",
            f"frame '{child}' has {len(by_parent)} parents: {', '.join(sorted(by_parent))}",
            {"frame": child, "parents": detail},
            "a TF frame has one parent: stop one publisher, or give the second estimate its "
            "own child frame (e.g. base_link_gt) and publish the pose chain from the tree root",
            child,
        )
    edges = {(c, p) for c, ps in parents.items() for p in ps if c and p}
    for cycle in find_cycles(edges):
        yield Finding(
            Severity.ERROR,
            "tf.cycle",
            f"TF has a cycle: {' -> '.join([*cycle, cycle[0]])}",
            {"cycle": cycle, "links": [f"{c} -> parent {p}" for c, p in _cycle_links(cycle)]},
            "one of these transforms is published in the wrong direction: swap its frame_id "
            "and child_frame_id (and invert it) so that every frame has one path to the root",
            cycle[0],
        )
    yield from _static_on_tf(ctx, parents)


def _cycle_links(cycle: list[str]) -> list[tuple[str, str]]:
    return [(cycle[i], cycle[(i + 1) % len(cycle)]) for i in range(len(cycle))]


def _quaternions(records: tuple[TfRecord, ...]) -> Iterator[Finding]:
    groups: dict[tuple[str, str, str], list[tuple[TfRecord, float]]] = defaultdict(list)
    totals: dict[tuple[str, str, str], int] = defaultdict(int)
    for r in records:
        key = (r.child, r.parent, r.authority)
        totals[key] += 1
        n2 = sum(v * v for v in r.rotation)
        if not math.isfinite(n2) or abs(n2 - 1.0) >= 1e-3:
            groups[key].append((r, n2))
    for (child, parent, authority), bad in sorted(groups.items()):
        worst, n2 = max(bad, key=lambda b: abs(b[1] - 1.0) if math.isfinite(b[1]) else math.inf)
        refused = not math.isfinite(n2) or abs(n2 - 1.0) >= 0.01
        yield Finding(
            Severity.ERROR if refused else Severity.WARNING,
            "tf.quaternion",
            f"{parent} -> {child}: quaternion norm^2 {n2:.6g}"
            + (" (tf2 refuses it)" if refused else " (not normalised)"),
            {
                "parent": parent,
                "child": child,
                "authority": authority or "unknown",
                "rotation_xyzw": list(worst.rotation),
                "norm_squared": n2 if math.isfinite(n2) else str(n2),
                "bad_transforms": len(bad),
                "transforms": totals[(child, parent, authority)],
            },
            "normalise the quaternion before publishing (q / |q|); build it with "
            "quaternion_from_euler / from a rotation matrix instead of by hand",
            child,
        )


def _same_values(rs: list[TfRecord]) -> bool:
    t = np.asarray([r.translation for r in rs])
    q = np.asarray([r.rotation for r in rs])
    return bool(np.ptp(t, axis=0).max() < 1e-9 and np.ptp(q, axis=0).max() < 1e-9)


def _static_on_tf(
    ctx: CheckContext, parents: dict[str, dict[str, list[TfRecord]]]
) -> Iterator[Finding]:
    odom_frames: set[str] = set()
    for _, frame, child in ctx.odometry():
        odom_frames |= {frame, child}
    fixed = ctx.declared.fixed_joints
    moving = ctx.declared.moving_joints
    for child, by_parent in sorted(parents.items()):
        for parent, rs in sorted(by_parent.items()):
            dyn = [r for r in rs if not r.is_static]
            if len(dyn) < 10 or not _same_values(dyn):
                continue
            span = (max(r.receive_ns for r in dyn) - min(r.receive_ns for r in dyn)) / 1e9
            is_fixed_joint = fixed.get(child) == parent
            if span < 1.0 or child in moving:
                continue
            if not is_fixed_joint and (
                child in odom_frames or parent in odom_frames or parent in _WORLD_FRAMES
            ):
                continue
            ev: dict[str, Any] = {
                "parent": parent,
                "child": child,
                "transforms": len(dyn),
                "over_s": round(span, 3),
                "authorities": sorted({r.authority or "unknown" for r in dyn}),
                "translation": list(dyn[-1].translation),
                "rotation_xyzw": list(dyn[-1].rotation),
            }
            if is_fixed_joint:
                ev["robot_description"] = f"the joint to '{child}' is fixed"
            yield Finding(
                Severity.WARNING,
                "tf.static_on_tf",
                f"{parent} -> {child} is constant but published on /tf ({len(dyn)} times)",
                ev,
                "publish it once on /tf_static (StaticTransformBroadcaster, `visnav tf static`, "
                "robot_state_publisher for fixed joints): on /tf it expires from buffers and "
                "lookups at older stamps extrapolate",
                child,
            )


# ---------------------------------------------------------------------- timing


def check_tf_timing(ctx: CheckContext) -> Iterator[Finding]:
    """``tf.stale`` and ``tf.future`` for dynamic transforms."""
    groups: dict[str, list[TfRecord]] = defaultdict(list)
    for r in ctx.obs.tf:
        if not r.is_static and r.stamp_ns > 0:
            groups[r.child.lstrip("/")].append(r)
    end = ctx.end_clock_ns
    for child, rs in sorted(groups.items()):
        rx = np.asarray([r.receive_ns for r in rs], dtype=np.int64)
        stamps = np.asarray([r.stamp_ns for r in rs], dtype=np.int64)
        ref = ctx.clock.at(rx)
        offsets = (stamps - ref).astype(np.float64) / 1e9
        med = float(np.median(offsets))
        if abs(med) > _HUGE_OFFSET_S:
            continue
        parent = rs[-1].parent
        base = {
            "parent": parent,
            "child": child,
            "authorities": sorted({r.authority or "unknown" for r in rs}),
            "transforms": len(rs),
            "median_stamp_minus_clock_s": round(med, 4),
        }
        if med < -0.25:
            yield Finding(
                Severity.ERROR if med < -1.0 else Severity.WARNING,
                "tf.stale",
                f"{parent} -> {child} is stamped {-med:.2f} s behind the clock",
                base,
                "stamp transforms with the time of the data they come from and publish them "
                "without delay (use_sim_time on the publisher if /clock runs)",
                child,
            )
        elif med > 0.2:
            # localisation post-dates map -> odom on purpose (AMCL's transform_tolerance)
            postdated = parent in _WORLD_FRAMES and child in _WORLD_FRAMES and med <= 1.5
            yield Finding(
                Severity.WARNING if postdated else Severity.ERROR,
                "tf.future",
                f"{parent} -> {child} is stamped {med:.2f} s ahead of the clock",
                base,
                "do not post-date transforms (a 'transform_tolerance' added to the stamp hides "
                "latency but makes lookups at older stamps fail); stamp with the data's time",
                child,
            )
        silent = (end - int(ref.max())) / 1e9
        authorities = ", ".join(sorted({r.authority or "unknown" for r in rs}))
        if len(rs) >= 3:
            period = float(np.median(np.diff(np.sort(ref)))) / 1e9
            if silent > max(1.0, 10.0 * period):
                yield Finding(
                    Severity.ERROR,
                    "tf.stale",
                    f"{parent} -> {child} stopped being published {silent:.2f} s before the end",
                    {**base, "silent_for_s": round(silent, 3), "median_period_s": round(period, 6)},
                    f"the publisher of {child} ({authorities}) stopped: "
                    "check that it is alive and receives its inputs",
                    child,
                )


# ---------------------------------------------------------------------- chains


def _required_chains(ctx: CheckContext) -> list[tuple[str, str, str]]:
    """``(target, source, why)`` chains that consumers need."""
    out: list[tuple[str, str, str]] = []
    if ctx.expect is not None:
        out += [
            (a, b, f"--expect tf_chains ({ctx.expect.source})") for a, b in ctx.expect.tf_chains
        ]
    frames = data_frames(ctx)
    base = ctx.base_frame()
    if ctx.fixed_frame and base and ctx.fixed_frame != base:
        out.append((ctx.fixed_frame, base, "the vehicle must be located in the fixed frame"))
    for frame, topics in sorted(frames.items()):
        names = ", ".join(t.name for t in topics)
        if ctx.fixed_frame and frame != ctx.fixed_frame:
            out.append(
                (ctx.fixed_frame, frame, f"{names} must be transformed into the fixed frame")
            )
        if base and frame != base and frame in ctx.tf_frames and base in ctx.tf_frames:
            out.append((base, frame, f"{names} must be placed on the vehicle ({base})"))
    seen: set[tuple[str, str]] = set()
    unique = []
    for a, b, why in out:
        if (a, b) not in seen:
            seen.add((a, b))
            unique.append((a, b, why))
    return unique


def _missing_link(
    ctx: CheckContext, t_root: str, s_root: str
) -> tuple[tuple[str, str], str, dict[str, Any]]:
    """The transform that joins two TF trees: ``(parent, child)``, the fix and evidence.

    The root of one tree is a link the robot description places with a joint: the
    joint's parent is the missing parent (``base_link -> camera_link``), not the other
    tree's root (``map -> camera_link`` would pin the camera to the map). Without a
    description, ``map -> odom`` is localisation's and a tree holding a sensor's frame
    hangs from the vehicle's base frame.
    """
    for orphan in (s_root, t_root):
        joint = ctx.declared.joints.get(orphan)
        if joint is None:
            continue
        evidence = {"robot_description_joint": joint.name, "joint_type_moves": joint.moves}
        if joint.moves:
            fix = (
                f"publish {joint.parent} -> {orphan}, the moving joint '{joint.name}' of "
                f"robot_description: run robot_state_publisher on the description and "
                f"publish '{joint.name}' on /joint_states"
            )
        else:
            x, y, z = (f"{v:g}" for v in joint.xyz)
            roll, pitch, yaw = (f"{v:g}" for v in joint.rpy)
            fix = (
                f"publish {joint.parent} -> {orphan}, the fixed joint '{joint.name}' of "
                "robot_description: run robot_state_publisher on the description, or "
                f"`visnav tf static {x} {y} {z} {yaw} {pitch} {roll} {joint.parent} {orphan}`"
            )
        return (joint.parent, orphan), fix, evidence
    if (t_root, s_root) == ("map", "odom"):
        fix = "publish the transform map -> odom (localisation / SLAM publishes it)"
        return (t_root, s_root), fix, {}
    base = ctx.base_frame()
    if base is not None and base not in (t_root, s_root):
        base_root = ctx.tf_root(base)
        loose = s_root if base_root == t_root else t_root if base_root == s_root else None
        sensors = {
            frame
            for frame, topics in data_frames(ctx).items()
            if any(t.type_name in SENSOR_TYPES for t in topics)
        }
        holds_sensor = loose is not None and any(ctx.tf_root(f) == loose for f in sensors)
        if loose is not None and holds_sensor and loose not in ("map", "odom"):
            fix = (
                f"'{loose}' is mounted on the vehicle: publish a static transform "
                f"{base} -> {loose} with the mount's offset (or publish robot_description "
                "with the joint and run robot_state_publisher)"
            )
            return (base, loose), fix, {"parent_guessed_from": "the vehicle's base frame"}
    fix = (
        f"publish the transform {t_root} -> {s_root}, or a static transform if the two are "
        "rigidly attached"
    )
    return (t_root, s_root), fix, {}


def _suggest(frame: str, known: set[str]) -> list[str]:
    return difflib.get_close_matches(frame, sorted(known), n=3, cutoff=0.5)


def check_tf_chains(ctx: CheckContext) -> Iterator[Finding]:
    """``tf.unknown_frame``, ``tf.chain_broken``, ``tf.extrapolation``."""
    known = ctx.tf_frames
    frames = data_frames(ctx)
    unknown: set[str] = set()
    for frame, topics in sorted(frames.items()):
        if frame in known:
            continue
        sensors = [t for t in topics if t.type_name in SENSOR_TYPES]
        if not sensors and ctx.fixed_frame != frame:
            continue
        unknown.add(frame)
        close = _suggest(frame, known)
        yield Finding(
            Severity.ERROR if known else Severity.WARNING,
            "tf.unknown_frame",
            f"frame '{frame}' of {', '.join(t.name for t in topics)} is not on TF"
            + (f" (did you mean '{close[0]}'?)" if close else "")
            + ("" if known else " (no transform is published at all)"),
            {
                "frame_id": frame,
                "topics": [t.name for t in topics],
                "tf_frames": sorted(known)[:30],
                **({"similar_frames": close} if close else {}),
            },
            f"set header.frame_id to a frame on TF ({close[0]}?)"
            if close
            else f"publish a transform placing '{frame}' (e.g. a static transform from the "
            "sensor mount), or fix the frame_id",
            frame,
        )
    # one finding per missing link; the other chains it breaks are listed in its evidence
    broken: dict[tuple[str, str], list[Finding]] = {}
    for target, source, why in _required_chains(ctx):
        if source in unknown or target in unknown:
            continue
        failure = _chain(ctx, target, source, why)
        if failure is not None:
            broken.setdefault(failure[0], []).append(failure[1])
    for found in broken.values():
        first = found[0]
        if len(found) > 1:
            also = [f.subject for f in found[1:]]
            first = replace(first, evidence={**first.evidence, "also_broken": also})
        yield first
    yield from _extrapolation(ctx, frames)


def _chain(
    ctx: CheckContext, target: str, source: str, why: str
) -> tuple[tuple[str, str], Finding] | None:
    """The broken link (as a key) and its finding, or None when the chain resolves."""
    known = ctx.tf_frames
    subject = f"{target} -> {source}"
    missing = [f for f in (target, source) if f not in known]
    if missing:
        frame = missing[0]
        close = _suggest(frame, known)
        return ("missing", frame), Finding(
            Severity.ERROR,
            "tf.chain_broken",
            f"TF chain {target} -> {source} is broken: '{frame}' is never published",
            {
                "target_frame": target,
                "source_frame": source,
                "missing_frame": frame,
                "needed_because": why,
                **({"similar_frames": close} if close else {}),
            },
            f"start what publishes '{frame}'"
            + (f", or use '{close[0]}'" if close else "")
            + (" (map -> odom comes from localisation / SLAM)" if frame == "map" else ""),
            subject,
        )
    try:
        ctx.buffer.lookup_transform_matrix(target, source, 0)
    except ConnectivityException as exc:
        t_root, s_root = (
            exc.target_root or ctx.tf_root(target),
            exc.source_root or ctx.tf_root(source),
        )
        link, fix, extra = _missing_link(ctx, t_root, s_root)
        return (t_root, s_root), Finding(
            Severity.ERROR,
            "tf.chain_broken",
            f"TF chain {target} -> {source} is broken: nothing links '{t_root}' to '{s_root}'",
            {
                "target_frame": target,
                "source_frame": source,
                "target_tree_root": t_root,
                "source_tree_root": s_root,
                "missing_link": f"{link[0]} -> {link[1]}",
                "needed_because": why,
                **extra,
            },
            fix,
            subject,
        )
    except LookupException as exc:
        return ("lookup", subject), Finding(
            Severity.ERROR,
            "tf.chain_broken",
            f"TF chain {target} -> {source} cannot be looked up: {str(exc).split(':')[0]}",
            {"target_frame": target, "source_frame": source, "needed_because": why},
            "see tf.cycle / tf.two_parents findings: the tree is malformed",
            subject,
        )
    except TransformException:
        return None
    return None


def _extrapolation(ctx: CheckContext, frames: dict[str, list[TopicData]]) -> Iterator[Finding]:
    target = ctx.fixed_frame
    if target is None:
        odo = [f for _, f, _ in ctx.odometry() if f in ctx.tf_frames]
        target = odo[0] if odo else None
    if target is None or target not in ctx.tf_frames:
        return
    for frame, topics in sorted(frames.items()):
        if frame not in ctx.tf_frames or frame == target:
            continue
        for topic in topics:
            if topic.type_name not in SENSOR_TYPES or not topic.has_stamps:
                continue
            stamps = topic.stamp_ns[(topic.stamp_ns > 0) & (topic.stamp_ns != NO_STAMP)]
            if stamps.size == 0:
                continue
            failures: list[ExtrapolationException] = []
            for s in stamps.tolist():
                try:
                    ctx.buffer.lookup_transform_matrix(target, frame, int(s))
                except ExtrapolationException as exc:
                    failures.append(exc)
                except TransformException:
                    break
            # a few at the edges of a recording are normal (TF and data start together)
            if len(failures) < max(3, 0.05 * stamps.size):
                continue
            ex = failures[len(failures) // 2]
            yield Finding(
                Severity.ERROR,
                "tf.extrapolation",
                f"{topic.name}: looking up {target} <- {frame} at the data stamps needs "
                f"extrapolation into the {ex.direction or 'unknown'} "
                f"({len(failures)} of {stamps.size} messages)",
                {
                    "topic": topic.name,
                    "target_frame": target,
                    "source_frame": frame,
                    "failing_link": ex.frame,
                    "direction": ex.direction,
                    "data_stamp_s": ex.requested_ns / 1e9,
                    "tf_earliest_s": ex.earliest_ns / 1e9,
                    "tf_latest_s": ex.latest_ns / 1e9,
                    "failed": len(failures),
                    "messages": int(stamps.size),
                },
                "stamp data and transforms from the same clock; publish the moving links at "
                "least as often as the data and without delay; consumers should wait for TF "
                "(tf2 MessageFilter) instead of looking up immediately",
                topic.name,
            )
