"""SLAM workers: the process worker gives the inline worker's results, errors come back."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.slam.config import SlamConfig
from visnav.slam.worker import InlineWorker, ProcessWorker, SlamWorkerError, make_worker

from .conftest import Sequence

N = 12


def _run(worker: InlineWorker | ProcessWorker, seq: Sequence) -> list[np.ndarray | None]:
    poses: list[np.ndarray | None] = []
    for i in range(N):  # two frames in flight at a time, as the node's latency allows
        worker.submit(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
        if i >= 2:
            out = worker.next_result()
            assert out.result is not None, out.error
            poses.append(out.result.t_wc)
    while worker.in_flight:
        out = worker.next_result()
        assert out.result is not None
        poses.append(out.result.t_wc)
    return poses


def test_process_worker_gives_the_inline_results(short_sequence: Sequence) -> None:
    seq = short_sequence
    cfg = SlamConfig(n_features=400, seed=3)
    inline = InlineWorker(seq.camera, cfg, initial_pose=seq.poses[0])
    proc = ProcessWorker(seq.camera, cfg, initial_pose=seq.poses[0])
    try:
        a, b = _run(inline, seq), _run(proc, seq)
        assert len(a) == len(b) == N
        for pa, pb in zip(a, b, strict=True):
            assert pa is not None
            assert pb is not None
            assert np.array_equal(pa, pb)  # bit for bit: same inputs, same order
        ta, tb = inline.trajectory(), proc.trajectory()
        assert np.array_equal(ta.positions, tb.positions)
        sa, sb = inline.stats(), proc.stats()
        assert (sa.frames, sa.keyframes, sa.ba_runs) == (sb.frames, sb.keyframes, sb.ba_runs)
        assert sb.frames == N
        assert sb.cpu_s > 0
        assert sb.ba_failures == 0
        assert len(proc.map_cloud()) > 100
        # the pose tracks the ground truth (the worker is not just echoing frames)
        last = b[-1]
        assert last is not None
        assert np.linalg.norm(last[:3, 3] - seq.poses[N - 1][:3, 3]) < 0.02
    finally:
        proc.close()
        proc.close()  # idempotent


def test_a_refused_frame_comes_back_as_an_error_and_the_worker_goes_on(
    short_sequence: Sequence,
) -> None:
    seq = short_sequence
    proc = ProcessWorker(seq.camera, SlamConfig(n_features=400))
    try:
        proc.submit(seq.rgb[0][:50], seq.depth[0], int(seq.stamps_ns[0]))  # wrong size
        bad = proc.next_result()
        assert bad.result is None
        assert "image" in bad.error
        assert "160" in bad.error
        proc.submit(seq.rgb[0], seq.depth[0], int(seq.stamps_ns[0]))
        good = proc.next_result()
        assert good.result is not None
        assert good.result.state == "ok"
        with pytest.raises(SlamWorkerError, match="no SLAM frame in flight"):
            proc.next_result()
    finally:
        proc.close()


def test_unknown_worker_kind_is_refused(short_sequence: Sequence) -> None:
    with pytest.raises(SlamWorkerError, match=r"worker 'thread'.*inline, process"):
        make_worker("thread", short_sequence.camera, SlamConfig())
