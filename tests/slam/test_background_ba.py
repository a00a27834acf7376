"""Global bundle adjustment in a helper process, merged at a fixed frame (issue 14)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from visnav.slam import SlamConfig, SlamInputError, SlamSystem, Trajectory, ate
from visnav.slam.background_ba import BackgroundGlobalBa, merge_global_ba
from visnav.slam.geometry import inverse, transform
from visnav.slam.optimizer import BaProblem, BaSolution, ba_problem

from .conftest import Sequence, make_sequence

CONFIG = SlamConfig(
    n_features=400, vocabulary_keyframes=6, loop_min_inliers=30, final_global_ba=False
)
DELAY = 6


def _gt(seq: Sequence) -> Trajectory:
    return Trajectory.from_matrices(seq.stamps_s, seq.poses)


def _run(
    seq: Sequence, config: SlamConfig, *, close: bool = True
) -> tuple[SlamSystem, list[tuple[int, int]]]:
    """Track every frame; per frame: (loop closed on it, a background BA pending after it)."""
    slam = SlamSystem(seq.camera, config, initial_pose=seq.poses[0])
    states = []
    try:
        for rgb, depth, t in zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True):
            res = slam.track(rgb, depth, int(t))
            bg = slam.global_ba.background
            states.append((int(res.loop), int(bg is not None and bg.pending)))
    finally:
        if close:
            slam.global_ba.close()
    return slam, states


def test_a_loops_adjustment_is_merged_exactly_delay_frames_later(
    loop_sequence: Sequence,
) -> None:
    slam, states = _run(loop_sequence, dataclasses.replace(CONFIG, global_ba_delay=DELAY))
    assert slam.loops, "the revisit of the start was not detected"
    loops = [i for i, (loop, _) in enumerate(states) if loop]
    first = loops[0]
    assert [p for _, p in states[first : first + DELAY]] == [1] * DELAY
    if len(loops) == 1 or loops[1] > first + DELAY:  # not superseded by the next loop
        assert states[first + DELAY][1] == 0  # merged before that frame was tracked
    assert slam.ba_failures == 0
    assert ate(slam.trajectory(), _gt(loop_sequence)).rmse < 0.02


def test_the_background_adjustment_keeps_runs_identical(loop_sequence: Sequence) -> None:
    cfg = dataclasses.replace(CONFIG, global_ba_delay=DELAY)
    a, _ = _run(loop_sequence, cfg)
    b, _ = _run(loop_sequence, cfg)
    ta, tb = a.trajectory(), b.trajectory()
    np.testing.assert_array_equal(ta.positions, tb.positions)
    np.testing.assert_array_equal(ta.quaternions, tb.quaternions)


def test_background_and_inline_adjustment_are_as_accurate(loop_sequence: Sequence) -> None:
    gt = _gt(loop_sequence)
    inline, _ = _run(loop_sequence, CONFIG)
    background, _ = _run(loop_sequence, dataclasses.replace(CONFIG, global_ba_delay=DELAY))
    e_in = ate(inline.trajectory(), gt).rmse
    e_bg = ate(background.trajectory(), gt).rmse
    assert e_bg < max(1.5 * e_in, 0.01), (e_bg, e_in)


def test_merge_moves_what_came_after_the_snapshot_with_its_parent(
    loop_sequence: Sequence,
) -> None:
    """A solution that moves the snapshot rigidly moves the newer keyframes and points too."""
    slam = SlamSystem(loop_sequence.camera, CONFIG, initial_pose=loop_sequence.poses[0])
    frames = list(zip(loop_sequence.rgb, loop_sequence.depth, loop_sequence.stamps_ns, strict=True))
    for rgb, depth, t in frames[:60]:
        slam.track(rgb, depth, int(t))
    m = slam.map
    ids = [kf.id for kf in m.keyframes if not kf.bad]
    problem = ba_problem(m, ids, fixed_ids=ids[:1], min_observations=2)
    assert isinstance(problem, BaProblem)
    n_kf, n_pts = len(m.keyframes), m.n_points
    for rgb, depth, t in frames[60:90]:  # the map goes on: new keyframes and points
        slam.track(rgb, depth, int(t))
    assert len(m.keyframes) > n_kf
    assert m.n_points > n_pts
    g = np.eye(4)  # the world moved by 10 cm and 2 degrees about z
    c, s = np.cos(np.radians(2.0)), np.sin(np.radians(2.0))
    g[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    g[:3, 3] = [0.1, -0.05, 0.02]
    moved_t = np.stack([t @ inverse(g) for t in problem.t_cw])
    moved_t[problem.fixed] = problem.t_cw[problem.fixed]
    solution = BaSolution(moved_t, transform(g, problem.positions), 1.0, 0.5)
    before_t = {kf.id: kf.t_cw.copy() for kf in m.keyframes}
    before_p = m.positions[: m.n_points].copy()
    refs = m.ref_kf[: m.n_points].copy()
    result = merge_global_ba(m, slam.camera, problem, solution, n_kf)
    assert result.ok
    snap = {int(k): i for i, k in enumerate(problem.keyframes)}
    expected: dict[int, np.ndarray] = {}
    for kf in m.keyframes:
        if kf.bad:  # culled: left alone
            expected[kf.id] = before_t[kf.id]
        elif kf.id in snap:
            i = snap[kf.id]
            want = problem.t_cw[i] if problem.fixed[i] else problem.t_cw[i] @ inverse(g)
        else:  # newer: its pose relative to its parent kept
            parent = kf.parent
            want = before_t[kf.id] @ inverse(before_t[parent]) @ expected[parent]
        expected[kf.id] = want
        np.testing.assert_allclose(kf.t_cw, want, atol=1e-9)
    in_snapshot = np.zeros(m.n_points, dtype=bool)
    in_snapshot[problem.points] = True
    for p in m.good_points().tolist():
        if in_snapshot[p]:
            want_p = transform(g, problem.positions[np.searchsorted(problem.points, p)][None])[0]
        else:  # moved with its reference keyframe's correction
            k = int(refs[p])
            corr = inverse(expected[k]) @ before_t[k]
            want_p = transform(corr, before_p[p][None])[0]
        np.testing.assert_allclose(m.positions[p], want_p, atol=1e-9)


@pytest.mark.parametrize("delay", [-1, 1.5, True])
def test_a_bad_delay_is_refused_naming_the_field(delay: object) -> None:
    with pytest.raises(SlamInputError, match="global_ba_delay"):
        SlamConfig(global_ba_delay=delay)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def two_loops() -> Sequence:
    """Twice round the room and a bit (280 frames): the start is revisited twice."""
    return make_sequence(280, turns=2.2)


def test_a_newer_loop_merges_the_pending_adjustment_before_its_correction(
    two_loops: Sequence,
) -> None:
    cfg = dataclasses.replace(CONFIG, global_ba_delay=10_000)  # never due by itself
    slam, states = _run(two_loops, cfg, close=False)
    bg = slam.global_ba.background
    assert bg is not None
    n_loops = sum(loop for loop, _ in states)
    assert n_loops >= 2, "the sequence should close more than one loop"
    assert bg.superseded == 0  # each was merged when the next loop came
    assert states[-1][1] == 1  # the last loop's is still pending
    runs = slam.ba_runs
    try:
        slam.global_bundle_adjustment()  # the end of a run: the pending one merged first
    finally:
        slam.global_ba.close()
    assert slam.ba_runs == runs + 2
    assert slam.ba_failures == 0


def test_a_second_start_supersedes_the_first(loop_sequence: Sequence) -> None:
    slam = SlamSystem(loop_sequence.camera, CONFIG, initial_pose=loop_sequence.poses[0])
    for rgb, depth, t in list(
        zip(loop_sequence.rgb, loop_sequence.depth, loop_sequence.stamps_ns, strict=True)
    )[:60]:
        slam.track(rgb, depth, int(t))
    m = slam.map
    ids = [kf.id for kf in m.keyframes if not kf.bad]
    problem = ba_problem(m, ids, fixed_ids=ids[:1], min_observations=2)
    assert isinstance(problem, BaProblem)
    bg = BackgroundGlobalBa(5, slam.camera, slam.extractor.inv_level_sigma2, 15)
    try:
        bg.start(m, problem, 60)
        bg.start(m, problem, 61)  # the first result would be stale: dropped (or its solve killed)
        assert bg.superseded == 1
        assert not bg.due(65)
        assert bg.due(66)
        result = bg.merge(m)
    finally:
        bg.close()
    assert result.ok
    assert not bg.pending


def test_a_helper_that_dies_is_reported_and_the_map_kept(loop_sequence: Sequence) -> None:
    slam = SlamSystem(
        loop_sequence.camera,
        dataclasses.replace(CONFIG, global_ba_delay=DELAY),
        initial_pose=loop_sequence.poses[0],
    )
    frames = zip(loop_sequence.rgb, loop_sequence.depth, loop_sequence.stamps_ns, strict=True)
    try:
        for rgb, depth, t in frames:
            res = slam.track(rgb, depth, int(t))
            if res.loop:
                break
        bg = slam.global_ba.background
        assert bg is not None
        assert bg.pending
        bg._proc.kill()  # type: ignore[union-attr]  # the helper crashes (e.g. out of memory)
        before = {kf.id: kf.t_cw.copy() for kf in slam.map.keyframes}
        result = bg.merge(slam.map)
    finally:
        slam.global_ba.close()
    assert not result.ok
    assert "helper process" in result.error
    for kf in slam.map.keyframes:
        np.testing.assert_array_equal(kf.t_cw, before[kf.id])
