"""``visnav initialpose X Y [YAW]``: RViz's "2D Pose Estimate" (see :mod:`visnav.cli.goal`)."""

from __future__ import annotations

import argparse

from visnav.cli.goal import add_initialpose_arguments

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``visnav initialpose``'s arguments."""
    add_initialpose_arguments(parser)
