"""``visnav camera``: run the usb_cam or cv_camera driver on a device, video file or stream.

``visnav camera /dev/video0 --width 1280 --height 720 --pixel-format yuyv`` is
``rosrun usb_cam usb_cam_node _video_device:=/dev/video0 _image_width:=1280 ...``;
``--driver cv_camera`` runs cv_camera's node. Any other parameter of the node goes in
``-p name:=value`` (``-p camera_info_url:=file:///home/me/cam.yaml``). The node
publishes until Ctrl-C, ``--duration`` seconds, or the end of a video file. A ``-p``
parameter the driver does not have is named (with the closest one it has), not applied.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

__all__ = ["add_arguments", "driver_parameters"]

_DRIVERS = ("usb_cam", "cv_camera")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``camera`` options."""
    parser.add_argument(
        "source",
        nargs="?",
        default=None,
        help="/dev/videoN, a device index, a video file or a stream URL "
        "(default: the driver's, /dev/video0)",
    )
    parser.add_argument("--driver", choices=_DRIVERS, default="usb_cam", help="which node")
    parser.add_argument("--name", default=None, help="node name (default: the driver's name)")
    parser.add_argument("--namespace", default="/", help="node namespace")
    parser.add_argument("--width", type=int, default=None, help="image_width")
    parser.add_argument("--height", type=int, default=None, help="image_height")
    parser.add_argument("--fps", type=float, default=None, help="framerate (usb_cam) / rate")
    parser.add_argument(
        "--pixel-format", default=None, help="usb_cam pixel_format: yuyv, mjpeg, uyvy, ..."
    )
    parser.add_argument("--frame-id", default=None, help="camera_frame_id / frame_id")
    parser.add_argument(
        "--camera-info-url", default=None, help="calibration YAML (file:///path or a path)"
    )
    parser.add_argument(
        "-p",
        "--param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="any other parameter of the node (repeatable)",
    )
    parser.add_argument("--duration", type=float, default=None, help="wall seconds to run")
    parser.set_defaults(func=cmd_camera)


def _value(text: str) -> Any:
    from visnav.safe_yaml import YamlError, load_yaml

    try:
        return load_yaml(text, source="--param value") if text else ""
    except YamlError:
        return text


def driver_parameters(args: argparse.Namespace) -> dict[str, Any]:
    """The node's parameter overrides from the command line.

    Raises:
        CameraDriverError: a ``-p`` item without ``:=``, or an option the driver has
            no parameter for.
    """
    from visnav.perception.camera_driver import CameraDriverError

    usb = args.driver == "usb_cam"
    params: dict[str, Any] = {}
    for item in args.param:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            msg = f"-p {item!r}: expected NAME:=VALUE, e.g. -p camera_name:=front"
            raise CameraDriverError(msg)
        params[name.lstrip("_")] = _value(value)
    if args.source is not None:
        if usb:
            params["video_device"] = args.source
        elif args.source.lstrip("-").isdigit():
            params["device_id"] = int(args.source)
        elif args.source.startswith("/dev/"):
            params["device_path"] = args.source
        else:
            params["file"] = args.source
    fps = args.fps
    if usb and fps is not None:
        if not float(fps).is_integer():  # also nan and inf
            msg = (
                f"--fps {fps:g}: usb_cam's framerate is whole frames per second (e.g. --fps 30); "
                "for a fractional rate use --driver cv_camera (its rate is a float)"
            )
            raise CameraDriverError(msg)
        fps = int(fps)
    named = {
        "image_width": args.width,
        "image_height": args.height,
        "framerate" if usb else "rate": fps,
        "camera_frame_id" if usb else "frame_id": args.frame_id,
        "camera_info_url": args.camera_info_url,
    }
    params.update({k: v for k, v in named.items() if v is not None})
    if args.pixel_format is not None:
        if not usb:
            msg = "--pixel-format is a usb_cam parameter: cv_camera takes the device's format"
            raise CameraDriverError(msg)
        params["pixel_format"] = args.pixel_format
    return params


def cmd_camera(args: argparse.Namespace) -> int:
    """``visnav camera``."""
    from visnav.graph.context import Context
    from visnav.launch.param_check import report_unknown_parameters
    from visnav.perception.camera_driver_node import CvCameraNode, UsbCamNode

    params = driver_parameters(args)
    cls = UsbCamNode if args.driver == "usb_cam" else CvCameraNode
    with Context(getattr(args, "domain", None)) as ctx:
        node = cls(
            args.name or args.driver,
            context=ctx,
            namespace=args.namespace,
            parameter_overrides=params,
        )
        report_unknown_parameters(node, params, executable=args.driver)
        deadline = None if args.duration is None else time.monotonic() + args.duration

        def done() -> bool:
            return node.finished or (deadline is not None and time.monotonic() >= deadline)

        try:
            while not done():
                ctx.spin_until(done, timeout_s=0.5)
        finally:
            frames = node.frames
            node.destroy_node()
    print(f"{args.driver}: published {frames} frames")
    return 0
