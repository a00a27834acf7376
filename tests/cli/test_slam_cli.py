"""``visnav slam --tum DIR --intrinsics ...``: the folder's warnings are said once."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from visnav.cli.main import main


def test_reversed_rgb_txt_is_warned_about_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    folder = tmp_path / "seq"
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    rng = np.random.default_rng(0)
    for i in range(3):
        cv2.imwrite(str(folder / f"rgb/{i}.png"), rng.integers(0, 255, (48, 64, 3), np.uint8))
        cv2.imwrite(str(folder / f"depth/{i}.png"), np.full((48, 64), 5000, np.uint16))
    (folder / "rgb.txt").write_text("".join(f"{i}.0 rgb/{i}.png\n" for i in (2, 1, 0)))
    (folder / "depth.txt").write_text("".join(f"{i}.0 depth/{i}.png\n" for i in range(3)))
    out = tmp_path / "traj.txt"
    with caplog.at_level(logging.WARNING):
        main(["slam", "--tum", str(folder), "--intrinsics", "50,50,32,24", "-o", str(out)])
    said = [r for r in caplog.records if "not in time order" in r.getMessage()]
    assert len(said) == 1, [r.getMessage() for r in said]
    assert "sorted by stamp" in said[0].getMessage()
    assert out.exists()
