"""``visnav run --record-images / --raw-images``: the flags reach run_scenario; the summary line."""

from __future__ import annotations

import argparse
from typing import Any

import pytest

from visnav.cli import run as run_cli
from visnav.scenarios.runner import format_summary


def _kwargs(monkeypatch: pytest.MonkeyPatch, *argv: str) -> dict[str, Any]:
    parser = argparse.ArgumentParser()
    run_cli.add_arguments(parser)
    args = parser.parse_args(["car", *argv])
    seen: dict[str, Any] = {}

    def fake_run(name: str, **kwargs: Any) -> dict[str, Any]:
        seen.update(kwargs, name=name)
        return {}

    monkeypatch.setattr(run_cli, "run_scenario", fake_run)
    run_cli._run(args, interrupt=None)  # type: ignore[arg-type]
    return seen


@pytest.mark.parametrize(
    ("argv", "record_images", "raw_images"),
    [
        ((), False, False),
        (("--record-images",), True, False),
        (("--raw-images",), True, True),  # implies --record-images
        (("--record-images", "--raw-images"), True, True),
    ],
)
def test_image_flags(
    monkeypatch: pytest.MonkeyPatch, argv: tuple[str, ...], record_images: bool, raw_images: bool
) -> None:
    kwargs = _kwargs(monkeypatch, *argv)
    assert (kwargs["record_images"], kwargs["raw_images"]) == (record_images, raw_images)


def test_summary_prints_bag_size_per_simulated_second() -> None:
    summary = {
        "scenario": "car",
        "seed": 0,
        "sim_duration_s": 3.0,
        "wall_duration_s": 30.0,
        "real_time_factor": 0.1,
        "bag": "runs/x/bag",
        "bag_bytes": 16_340_000,
        "bag_mb_per_sim_s": 5.447,
        "bag_images": "compressed",
        "topics": {},
    }
    text = format_summary(summary)
    assert "bag runs/x/bag  (16.3 MB, 5.45 MB per simulated second, images compressed)" in text
    summary.update(bag_images="none")
    assert "(16.3 MB, 5.45 MB per simulated second)" in format_summary(summary)
