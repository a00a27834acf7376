"""Frames reach the SLAM worker process through shared memory (pickled when they do not fit)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest

from visnav.slam.config import SlamConfig
from visnav.slam.worker import FrameSlots, ProcessWorker

from .conftest import Sequence


def test_frame_slots_round_trip() -> None:
    slots = FrameSlots(64 * 48 * 3 + 64 + 64 * 48 * 4, 2)
    try:
        rng = np.random.default_rng(0)
        image = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
        depth = rng.random((48, 64), dtype=np.float32)
        layouts = slots.put(1, (image, depth[::-1]))  # any layout: a reversed view too
        assert layouts is not None
        again = FrameSlots(slots.slot_bytes, 2, fd=os.dup(slots.fd))  # the worker side
        got_image, got_depth = again.get(layouts[0]), again.get(layouts[1])
        np.testing.assert_array_equal(got_image, image)
        np.testing.assert_array_equal(got_depth, depth[::-1])
        assert got_depth.dtype == np.float32
        assert slots.put(0, (image, depth, depth)) is None  # more than a slot holds
        got_image[0, 0] = 7  # a copy: the slot keeps the frame
        assert again.get(layouts[0])[0, 0, 0] == image[0, 0, 0]
        again.close()
    finally:
        slots.close()
        slots.close()  # idempotent


def test_frames_travel_in_slots_and_odd_ones_pickled(
    short_sequence: Sequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    seq = short_sequence
    proc = ProcessWorker(seq.camera, SlamConfig(n_features=400, seed=3), initial_pose=seq.poses[0])
    sent: list[str] = []
    real_send = proc._conn.send

    def send(msg: Any) -> None:
        sent.append(msg[0])
        real_send(msg)

    monkeypatch.setattr(proc._conn, "send", send)
    try:
        assert proc._slots is not None
        n = proc._slots.count + 2  # more frames in flight than slots: the rest are pickled
        for i in range(n):
            proc.submit(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
        assert sent == ["track_slot"] * proc._slots.count + ["track", "track"]
        assert proc._slots.free == []
        results = [proc.next_result() for _ in range(n)]
        assert all(r.result is not None and r.result.state == "ok" for r in results)
        assert len(proc._slots.free) == proc._slots.count  # every slot back
        big = np.zeros((seq.rgb[0].shape[0] * 2, *seq.rgb[0].shape[1:]), dtype=np.uint8)
        proc.submit(big, seq.depth[0], int(seq.stamps_ns[n]))  # larger than a slot: pickled
        assert sent[-1] == "track"
        bad = proc.next_result()
        assert bad.result is None
        assert "image" in bad.error
        last = results[-1].result
        assert last is not None
        assert last.t_wc is not None
        assert np.linalg.norm(last.t_wc[:3, 3] - seq.poses[n - 1][:3, 3]) < 0.02
    finally:
        proc.close()
