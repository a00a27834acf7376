"""A TUM rgb.txt out of time order is processed sorted by stamp, with a warning."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from visnav.slam import TumSequence


def _lists(folder: Path, rgb: list[float], depth: list[float]) -> Path:
    folder.mkdir()
    (folder / "rgb.txt").write_text("# rgb\n" + "".join(f"{s:.6f} rgb/{s:.6f}.png\n" for s in rgb))
    (folder / "depth.txt").write_text("".join(f"{s:.6f} d/{s:.6f}.png\n" for s in depth))
    return folder


def test_reversed_rgb_txt_is_sorted_with_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    stamps = [1.0, 1.1, 1.2, 1.3]
    folder = _lists(tmp_path / "seq", list(reversed(stamps)), stamps)
    with caplog.at_level(logging.WARNING):
        seq = TumSequence(folder)
    assert [f.stamp for f in seq.frames] == stamps
    assert [f.rgb_path.name for f in seq.frames] == [f"{s:.6f}.png" for s in stamps]
    assert [f.depth_stamp for f in seq.frames] == stamps
    assert "rgb.txt is not in time order (entry 2, stamp 1.200000, comes after 1.300000)" in (
        caplog.text
    )
    assert "sorted by stamp" in caplog.text


def test_sorted_rgb_txt_gives_no_warning(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    stamps = [1.0, 1.1, 1.2]
    folder = _lists(tmp_path / "seq", stamps, list(reversed(stamps)))  # depth order is free
    with caplog.at_level(logging.WARNING):
        seq = TumSequence(folder)
    assert [f.stamp for f in seq.frames] == stamps
    assert "time order" not in caplog.text
