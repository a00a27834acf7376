"""Global bundle adjustment off the tracking path, applied at a fixed frame.

After a loop closes, ORB-SLAM2 runs its global bundle adjustment in a thread of its
own while tracking and local mapping go on, and merges the result when it is done:
keyframes and points that were in the adjustment take its poses and positions, the
keyframes created meanwhile follow their spanning-tree parent's correction, and the
points created meanwhile their reference keyframe's. Its runs therefore depend on
how long the adjustment took.

:class:`BackgroundGlobalBa` does the same with a fixed delay instead: the problem is
a snapshot (:class:`~visnav.slam.optimizer.BaProblem`) solved by gtsam in a helper
process, and the result is merged before frame ``n + delay`` is tracked, ``n`` being
the frame that closed the loop, waiting for the helper if it is not done. The merge
happens at the same frame whatever the machine's speed, so the same inputs give the
same trajectory. A loop closed before the merge must not be undone by it:
:class:`~visnav.slam.global_ba.GlobalAdjuster` merges the pending adjustment before the
loop's pose-graph check (ORB-SLAM2 instead aborts the running one). Starting a new
adjustment while one is pending supersedes it: the stale result is dropped.

gtsam holds the GIL while it optimises (a thread would stall tracking as much as
running it inline), hence a process, started by ``spawn`` with the system (its imports
take ~1 s of CPU, better spent then than at the first loop); it inherits the worker's
single-threaded BLAS settings. A helper still solving a superseded adjustment is killed
and a new one started rather than let the stale solve delay the new one.
"""

from __future__ import annotations

import multiprocessing
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.errors import SlamError
from visnav.slam.geometry import inverse, orthonormalize
from visnav.slam.optimizer import (
    BaProblem,
    BaResult,
    BaSolution,
    apply_point_corrections,
    erase_outliers,
    solve_ba,
)
from visnav.slam.slam_map import SlamMap

__all__ = ["BackgroundGlobalBa", "merge_global_ba"]

FloatArray = NDArray[np.float64]

_Task = tuple[BaProblem, CameraIntrinsics, FloatArray, int]


def _serve(conn: Connection) -> None:
    """The helper process: solve each problem received, until the pipe closes."""
    while True:
        try:
            task: _Task | None = conn.recv()
        except (EOFError, OSError):  # the worker is gone
            return
        if task is None:
            return
        try:
            answer: BaSolution | str = solve_ba(*task)
        except Exception as exc:  # noqa: BLE001 - every failure goes back to the worker
            answer = f"{type(exc).__name__}: {exc}"
        try:
            conn.send(answer)
        except OSError:  # the worker stopped waiting (closed, or gone)
            return


@dataclass(frozen=True)
class _Pending:
    problem: BaProblem
    apply_at: int
    n_keyframes: int  # keyframes in the map when the snapshot was taken


