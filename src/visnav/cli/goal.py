"""``visnav goal`` and ``visnav initialpose``: RViz's "2D Nav Goal" and "2D Pose Estimate".

RViz's GoalTool publishes a ``geometry_msgs/PoseStamped`` on ``/move_base_simple/goal``
and its InitialPoseTool a ``geometry_msgs/PoseWithCovarianceStamped`` on ``/initialpose``,
both in the fixed frame, stamped with the node's time (sim time under ``/use_sim_time``),
the pose estimate with a covariance of 0.5 m standard deviation in x and y and pi/12 in
yaw. These verbs send the same messages from a terminal. Unlike a click, they wait for
the subscriber to match before publishing, so the one message is never lost (``rostopic
pub -1`` latches for the same reason); ``goal --wait`` sends the goal through move_base's
action instead and prints its result, as ``actionlib``'s SimpleActionClient would.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from visnav.cli._common import cli_node
from visnav.cli.topic import wait_for_matching_subscriptions
from visnav.errors import VisnavError
from visnav.graph import Parameter
from visnav.graph.action_client import ActionClient
from visnav.graph.action_types import ActionError, GoalStatus
from visnav.graph.node import Node
from visnav.msgs import PoseStamped, PoseWithCovarianceStamped
from visnav.msgs.action import get_action_type
from visnav.msgs.rviz_tools import nav_goal, pose_estimate

__all__ = ["GoalArgumentError", "add_arguments", "add_initialpose_arguments"]


class GoalArgumentError(VisnavError, ValueError):
    """A pose argument that is not a finite number."""


def _finite(name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        msg = f"{name} is {text!r}: expected a finite number (metres, or radians for yaw)"
        raise GoalArgumentError(msg)
    return value


def _common(p: argparse.ArgumentParser, topic: str) -> None:
    p.add_argument("x", help="x in the frame (m)")
    p.add_argument("y", help="y in the frame (m)")
    p.add_argument("yaw", nargs="?", default="0", help="heading (rad, default 0)")
    p.add_argument("--frame", default="map", help="the fixed frame (default map, as RViz's)")
    p.add_argument("--topic", default=topic, help=f"topic (default {topic})")
    p.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        help="seconds to wait for a subscriber (or the action server) (default 10)",
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``visnav goal``'s arguments."""
    _common(parser, "/move_base_simple/goal")
    parser.add_argument(
        "--wait",
        action="store_true",
        help="send through the move_base action and wait for its result",
    )
    parser.add_argument(
        "--action", default="move_base", help="the action with --wait (default move_base)"
    )
    parser.set_defaults(func=cmd_goal)


def add_initialpose_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``visnav initialpose``'s arguments."""
    _common(parser, "/initialpose")
    parser.set_defaults(func=cmd_initialpose)


def _pose_args(args: argparse.Namespace) -> tuple[float, float, float]:
    return _finite("x", args.x), _finite("y", args.y), _finite("yaw", args.yaw)


def _now_ns(node: Node) -> int:
    """The graph's time: sim time when a node publishes /clock (as RViz under use_sim_time)."""
    if any(e.kind == "publisher" for e in node.context.graph.endpoints("/clock")):
        node.set_parameters([Parameter("use_sim_time", value=True)])
        clock = node.get_clock()
        node.context.spin_until(lambda: clock.now_ns() > 0, 2.0)
        return clock.now_ns()
    return node.get_clock().now_ns()


def _publish_once(node: Node, msg_type: Any, topic: str, msg: Any, timeout: float) -> None:
    pub = node.create_publisher(msg_type, topic, 10)
    wait_for_matching_subscriptions(pub, 1, max_wait_s=timeout)
    pub.publish(msg)
    node.context.spin_some()


def cmd_goal(args: argparse.Namespace) -> int:
    """``visnav goal X Y [YAW]``."""
    x, y, yaw = _pose_args(args)
    with cli_node(args) as node:
        msg = nav_goal(x, y, yaw, frame_id=args.frame, stamp_ns=_now_ns(node))
        if not args.wait:
            _publish_once(node, PoseStamped, args.topic, msg, args.timeout)
            print(f"goal ({x:g}, {y:g}, yaw {yaw:g}) in '{args.frame}' sent on {args.topic}")
            return 0
        return _goal_through_action(node, args, msg)


def _goal_through_action(node: Node, args: argparse.Namespace, target: PoseStamped) -> int:
    atype = get_action_type("move_base_msgs/action/MoveBase")
    client = ActionClient(node, atype, args.action)
    ctx = node.context
    if not client.wait_for_server(args.timeout):
        msg = (
            f"action '{client.action_name}' (move_base_msgs/action/MoveBase) has no server "
            f"after {args.timeout:g} s: is move_base running? (`visnav action list -t`)"
        )
        raise ActionError(msg)
    goal = atype.Goal(target_pose=target)
    sent = client.send_goal_async(goal)
    ctx.spin_until(sent.done)
    handle = sent.result()
    if handle is None or not handle.accepted:
        print("goal rejected")
        return 1
    print(f"goal ({target.pose.position.x:g}, {target.pose.position.y:g}) accepted", flush=True)
    result = handle.get_result_async()
    try:
        while not result.done():
            ctx.spin_once(0.1)
    except KeyboardInterrupt:
        cancel = handle.cancel_goal_async()
        ctx.spin_until(cancel.done, 5.0)
        print("goal canceled")
        return 130
    response: Any = result.result()
    status = GoalStatus(int(response.status)).name.removeprefix("STATUS_")
    print(f"goal finished: {status}")
    return 0 if status == "SUCCEEDED" else 1


def cmd_initialpose(args: argparse.Namespace) -> int:
    """``visnav initialpose X Y [YAW]``."""
    x, y, yaw = _pose_args(args)
    with cli_node(args) as node:
        msg = pose_estimate(x, y, yaw, frame_id=args.frame, stamp_ns=_now_ns(node))
        _publish_once(node, PoseWithCovarianceStamped, args.topic, msg, args.timeout)
        print(f"pose estimate ({x:g}, {y:g}, yaw {yaw:g}) in '{args.frame}' sent on {args.topic}")
    return 0
