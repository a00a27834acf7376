"""``visnav tf``: echo (tf2_echo), static (static_transform_publisher), tree (view_frames)."""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

from visnav.cli._common import cli_node
from visnav.errors import VisnavError
from visnav.msgs.construct import make
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Quaternion, Transform, TransformStamped, Vector3
from visnav.tf.buffer import Buffer
from visnav.tf.errors import TransformException
from visnav.tf.ros import StaticTransformBroadcaster, TransformListener
from visnav.tf.transforms import euler_from_quaternion, quaternion_from_euler, transform_to_matrix
from visnav.tf.tree import format_tree, format_tree_dot

__all__ = ["add_arguments", "format_echo", "static_transform_from_args"]


class TfArgumentError(VisnavError, ValueError):
    """Bad ``visnav tf`` arguments."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``tf`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True

    p = sub.add_parser(
        "echo",
        help="print the transform of TARGET in SOURCE (tf2_echo SOURCE TARGET)",
        description=(
            "As tf2_echo: prints lookup_transform(target=SOURCE, source=TARGET), i.e. the pose "
            "of TARGET expressed in SOURCE."
        ),
    )
    p.add_argument("source_frame")
    p.add_argument("target_frame")
    p.add_argument("-r", "--rate", type=float, default=1.0, help="echo rate in Hz")
    p.add_argument("--once", action="store_true", help="print one transform and exit")
    p.add_argument("--timeout", type=float, default=5.0, help="give up after S seconds")
    p.set_defaults(func=cmd_echo)

    p = sub.add_parser(
        "static",
        help="publish a static transform (static_transform_publisher)",
        description=(
            "x y z yaw pitch roll PARENT CHILD, or x y z qx qy qz qw PARENT CHILD "
            "(angles in radians, as static_transform_publisher)."
        ),
    )
    p.add_argument("values", nargs="+", help="x y z yaw pitch roll|qx qy qz qw PARENT CHILD")
    p.add_argument("--duration", type=float, default=None, help="exit after S seconds")
    p.set_defaults(func=cmd_static)

    p = sub.add_parser("tree", help="print the TF tree with each link's publisher and rate")
    p.add_argument("--duration", type=float, default=2.0, help="listen for S seconds")
    p.add_argument("--dot", action="store_true", help="print Graphviz dot instead of text")
    p.set_defaults(func=cmd_tree)


def format_echo(t: TransformStamped) -> str:
    """Format a transform the way tf2_echo prints it."""
    tr, q = t.transform.translation, t.transform.rotation
    quat = np.array([q.x, q.y, q.z, q.w])
    rpy = euler_from_quaternion(quat)
    mat = transform_to_matrix(t.transform)
    stamp = t.header.stamp.sec + t.header.stamp.nanosec / 1e9
    lines = [
        f"At time {stamp:.9f}",
        f"- Translation: [{tr.x:.3f}, {tr.y:.3f}, {tr.z:.3f}]",
        f"- Rotation: in Quaternion [{q.x:.3f}, {q.y:.3f}, {q.z:.3f}, {q.w:.3f}]",
        f"- Rotation: in RPY (radian) [{rpy[0]:.3f}, {rpy[1]:.3f}, {rpy[2]:.3f}]",
        "- Rotation: in RPY (degree) "
        f"[{math.degrees(rpy[0]):.3f}, {math.degrees(rpy[1]):.3f}, {math.degrees(rpy[2]):.3f}]",
        "- Matrix:",
        *("  " + " ".join(f"{v:6.3f}" for v in row) for row in mat),
    ]
    return "\n".join(lines)


def cmd_echo(args: argparse.Namespace) -> int:
    """``tf echo``."""
    buffer = Buffer()
    with cli_node(args, discover=False) as node:
        TransformListener(buffer, node)
        period = 1.0 / args.rate if args.rate > 0 else 1.0
        deadline = time.monotonic() + args.timeout
        printed = False
        last_error: TransformException | None = None
        while True:
            node.context.spin_until(lambda: False, period if printed else 0.1)
            try:
                t = buffer.lookup_transform(args.source_frame, args.target_frame, 0)
            except TransformException as exc:
                last_error = exc
                if not printed and time.monotonic() > deadline:
                    raise TransformException(str(last_error)) from exc
                continue
            print(format_echo(t), flush=True)
            printed = True
            if args.once:
                return 0


def static_transform_from_args(values: list[str]) -> TransformStamped:
    """Parse static_transform_publisher's positional arguments.

    Raises:
        TfArgumentError: not 8 or 9 values, or a number that does not parse.
    """
    if len(values) not in (8, 9):
        msg = (
            f"tf static got {len(values)} values: expected 'x y z yaw pitch roll PARENT CHILD' "
            "or 'x y z qx qy qz qw PARENT CHILD'"
        )
        raise TfArgumentError(msg)
    *numbers, parent, child = values
    try:
        nums = [float(v) for v in numbers]
    except ValueError as exc:
        msg = f"tf static: {numbers} must all be numbers (metres and radians)"
        raise TfArgumentError(msg) from exc
    x, y, z = nums[:3]
    if len(nums) == 6:  # x y z yaw pitch roll
        yaw, pitch, roll = nums[3:]
        q = quaternion_from_euler(roll, pitch, yaw)
    else:
        q = np.asarray(nums[3:], dtype=float)
        norm = float(np.linalg.norm(q))
        if norm < 1e-9:
            msg = f"tf static: quaternion {nums[3:]} has zero length"
            raise TfArgumentError(msg)
        q = q / norm
    return make(
        TransformStamped,
        header=Header(stamp=ns_to_time(time.time_ns()), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=z),
            rotation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])),
        ),
    )


def cmd_static(args: argparse.Namespace) -> int:
    """``tf static``."""
    transform = static_transform_from_args(args.values)
    with cli_node(args, discover=False) as node:
        from visnav.graph.node import Node

        pub_node = Node(f"static_transform_publisher_{os.getpid()}", context=node.context)
        StaticTransformBroadcaster(pub_node).send_transform(transform)
        tr = transform.transform.translation
        print(
            f"publishing static transform {transform.header.frame_id} -> "
            f"{transform.child_frame_id}: [{tr.x:.3f}, {tr.y:.3f}, {tr.z:.3f}]",
            flush=True,
        )
        node.context.spin(duration_s=args.duration)
    return 0


def cmd_tree(args: argparse.Namespace) -> int:
    """``tf tree``."""
    buffer = Buffer()
    with cli_node(args) as node:
        TransformListener(buffer, node)
        node.context.spin(duration_s=args.duration)
        infos = buffer.frame_infos()
        print(format_tree_dot(infos) if args.dot else format_tree(infos))
    return 0
