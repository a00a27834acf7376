"""``visnav slam``: offline RGB-D SLAM on a TUM RGB-D folder or a bag -> TUM trajectory."""

from __future__ import annotations

import argparse
import dataclasses
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from visnav.slam.camera import CameraIntrinsics

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``slam`` options."""
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--tum", metavar="DIR", help="a TUM RGB-D folder (rgb.txt, depth.txt, ...)")
    src.add_argument("--bag", metavar="FILE", help="a bag with image, depth and camera_info")
    parser.add_argument("-o", "--output", help="TUM trajectory to write (default beside the input)")
    parser.add_argument("--intrinsics", metavar="FX,FY,CX,CY", help="TUM: rectified intrinsics")
    parser.add_argument("--camera-info", metavar="FILE", help="TUM: a camera_info YAML")
    parser.add_argument("--depth-scale", type=float, default=5000.0, help="TUM: depth units/m")
    bag = "bag (defaults: the built-in car's RGB-D camera)"
    parser.add_argument("--image-topic", default="/depth_camera/image_raw", help=f"{bag}: image")
    parser.add_argument(
        "--depth-topic", default="/depth_camera/depth/image_raw", help=f"{bag}: depth"
    )
    parser.add_argument(
        "--info-topic", default="/depth_camera/camera_info", help=f"{bag}: camera_info"
    )
    parser.add_argument("--gt-topic", default="/ground_truth/odom", help="bag: ground truth odom")
    parser.add_argument(
        "--base-frame", default=None, help="bag: trajectory frame (default: the ground truth's)"
    )
    parser.add_argument("--features", type=int, default=1000, help="ORB features per frame")
    parser.add_argument("--seed", type=int, default=0, help="seed of RANSAC and vocabulary")
    parser.add_argument("--no-loop", action="store_true", help="disable loop closure")
    parser.add_argument("--vocabulary", metavar="NPZ", help="a saved vocabulary")
    parser.add_argument("--max-frames", type=int, default=None, help="stop after N frames")
    parser.add_argument(
        "--mono", action="store_true", help="monocular SLAM (depth/odometry only for the scale)"
    )
    parser.add_argument(
        "--scale",
        choices=("depth", "odometry"),
        default="depth",
        help="--mono: metric scale from the depth image at initialisation, or from odometry "
        "(TUM: groundtruth.txt; bag: odom -> camera in /tf)",
    )
    parser.set_defaults(func=cmd_slam)


def _intrinsics(args: argparse.Namespace, width: int, height: int) -> CameraIntrinsics:
    from visnav.slam.errors import SlamInputError

    try:
        fx, fy, cx, cy = (float(v) for v in args.intrinsics.split(","))
    except ValueError:
        text = f"--intrinsics {args.intrinsics!r}: expected four numbers FX,FY,CX,CY"
        raise SlamInputError(text) from None
    from visnav.slam.camera import CameraIntrinsics

    return CameraIntrinsics(fx, fy, cx, cy, width, height)


def cmd_slam(args: argparse.Namespace) -> int:
    """Run SLAM and print the summary (and the evaluation when there is ground truth)."""
    from visnav.slam.camera import CameraIntrinsics
    from visnav.slam.config import SlamConfig
    from visnav.slam.offline import slam_bag, slam_tum

    config = SlamConfig(
        n_features=args.features,
        seed=args.seed,
        loop_closure=not args.no_loop,
        sensor="mono" if args.mono else "rgbd",
        mono_scale=args.scale,
    )
    if args.tum is not None:
        camera = None
        if args.camera_info:
            from visnav.perception.camera_info_yaml import read_camera_info_yaml

            camera, _ = CameraIntrinsics.from_camera_info(
                read_camera_info_yaml(args.camera_info), source=args.camera_info
            )
        elif args.intrinsics:
            camera = _intrinsics_for_folder(args)
        run = slam_tum(
            args.tum,
            output=args.output,
            camera=camera,
            config=config,
            vocabulary=args.vocabulary,
            depth_scale=args.depth_scale,
            max_frames=args.max_frames,
        )
    else:
        run = slam_bag(
            args.bag,
            image_topic=args.image_topic,
            depth_topic=args.depth_topic,
            info_topic=args.info_topic,
            groundtruth_topic=args.gt_topic or None,
            base_frame=args.base_frame,
            output=args.output,
            config=dataclasses.replace(config, depth_scale=None),
            vocabulary=args.vocabulary,
            max_frames=args.max_frames,
        )
    print(run.summary())
    return 0 if run.tracked else 1


def _intrinsics_for_folder(args: argparse.Namespace) -> CameraIntrinsics:
    """Intrinsics from --intrinsics, with the image size read from the first colour image."""
    import logging

    import cv2

    from visnav.slam.errors import SlamInputError
    from visnav.slam.tum import TumSequence

    # the run reads the folder again and logs its warnings then: say them once
    quiet = logging.Logger("visnav.cli.slam.image_size")
    quiet.addHandler(logging.NullHandler())
    seq = TumSequence(args.tum, logger=quiet)
    first = cv2.imread(str(seq.frames[0].rgb_path), cv2.IMREAD_UNCHANGED)
    if first is None:
        text = f"cannot read {seq.frames[0].rgb_path} to get the image size"
        raise SlamInputError(text)
    return _intrinsics(args, int(first.shape[1]), int(first.shape[0]))
