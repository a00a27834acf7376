"""ATE / RPE: agreement with evo on the same TUM files, alignment and association."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.slam.errors import AssociationError, EvaluationError, TrajectoryFormatError
from visnav.slam.evaluation import associate, ate, rpe, umeyama
from visnav.slam.trajectory import Trajectory, quaternions_to_matrices, read_tum, write_tum

evo_sync = pytest.importorskip("evo.core.sync")
from evo import main_ape, main_rpe  # noqa: E402
from evo.core import metrics  # noqa: E402
from evo.tools import file_interface  # noqa: E402


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return quaternions_to_matrices(q / np.linalg.norm(q))[0]


def _ground_truth(n: int = 240, rate: float = 30.0) -> Trajectory:
    t = 100.0 + np.arange(n) / rate
    a = np.linspace(0.0, 2.4 * np.pi, n)
    mats = np.zeros((n, 4, 4))
    for i, ai in enumerate(a):
        c, s = np.cos(ai + 0.3), np.sin(ai + 0.3)
        mats[i, :3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        mats[i, :3, 3] = [2.0 * np.cos(ai), 1.5 * np.sin(ai), 0.2 * np.sin(3 * ai)]
        mats[i, 3, 3] = 1.0
    return Trajectory.from_matrices(t, mats)


def _estimate(gt: Trajectory, seed: int) -> Trajectory:
    """GT in another frame and scale, with noise, jittered stamps and missing poses."""
    rng = np.random.default_rng(seed)
    r = _random_rotation(rng)
    sim = np.eye(4)
    sim[:3, :3] = r
    sim[:3, 3] = rng.normal(size=3)
    keep = np.sort(rng.choice(len(gt), int(0.8 * len(gt)), replace=False))
    mats = gt.matrices()[keep]
    mats[:, :3, 3] *= 1.1
    mats = np.einsum("ij,njk->nik", sim, mats)
    mats[:, :3, 3] += rng.normal(scale=0.02, size=(len(keep), 3))
    for m in mats:
        m[:3, :3] = m[:3, :3] @ _random_rotation(rng) ** 0 @ _small_rotation(rng)
    stamps = gt.stamps[keep] + rng.uniform(-0.004, 0.004, len(keep))
    extra = gt.stamps[-1] + 1.0 + np.arange(5) / 30.0  # no partner in GT
    mats = np.concatenate([mats, np.repeat(mats[-1:], 5, axis=0)])
    return Trajectory.from_matrices(np.concatenate([stamps, extra]), mats)


def _small_rotation(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(scale=0.01, size=3)
    q = np.array([*(v / 2), 1.0])
    return quaternions_to_matrices(q)[0]


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    gt = _ground_truth()
    est = _estimate(gt, seed=3)
    return write_tum(tmp_path / "est.txt", est), write_tum(tmp_path / "gt.txt", gt)


def _evo_pair(est: Path, gt: Path) -> tuple[object, object]:
    ref = file_interface.read_tum_trajectory_file(str(gt))
    e = file_interface.read_tum_trajectory_file(str(est))
    return evo_sync.associate_trajectories(ref, e, max_diff=0.01, offset_2=0.0)


_RELATIONS = {
    "trans_part": metrics.PoseRelation.translation_part,
    "angle_deg": metrics.PoseRelation.rotation_angle_deg,
    "angle_rad": metrics.PoseRelation.rotation_angle_rad,
    "full": metrics.PoseRelation.full_transformation,
}


def _assert_same_stats(ours: dict[str, float], theirs: dict[str, float]) -> None:
    for key in ("rmse", "mean", "median", "std", "min", "max", "sse"):
        assert ours[key] == pytest.approx(float(theirs[key]), abs=1e-6, rel=1e-9), key


@pytest.mark.parametrize("relation", list(_RELATIONS))
@pytest.mark.parametrize(
    ("align", "scale"), [(False, False), (True, False), (True, True), (False, True)]
)
def test_ate_agrees_with_evo_ape(
    files: tuple[Path, Path], relation: str, align: bool, scale: bool
) -> None:
    est_file, gt_file = files
    ours = ate(
        read_tum(est_file), read_tum(gt_file), align=align, scale=scale, pose_relation=relation
    )  # type: ignore[arg-type]
    ref, est = _evo_pair(est_file, gt_file)
    result = main_ape.ape(
        copy.deepcopy(ref),
        copy.deepcopy(est),
        _RELATIONS[relation],
        align=align,
        correct_scale=scale,
    )
    assert len(ours.errors) == len(result.np_arrays["error_array"])
    np.testing.assert_allclose(ours.errors, result.np_arrays["error_array"], atol=1e-6)
    _assert_same_stats(ours.stats(), result.stats)


@pytest.mark.parametrize(
    ("delta", "unit", "all_pairs"),
    [
        (1, "frames", False),
        (5, "frames", False),
        (3, "frames", True),
        (0.5, "meters", False),
        (1.0, "meters", True),
    ],
)
@pytest.mark.parametrize("relation", ["trans_part", "angle_deg"])
@pytest.mark.parametrize(("align", "scale"), [(False, False), (True, True)])
def test_rpe_agrees_with_evo_rpe(
    files: tuple[Path, Path],
    delta: float,
    unit: str,
    all_pairs: bool,
    relation: str,
    align: bool,
    scale: bool,
) -> None:
    est_file, gt_file = files
    ours = rpe(
        read_tum(est_file),
        read_tum(gt_file),
        delta=delta,
        delta_unit=unit,
        all_pairs=all_pairs,  # type: ignore[arg-type]
        align=align,
        scale=scale,
        pose_relation=relation,  # type: ignore[arg-type]
    )
    ref, est = _evo_pair(est_file, gt_file)
    result = main_rpe.rpe(
        copy.deepcopy(ref),
        copy.deepcopy(est),
        _RELATIONS[relation],
        delta=delta,
        delta_unit=metrics.Unit.frames if unit == "frames" else metrics.Unit.meters,
        all_pairs=all_pairs,
        align=align,
        correct_scale=scale,
    )
    _assert_same_stats(ours.stats(), result.stats)


def test_cli_eval_prints_the_evo_numbers(
    files: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from visnav.cli.main import main

    est_file, gt_file = files
    assert main(["eval", "ate", str(est_file), str(gt_file), "--align", "--scale", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    ref, est = _evo_pair(est_file, gt_file)
    result = main_ape.ape(
        ref, est, metrics.PoseRelation.translation_part, align=True, correct_scale=True
    )
    assert printed["rmse"] == pytest.approx(result.stats["rmse"], abs=1e-6)
    assert main(["eval", "rpe", str(est_file), str(gt_file), "-d", "2"]) == 0
    assert "RPE w.r.t. trans_part" in capsys.readouterr().out


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.floats(0.2, 5.0))
def test_umeyama_recovers_a_similarity(seed: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(20, 3))
    r = _random_rotation(rng)
    t = rng.normal(size=3)
    y = scale * x @ r.T + t
    al = umeyama(x, y, with_scale=True)
    np.testing.assert_allclose(al.rotation, r, atol=1e-9)
    np.testing.assert_allclose(al.translation, t, atol=1e-8)
    assert al.scale == pytest.approx(scale, rel=1e-9)
    rigid = umeyama(x, x @ r.T + t)
    assert rigid.scale == 1.0
    np.testing.assert_allclose(rigid.rotation, r, atol=1e-9)


def test_umeyama_refuses_degenerate_points() -> None:
    with pytest.raises(EvaluationError, match="degenerate"):
        umeyama(np.ones((5, 3)), np.ones((5, 3)))


def test_timestamps_that_do_not_associate_raise_a_clear_error() -> None:
    gt = _ground_truth(50)
    shifted = Trajectory(gt.stamps + 1000.0, gt.positions, gt.quaternions)
    with pytest.raises(AssociationError, match="no timestamps associate") as info:
        ate(shifted, gt)
    assert "offset" in str(info.value)
    # an offset makes them associate again
    assert ate(shifted, gt, offset=-1000.0).rmse == pytest.approx(0.0, abs=1e-9)


def test_associate_uses_the_nearest_stamp_and_max_diff() -> None:
    i_ref, i_est = associate([0.0, 1.0, 2.0], [0.004, 0.995, 1.5, 2.02])
    assert i_ref.tolist() == [0, 1]
    assert i_est.tolist() == [0, 1]


def test_perfect_estimate_has_zero_error_and_aligned_ate_is_frame_invariant() -> None:
    gt = _ground_truth(60)
    assert ate(gt, gt).rmse == pytest.approx(0.0, abs=1e-12)
    moved = np.einsum("ij,njk->nik", np.diag([1.0, -1.0, -1.0, 1.0]), gt.matrices())
    est = Trajectory.from_matrices(gt.stamps, moved)
    assert ate(est, gt).rmse > 0.5
    assert ate(est, gt, align=True).rmse == pytest.approx(0.0, abs=1e-9)
    assert rpe(est, gt).rmse == pytest.approx(0.0, abs=1e-9)


def test_rpe_rejects_bad_delta() -> None:
    gt = _ground_truth(10)
    with pytest.raises(EvaluationError, match="delta"):
        rpe(gt, gt, delta=1.5)
    with pytest.raises(EvaluationError, match="no pose pair"):
        rpe(gt, gt, delta=50)


def test_read_tum_reports_the_bad_line(tmp_path: Path) -> None:
    p = tmp_path / "t.txt"
    p.write_text("# comment\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n")
    with pytest.raises(TrajectoryFormatError, match=r"t\.txt:3: 7 values"):
        read_tum(p)
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(TrajectoryFormatError, match="no poses"):
        read_tum(tmp_path / "empty.txt")
    with pytest.raises(TrajectoryFormatError, match="does not exist"):
        read_tum(tmp_path / "missing.txt")


def test_tum_round_trip_keeps_poses(tmp_path: Path) -> None:
    gt = _ground_truth(30)
    back = read_tum(write_tum(tmp_path / "gt.txt", gt))
    np.testing.assert_allclose(back.matrices(), gt.matrices(), atol=1e-8)
    np.testing.assert_allclose(back.stamps, gt.stamps, atol=1e-9)
