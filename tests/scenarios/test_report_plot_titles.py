"""The sweep report's plot titles fit in their figures (a one-setting sweep cut them)."""

from __future__ import annotations

from typing import Any

import pytest

from visnav.scenarios import report_plots


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """The figures the plot functions save, kept for inspection."""
    kept: list[Any] = []
    save = report_plots.figure_png

    def keep(fig: Any) -> bytes:
        kept.append(fig)
        return save(fig)

    monkeypatch.setattr(report_plots, "figure_png", keep)
    return kept


def title_fits(fig: Any) -> bool:
    [ax] = fig.axes
    box = ax.title.get_window_extent()
    return bool(box.x0 >= 0 and box.x1 <= fig.bbox.width and box.y1 <= fig.bbox.height)


@pytest.mark.parametrize("settings", [1, 2, 5])
def test_success_title_is_whole(figures: list[Any], settings: int) -> None:
    labels = [f"slam={i % 2 == 0},seed_offset={i}" for i in range(settings)]
    png = report_plots.success_png(labels, [0.5] * settings, [(0.2, 0.8)] * settings)
    assert png.startswith(b"\x89PNG")
    [fig] = figures
    assert title_fits(fig)
    # Every word is there: wrapped, never cut.
    title = fig.axes[0].get_title()
    assert " ".join(title.split()) == "success per setting (95 % Wilson interval)"


def test_distribution_title_is_whole(figures: list[Any]) -> None:
    text = "localization RMSE over the whole run, aligned (m)"
    report_plots.distribution_png(text, "m", ["default"], [[0.02, 0.03, 0.05]])
    [fig] = figures
    assert title_fits(fig)
    assert " ".join(fig.axes[0].get_title().split()) == text