class BackgroundGlobalBa:
    """Solves global bundle adjustments in a helper process; merges them at a set frame.

    Args:
        delay_frames: frames after the one that started an adjustment at which it is
            merged (> 0).
        camera: intrinsics of the map.
        inv_sigma2_levels: per pyramid level, ``1 / scale^2``.
        iterations: Levenberg-Marquardt iterations.
    """

    def __init__(
        self,
        delay_frames: int,
        camera: CameraIntrinsics,
        inv_sigma2_levels: FloatArray,
        iterations: int,
    ) -> None:
        if delay_frames < 1:
            text = f"global_ba_delay {delay_frames}: expected frames >= 1 (0: inline)"
            raise SlamError(text)
        self.delay = int(delay_frames)
        self.camera = camera
        self.levels = np.asarray(inv_sigma2_levels, dtype=np.float64)
        self.iterations = int(iterations)
        self._proc: BaseProcess | None = None
        self._conn: Connection | None = None
        self._pending: _Pending | None = None
        self.superseded = 0
        self._spawn()  # its imports now rather than at the first loop

    def _spawn(self) -> None:
        ctx = multiprocessing.get_context("spawn")
        ours, theirs = ctx.Pipe()
        self._proc = ctx.Process(target=_serve, args=(theirs,), daemon=True)
        self._proc.start()
        theirs.close()
        self._conn = ours

    @property
    def pending(self) -> bool:
        """An adjustment is being solved and not yet merged."""
        return self._pending is not None

    def start(self, slam_map: SlamMap, problem: BaProblem, frame: int) -> None:
        """Solve ``problem`` in the helper; it is due before frame ``frame + delay``.

        A pending adjustment is superseded: its result would undo the newer loop's
        correction. A helper still solving it is stopped rather than waited for.
        """
        if self._pending is not None:
            self._pending = None
            self.superseded += 1
            assert self._conn is not None  # a pending adjustment was sent on it
            if self._conn.poll():
                self._conn.recv()  # done: drop it
            else:
                self._stop(kill=True)
        if self._conn is None:
            self._spawn()
        assert self._conn is not None  # _spawn made it
        task: _Task = (problem, self.camera, self.levels, self.iterations)
        self._conn.send(task)
        self._pending = _Pending(problem, frame + self.delay, len(slam_map.keyframes))

    def due(self, frame: int) -> bool:
        """Whether an adjustment is to be merged before tracking ``frame``."""
        return self._pending is not None and frame >= self._pending.apply_at

    def merge(self, slam_map: SlamMap) -> BaResult:
        """Wait for the pending adjustment and merge it into the map.

        Raises:
            SlamError: nothing is pending.
        """
        pending = self._pending
        if pending is None or self._conn is None:
            raise SlamError("no global bundle adjustment is pending")
        self._pending = None
        try:
            answer: BaSolution | str = self._conn.recv()
        except (EOFError, OSError) as exc:  # the helper died: report it, keep the map
            self._stop(kill=True)
            answer = f"the helper process ended ({exc!r})"
        if isinstance(answer, str):
            text = f"global bundle adjustment in the helper process failed: {answer}"
            return BaResult(*pending.problem.sizes(), 0, 0.0, 0.0, text)
        return merge_global_ba(slam_map, self.camera, pending.problem, answer, pending.n_keyframes)

    def close(self) -> None:
        """Stop the helper process (idempotent); a pending adjustment is dropped."""
        busy, self._pending = self._pending is not None, None
        self._stop(kill=busy)

    def _stop(self, *, kill: bool) -> None:
        if self._conn is not None:
            if not kill:
                try:
                    self._conn.send(None)
                except (OSError, ValueError):
                    kill = True
            self._conn.close()
            self._conn = None
        if self._proc is not None:
            if kill:
                self._proc.kill()
            self._proc.join(5.0)
            if self._proc.is_alive():
                self._proc.kill()
                self._proc.join(5.0)
            self._proc = None


def merge_global_ba(
    slam_map: SlamMap,
    cam: CameraIntrinsics,
    problem: BaProblem,
    solution: BaSolution,
    n_keyframes: int,
) -> BaResult:
    """Merge a global adjustment solved on a snapshot into a map that went on.

    Args:
        slam_map: the map now.
        cam: intrinsics.
        problem: the snapshot the adjustment solved.
        solution: its result.
        n_keyframes: keyframes in the map when the snapshot was taken (those after
            it were created meanwhile).

    Keyframes of the snapshot take their optimised pose; later keyframes keep their
    pose relative to their spanning-tree parent; points of the snapshot take their
    optimised position, every other point moves with its reference keyframe.
    Observations that the merged map rejects are erased, as after an inline adjustment.
    """
    sizes = problem.sizes()
    if solution.error:
        e = solution.error_before
        return BaResult(*sizes, 0, e, e, solution.error)
    kfs = slam_map.keyframes
    new_t: dict[int, FloatArray] = {}
    for i, k in enumerate(problem.keyframes.tolist()):
        if not problem.fixed[i] and not kfs[k].bad:
            new_t[k] = orthonormalize(solution.t_cw[i])
    for kf in kfs[n_keyframes:]:  # created meanwhile: parents are older
        if kf.parent in new_t and not kf.bad:
            parent_old = kfs[kf.parent].t_cw
            new_t[kf.id] = orthonormalize(kf.t_cw @ inverse(parent_old) @ new_t[kf.parent])
    corrections = {k: inverse(t) @ kfs[k].t_cw for k, t in new_t.items()}
    apply_point_corrections(slam_map, corrections)  # every point with its reference keyframe
    for k, t in new_t.items():
        kfs[k].t_cw = t
    alive = ~slam_map.bad[problem.points]
    slam_map.positions[problem.points[alive]] = solution.positions[alive]
    obs = problem.obs_list[~slam_map.bad[problem.obs_list[:, 2]]]
    outliers = erase_outliers(slam_map, cam, obs) if len(obs) else 0
    slam_map.update_point_normals(problem.points[~slam_map.bad[problem.points]])
    return BaResult(*sizes, outliers, solution.error_before, solution.error_after)
