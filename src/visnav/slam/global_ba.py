"""When and how a :class:`~visnav.slam.SlamSystem` adjusts its whole map.

Global bundle adjustment optimises every keyframe pose (but the first, or the first
two in monocular mode, which hold the scale) and every map point seen twice. It runs
after each loop closure (``global_ba_after_loop``) and at the end of a run
(``final_global_ba``). After a loop it runs inline, or with ``global_ba_delay`` > 0
in a helper process, merged that many frames later
(:class:`~visnav.slam.background_ba.BackgroundGlobalBa`). In localisation mode only
the new keyframes are optimised; the saved ones that see their points are held.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from visnav.slam.background_ba import BackgroundGlobalBa
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig
from visnav.slam.localization_mode import SavedMapAnchor
from visnav.slam.optimizer import BaProblem, BaResult, ba_problem, solve_ba, store_ba
from visnav.slam.slam_map import SlamMap

__all__ = ["GlobalAdjuster"]

FloatArray = NDArray[np.float64]


class GlobalAdjuster:
    """Runs a system's global bundle adjustments (inline or in the background).

    Args:
        slam_map: the map (adjusted in place).
        camera: intrinsics.
        config: ``global_ba_iterations`` and ``global_ba_delay``.
        inv_sigma2_levels: per pyramid level, ``1 / scale^2``.
        mono: monocular (the first two keyframes are held).
        saved: localisation mode's saved map (its keyframes are held).
        note: called with every adjustment's result.
    """

    def __init__(
        self,
        slam_map: SlamMap,
        camera: CameraIntrinsics,
        config: SlamConfig,
        inv_sigma2_levels: FloatArray,
        *,
        mono: bool,
        saved: SavedMapAnchor | None,
        note: Callable[[BaResult], None],
    ) -> None:
        self.map, self.camera, self.config = slam_map, camera, config
        self.levels = inv_sigma2_levels
        self.mono, self.saved, self.note = mono, saved, note
        self.background = (
            BackgroundGlobalBa(
                config.global_ba_delay, camera, inv_sigma2_levels, config.global_ba_iterations
            )
            if config.global_ba_delay > 0
            else None
        )

    def run(self, iterations: int | None = None) -> BaResult | None:
        """Adjust the map now (None with fewer than two keyframes to optimise)."""
        self.merge_pending()  # the older one first, as it was due
        problem = self._problem()
        if problem is None:
            return None
        if isinstance(problem, BaResult):  # nothing observed twice
            self.note(problem)
            return problem
        solution = solve_ba(
            problem, self.camera, self.levels, iterations or self.config.global_ba_iterations
        )
        result = store_ba(self.map, self.camera, problem, solution)
        self.note(result)
        return result

    def after_loop(self, frame: int) -> None:
        """A loop closed while tracking ``frame``: adjust now, or start it in the background."""
        if self.background is None:
            self.run()
            return
        problem = self._problem()
        if problem is None:
            return
        if isinstance(problem, BaResult):
            self.note(problem)
            return
        self.background.start(self.map, problem, frame)

    def merge_pending(self) -> None:
        """Merge a background adjustment now, if one is pending (waits for the helper).

        A loop about to correct the map calls it: merging the older adjustment after that
        correction would undo it for the keyframes the adjustment holds.
        """
        if self.background is not None and self.background.pending:
            self.note(self.background.merge(self.map))

    def merge_due(self, frame: int) -> bool:
        """Merge a background adjustment due before ``frame``; return whether one was."""
        if self.background is None or not self.background.due(frame):
            return False
        self.note(self.background.merge(self.map))
        return True

    def close(self) -> None:
        """Stop the helper process, if any (idempotent)."""
        if self.background is not None:
            self.background.close()

    def _problem(self) -> BaProblem | BaResult | None:
        ids = [kf.id for kf in self.map.keyframes if not kf.bad]
        fixed: list[int] | None = ids[:2] if self.mono else ids[:1]  # mono: the scale
        if self.saved is not None:  # the new keyframes; the saved ones seeing them are held
            ids, fixed = self.saved.new_only(ids), None
        if len(ids) < 2:
            return None
        return ba_problem(self.map, ids, fixed_ids=fixed, min_observations=2)
