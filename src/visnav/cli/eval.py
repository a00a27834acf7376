"""``visnav eval ate|rpe EST GT``: trajectory errors of TUM files (evo_ape / evo_rpe numbers)."""

from __future__ import annotations

import argparse
import json

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``eval`` sub-commands."""
    sub = parser.add_subparsers(dest="metric", metavar="METRIC")
    sub.required = True
    for name, help_text in (
        ("ate", "absolute trajectory error (evo_ape)"),
        ("rpe", "relative pose error (evo_rpe)"),
    ):
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("est", metavar="EST", help="estimated trajectory (TUM file)")
        p.add_argument("gt", metavar="GT", help="reference trajectory (TUM file)")
        p.add_argument("-a", "--align", action="store_true", help="Umeyama SE(3) alignment")
        p.add_argument("-s", "--scale", action="store_true", help="also correct the scale")
        p.add_argument(
            "-r",
            "--pose-relation",
            default="trans_part",
            choices=("trans_part", "angle_deg", "angle_rad", "full"),
            help="what to measure (default trans_part, metres)",
        )
        p.add_argument("--max-diff", type=float, default=0.01, help="association tolerance (s)")
        p.add_argument("--offset", type=float, default=0.0, help="added to EST stamps (s)")
        p.add_argument("--json", action="store_true", help="print the statistics as JSON")
        if name == "rpe":
            p.add_argument("-d", "--delta", type=float, default=1, help="pair distance")
            p.add_argument(
                "-u",
                "--delta-unit",
                choices=("f", "m"),
                default="f",
                help="delta in frames (f) or metres travelled (m)",
            )
            p.add_argument("--all-pairs", action="store_true", help="every pose starts a pair")
        p.set_defaults(func=cmd_eval)


def cmd_eval(args: argparse.Namespace) -> int:
    """Compute and print the metric."""
    from visnav.slam.evaluation import ate, rpe
    from visnav.slam.trajectory import read_tum

    est = read_tum(args.est)
    gt = read_tum(args.gt)
    common = {
        "align": args.align,
        "scale": args.scale,
        "pose_relation": args.pose_relation,
        "max_diff": args.max_diff,
        "offset": args.offset,
    }
    if args.metric == "ate":
        result = ate(est, gt, **common)
    else:
        result = rpe(
            est,
            gt,
            delta=args.delta,
            delta_unit="frames" if args.delta_unit == "f" else "meters",
            all_pairs=args.all_pairs,
            **common,
        )
    if args.json:
        print(json.dumps({"metric": args.metric, "pairs": len(result.errors), **result.stats()}))
    else:
        print(result.summary())
    return 0
