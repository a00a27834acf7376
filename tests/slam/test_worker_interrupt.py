"""A Ctrl-C while the SLAM node waits for its worker process leaves no wrong answer behind.

The trace users saw at shutdown after Ctrl-C, ``AttributeError: 'WorkerResult' object has
no attribute 'npz'``: the interrupted wait had counted its frame as taken, so saving the map
read that frame's late result as the save's answer. Now the frame stays in flight and the
worker refuses further reads; the map's save reports the interruption instead.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from visnav.slam.config import SlamConfig
from visnav.slam.worker import ProcessWorker, SlamWorkerError, save_at_shutdown

from .conftest import Sequence


def test_an_interrupted_wait_is_reported_not_misread(
    short_sequence: Sequence, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seq = short_sequence
    proc = ProcessWorker(seq.camera, SlamConfig(n_features=400))
    try:
        proc.submit(seq.rgb[0], seq.depth[0], int(seq.stamps_ns[0]))

        def ctrl_c() -> object:
            raise KeyboardInterrupt

        monkeypatch.setattr(proc._conn, "recv", ctrl_c)
        with pytest.raises(KeyboardInterrupt):
            proc.next_result()
        monkeypatch.undo()
        assert proc.in_flight == 1  # not taken: its answer is still on its way
        level, text = save_at_shutdown(proc, str(tmp_path / "slam_map.npz"))
        assert level == "error"
        assert "interrupted while waiting for tracking" in text
        with pytest.raises(SlamWorkerError, match="unusable"):
            proc.stats()
    finally:
        proc.close()
    assert not (tmp_path / "slam_map.npz").exists()
