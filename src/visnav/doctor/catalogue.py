"""The fault catalogue: every check doctor runs, by id.

Each finding names one of these ids. Ids are ``<category>.<name>``; the categories are
topics, description, rates, images, camera_info, tf, time, frames and planner.
``needs_graph`` checks look at publishers and subscriptions, which a bag does not
record: they are skipped on bags (QoS of a bag's publishers is still read).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["CATALOGUE", "CATEGORIES", "CheckInfo"]

CATEGORIES = (
    "topics",
    "description",
    "rates",
    "images",
    "camera_info",
    "tf",
    "time",
    "frames",
    "planner",
)


@dataclass(frozen=True)
class CheckInfo:
    """One check of the catalogue.

    Attributes:
        check_id: ``category.name``.
        category: one of :data:`CATEGORIES`.
        summary: the fault it detects, one line.
        needs_graph: True when it needs the live graph (endpoints), so bags skip it.
    """

    check_id: str
    category: str
    summary: str
    needs_graph: bool = False


def _c(check_id: str, summary: str, *, needs_graph: bool = False) -> CheckInfo:
    category = check_id.split(".", 1)[0]
    return CheckInfo(check_id, category, summary, needs_graph)


_ALL = (
    # topics
    _c("topics.expected_missing", "a topic named in --expect is not published (or not in the bag)"),
    _c("topics.expected_type", "a topic carries another type than --expect declares"),
    _c(
        "topics.namespace_mismatch",
        "a subscriber waits on a name that exists only under another namespace "
        "(/camera/depth/points vs /drone/camera/depth/points)",
        needs_graph=True,
    ),
    _c("topics.no_publisher", "a subscription has no publisher", needs_graph=True),
    _c("topics.no_subscriber", "a publisher has no subscription (info)", needs_graph=True),
    _c(
        "topics.qos_incompatible",
        "a publisher's QoS cannot feed a subscription (best effort -> reliable, ...)",
        needs_graph=True,
    ),
    _c(
        "topics.type_mismatch",
        "publishers and subscriptions of one topic use different types",
        needs_graph=True,
    ),
    _c("topics.undecodable", "a topic's type is unknown to visnav, its data were not checked"),
    # description
    _c(
        "description.sensor_unpublished",
        "a sensor or plugin of robot_description declares a topic nobody publishes",
        needs_graph=True,
    ),
    _c(
        "description.sensor_ignored",
        "a <sensor> or <plugin> of robot_description is not simulated (unsupported type)",
    ),
    # rates
    _c("rates.no_messages", "a published (or expected) topic delivered no message"),
    _c("rates.mismatch", "measured rate differs from the declared rate"),
    _c("rates.jitter", "the period varies a lot from message to message"),
    _c("rates.gap", "the stream paused once for many periods"),
    _c("rates.intermittent", "the stream keeps stopping and restarting"),
    _c("rates.stopped", "the stream stopped before the end of the observation"),
    # images
    _c("images.size_mismatch", "encoding, width, step and data size disagree"),
    _c("images.encoding_unexpected", "encoding differs from the declared or expected one"),
    _c("images.rgb_bgr_swap", "colour channels look swapped (sky/ground/known-colour heuristic)"),
    _c("images.black", "frames are black"),
    _c("images.blank", "frames are uniform (one grey level or colour)"),
    _c("images.saturated", "frames are mostly saturated (white)"),
    _c("images.depth_invalid", "depth images are all zero / NaN / inf"),
    _c("images.depth_unit", "depth values are in another unit than the encoding or consumer uses"),
    # camera_info
    _c("camera_info.missing", "an image topic has no sibling camera_info"),
    _c("camera_info.k_zero", "K (or P) is all zero: uncalibrated camera"),
    _c("camera_info.k_vs_size", "K or the camera_info size is inconsistent with the image size"),
    _c("camera_info.fx_vs_fov", "fx disagrees with the declared horizontal field of view"),
    _c("camera_info.d_length", "D has the wrong length for distortion_model"),
    _c(
        "camera_info.distortion_unknown",
        "distortion_model is empty/unknown where rectification is needed",
    ),
    _c(
        "camera_info.unrectified_consumer",
        "a node reads the raw (distorted) images while no rectified topic exists",
        needs_graph=True,
    ),
    _c("camera_info.stamp_mismatch", "image and camera_info stamps do not match"),
    _c("camera_info.frame_mismatch", "image and camera_info frame_ids differ"),
    # tf
    _c("tf.unknown_frame", "a message's frame_id is never published on TF"),
    _c("tf.chain_broken", "a chain a consumer needs is broken; the missing link is named"),
    _c("tf.cycle", "TF parent links form a cycle"),
    _c("tf.two_parents", "a frame is published with two different parents"),
    _c("tf.quaternion", "a transform's quaternion is not normalised (or not finite)"),
    _c("tf.stale", "transforms lag the clock or stopped being published"),
    _c("tf.future", "transforms are stamped ahead of the clock"),
    _c("tf.extrapolation", "data stamps fall outside the TF data a consumer's lookup needs"),
    _c("tf.static_on_tf", "a constant (static) transform is published on /tf"),
    # time
    _c("time.sim_time_no_clock", "nodes use sim time (subscribe /clock), no /clock is published"),
    _c("time.wall_stamps", "/clock runs sim time but a node stamps with wall time"),
    _c("time.zero_stamp", "header stamps are zero"),
    _c("time.stamp_offset", "stamps are far from the clock (late or in the future)"),
    _c("time.backwards", "stamps (or /clock) go backwards"),
    # frames
    _c("frames.rotated_cloud", "a cloud in a body frame holds optical data (or the reverse)"),
    _c("frames.image_in_body_frame", "an image / camera_info is in a body (z up) frame"),
    _c("frames.scan_in_optical_frame", "a LaserScan is in an optical (z forward) frame"),
    _c("frames.odom_tf_mismatch", "odometry frame_id / child_frame_id / pose disagree with TF"),
    _c("frames.empty_frame_id", "header.frame_id is empty"),
    _c("frames.leading_slash", "frame_id starts with '/' (tf2 refuses it in lookups)"),
    # planner
    _c("planner.inputs_missing", "a planner input is not published", needs_graph=False),
    _c("planner.range_short", "sensor range (clip far) is shorter than the planner horizon"),
    _c("planner.fov_ahead", "the cloud or scan never covers the region ahead of the vehicle"),
)

CATALOGUE: Mapping[str, CheckInfo] = {c.check_id: c for c in _ALL}
"""Every check by id, in report order."""
