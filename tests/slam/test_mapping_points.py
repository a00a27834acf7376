"""New map points of a keyframe: close depths first, far ones only while points are few."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.slam.features import Frame
from visnav.slam.mapping import create_points
from visnav.slam.slam_map import Keyframe, SlamMap


def _keyframe_with(depths: np.ndarray, tracked: np.ndarray) -> tuple[SlamMap, Keyframe]:
    n = len(depths)
    uv = np.column_stack([np.arange(n, dtype=np.float64), np.zeros(n)])
    frame = Frame(
        stamp_ns=0,
        uv=uv,
        octave=np.zeros(n, dtype=np.int64),
        descriptors=np.zeros((n, 32), dtype=np.uint8),
        depth=depths.astype(np.float64),
        u_right=uv[:, 0] - 40.0 / depths,
        points_c=np.column_stack([np.zeros(n), np.zeros(n), depths]),
        inv_sigma2=np.ones(n),
    )
    m = SlamMap()
    kf = m.add_keyframe(frame, np.eye(4), parent=-1)
    frame.map_points[tracked] = 0  # stands for "already has a map point"
    return m, kf


def _orb_slam2(depths: np.ndarray, tracked: np.ndarray, close: float, min_points: int) -> set[int]:
    """Tracking::CreateNewKeyFrame's loop, written out keypoint by keypoint."""
    order = sorted((float(d), i) for i, d in enumerate(depths) if np.isfinite(d))
    made = set()
    for counted, (d, i) in enumerate(order, start=1):
        if not tracked[i]:
            made.add(i)
        if d > close and counted > min_points:
            break
    return made


def _made(kf: Keyframe, tracked: np.ndarray) -> set[int]:
    return set(np.flatnonzero((kf.frame.map_points >= 0) & ~tracked).tolist())


def test_every_depth_makes_a_point_without_a_close_depth() -> None:
    """The first keyframe (no close_depth) keeps every depth, as ORB-SLAM2's initialisation."""
    depths = np.array([0.5, 7.0, np.nan, 3.5])
    m, kf = _keyframe_with(depths, np.zeros(4, dtype=bool))
    assert len(create_points(m, kf)) == 3


def test_far_points_are_made_only_while_the_keyframe_has_few() -> None:
    rng = np.random.default_rng(0)
    far = rng.uniform(3.1, 8.0, 50)
    close = rng.uniform(0.5, 2.9, 150)
    depths = np.concatenate([far, close])
    tracked = np.zeros(200, dtype=bool)
    tracked[50:] = True  # every close keypoint already has a point
    m, kf = _keyframe_with(depths, tracked)
    created = create_points(m, kf, close_depth=3.0)
    # 150 close keypoints counted before any far one: only the nearest far one is taken
    assert len(created) == 1
    assert _made(kf, tracked) == {int(np.argmin(far))}
    # few close points: far ones are made, nearest first, until the count passes min_points
    depths2 = np.concatenate([far, close[:20]])
    none = np.zeros(70, dtype=bool)
    m2, kf2 = _keyframe_with(depths2, none)
    assert len(create_points(m2, kf2, close_depth=3.0, min_points=30)) == 31
    far_made = sorted(kf2.frame.depth[kf2.frame.map_points >= 0])[20:]
    assert far_made == sorted(far)[:11]


@settings(max_examples=80, deadline=None)
@given(
    depths=st.lists(st.floats(0.2, 9.0) | st.just(float("nan")), min_size=1, max_size=300),
    close=st.floats(0.5, 5.0),
    min_points=st.integers(0, 120),
    every=st.integers(1, 5),
)
def test_the_points_made_are_orb_slam2s(
    depths: list[float], close: float, min_points: int, every: int
) -> None:
    arr = np.array(depths)
    tracked = np.zeros(len(arr), dtype=bool)
    tracked[::every] = every > 1
    m, kf = _keyframe_with(arr, tracked)
    create_points(m, kf, close_depth=close, min_points=min_points)
    assert _made(kf, tracked) == _orb_slam2(arr, tracked, close, min_points)


def test_the_rule_is_off_by_default_and_a_bad_limit_is_refused() -> None:
    import pytest

    from visnav.slam.config import SlamConfig
    from visnav.slam.errors import SlamInputError

    assert SlamConfig().far_point_limit is None
    assert SlamConfig(far_point_limit=100).far_point_limit == 100
    for bad in (-1, 2.5, True):
        with pytest.raises(SlamInputError, match="far_point_limit"):
            SlamConfig(far_point_limit=bad)  # type: ignore[arg-type]
