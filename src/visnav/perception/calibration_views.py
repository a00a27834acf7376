"""Are the calibration views able to determine the camera? Checks run before solving.

``cv2.calibrateCamera`` returns a camera matrix for any set of views, even for views
that carry no information on the focal length: eight copies of one image gave fx 870
and fy 950, boards parallel to the image plane gave fx 7400 with a small reported
uncertainty. :func:`check_views` refuses such sets with an error saying what to
change, instead of letting a wrong K be written:

* repeated views: two views whose corners lie within ``DUPLICATE_PX`` pixels of each
  other (on average) are one board pose; fewer than ``min_views`` distinct poses is an
  error (a few repeats among enough distinct poses only warn);
* fronto-parallel views: a view counts as tilted when its farthest corner is at least
  ``MIN_PERSPECTIVE`` (5 %) farther from the camera than its nearest one, measured
  from the image alone (:func:`~visnav.perception.chessboard.perspective_ratio`);
  fewer than two tilted views is an error.

ROS camera_calibration has no such checks (it only refuses to calibrate until its
X / Y / size / skew progress bars have moved); visnav differs on purpose.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from visnav.perception._calibration_common import CalibrationError, WarningLogger
from visnav.perception.chessboard import perspective_ratio

__all__ = ["DUPLICATE_PX", "MIN_PERSPECTIVE", "MIN_TILTED_VIEWS", "check_views"]

DUPLICATE_PX = 2.0
"""Views whose corners differ by less than this (mean, pixels) show the same pose."""
MIN_PERSPECTIVE = 0.05
"""A view is tilted when its far corner is at least this much farther than its near one."""
MIN_TILTED_VIEWS = 2
"""Fewest tilted views that determine the focal length."""


def _distinct(
    names: Sequence[str], points: Sequence[NDArray[np.float32]]
) -> tuple[list[int], list[tuple[str, str]]]:
    """Indices of the first view of each pose, and (repeat, original) name pairs."""
    kept: list[int] = []
    repeats: list[tuple[str, str]] = []
    for i, pts in enumerate(points):
        for k in kept:
            if float(np.linalg.norm(pts - points[k], axis=1).mean()) < DUPLICATE_PX:
                repeats.append((names[i], names[k]))
                break
        else:
            kept.append(i)
    return kept, repeats


def check_views(
    names: Sequence[str],
    points: Sequence[NDArray[np.float32]],
    pattern: tuple[int, int],
    *,
    min_views: int,
    logger: WarningLogger,
) -> None:
    """Refuse views that cannot determine the focal length (see the module docs).

    Args:
        names: a display name per view.
        points: the refined corners per view, (N, 2) pixels, row by row.
        pattern: inner corners (columns, rows).
        min_views: fewest distinct board poses required.
        logger: where warnings go (a few repeated views).

    Raises:
        CalibrationError: too few distinct poses, or too few tilted views.
    """
    kept, repeats = _distinct(names, points)
    if len(kept) < min_views:
        example = f" ({repeats[0][0]} repeats {repeats[0][1]})" if repeats else ""
        text = (
            f"only {len(kept)} distinct board poses among {len(points)} views{example}: "
            f"at least {min_views} are needed, or the camera matrix is undetermined. Move "
            "and tilt the board between images"
        )
        raise CalibrationError(text)
    if repeats:
        logger.warning(
            f"{len(repeats)} views repeat another view's board pose (e.g. {repeats[0][0]} "
            f"repeats {repeats[0][1]}); they add no information"
        )
    ratios = [perspective_ratio(points[i], pattern) for i in kept]
    tilted = sum(r >= MIN_PERSPECTIVE for r in ratios)
    if tilted < MIN_TILTED_VIEWS:
        text = (
            f"{len(kept) - tilted} of {len(kept)} views show the board nearly parallel to the "
            f"image plane (its far corner at most {max(ratios) * 100:.1f} % farther than the "
            f"near one; a view needs {MIN_PERSPECTIVE * 100:.0f} %): the focal length is "
            f"undetermined. Add at least {MIN_TILTED_VIEWS} views with the board tilted by "
            "20-45 degrees (left/right and up/down)"
        )
        raise CalibrationError(text)
