"""A failing bundle adjustment is reported and counted, not discarded (issue 17 item 5)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from visnav.slam import optimizer
from visnav.slam.config import SlamConfig
from visnav.slam.system import SlamSystem

from .conftest import Sequence


class _FailingGtsam:
    """gtsam with an optimizer that raises as gtsam does on an indeterminate system."""

    def __init__(self, real: Any) -> None:
        self._real = real

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)

    def LevenbergMarquardtOptimizer(self, *args: Any) -> Any:
        class _Opt:
            def optimize(self) -> Any:
                msg = "Indeterminant linear system detected while working near variable 7"
                raise RuntimeError(msg)

        return _Opt()


def _diverging(poses: Any, points: Any, *args: Any) -> Any:
    """The compiled solver's failure: non-finite poses (the map must stay unchanged)."""
    return np.full_like(poses, np.nan), points.copy(), 1.0, float("nan")


@pytest.mark.parametrize("solver", ["compiled", "gtsam"])
def test_a_failed_local_bundle_adjustment_is_counted_and_warned(
    short_sequence: Sequence, monkeypatch: pytest.MonkeyPatch, solver: str
) -> None:
    seq = short_sequence
    if solver == "gtsam":
        real = optimizer._gtsam()
        monkeypatch.setattr(optimizer, "_gtsam", lambda: _FailingGtsam(real))
        monkeypatch.setattr(optimizer, "MAX_DENSE_KEYFRAMES", -1)
    else:
        monkeypatch.setattr(optimizer, "levenberg_marquardt_odometry", _diverging)
    slam = SlamSystem(seq.camera, SlamConfig(n_features=400), initial_pose=seq.poses[0])
    warnings: list[str] = []
    for i in range(25):
        res = slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
        warnings.extend(res.warnings)
    assert slam.ba_runs >= 1
    assert slam.ba_failures == slam.ba_runs
    expected = "Indeterminant linear system" if solver == "gtsam" else "diverged"
    assert expected in slam.ba_last_error
    ba = [w for w in warnings if "bundle adjustment" in w]
    assert len(ba) == slam.ba_failures
    assert ("failed in gtsam" if solver == "gtsam" else "diverged") in ba[0]
    assert "keeps its previous poses" in ba[0]
    # tracking goes on without the adjustment
    assert slam.state == "ok"
    assert np.linalg.norm(slam.trajectory().positions[-1] - seq.poses[24][:3, 3]) < 0.05


def test_a_successful_bundle_adjustment_is_counted(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, SlamConfig(n_features=400), initial_pose=seq.poses[0])
    for i in range(25):
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
    result = slam.global_bundle_adjustment()
    assert result is not None
    assert result.ok
    assert result.error_after <= result.error_before
    assert slam.ba_runs >= 2
    assert slam.ba_failures == 0
