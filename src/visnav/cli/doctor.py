"""``visnav doctor``: diagnose the data chain of a live graph or a bag.

Exit code 0 when no error-level finding exists, 1 otherwise (and 1 with ``error: ...``
when doctor itself cannot run, or when the live graph has no topic at all: nothing runs
in that domain).
"""

from __future__ import annotations

import argparse

__all__ = ["add_arguments", "cmd_doctor"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``doctor`` options."""
    parser.add_argument("--bag", metavar="FILE", help="diagnose a bag instead of the live graph")
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="seconds to listen to the live graph (default 5); with --bag, only the first S s",
    )
    parser.add_argument(
        "--expect",
        metavar="EXPECT.yaml",
        help="expected topics, rates, frames, TF chains, consumer needs (docs/doctor.md)",
    )
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument(
        "--fixed-frame",
        metavar="F",
        default=None,
        help="the frame consumers transform data into (planning / fixed frame)",
    )
    parser.add_argument(
        "--no-info", action="store_true", help="leave info-level findings out of the table"
    )
    parser.set_defaults(func=cmd_doctor)


def cmd_doctor(args: argparse.Namespace) -> int:
    """Run doctor and print the report."""
    from visnav.doctor.expect import load_expectations
    from visnav.doctor.run import doctor_bag, doctor_live

    expect = load_expectations(args.expect) if args.expect else None
    if args.bag:
        report = doctor_bag(
            args.bag, duration_s=args.duration, expect=expect, fixed_frame=args.fixed_frame
        )
    else:
        report = doctor_live(
            domain=getattr(args, "domain", None),
            duration_s=5.0 if args.duration is None else args.duration,
            expect=expect,
            fixed_frame=args.fixed_frame,
        )
    if args.json:
        print(report.to_json())
    else:
        print(report.format(show_info=not args.no_info), end="")
    return 1 if report.has_errors else 0
