"""BENCHMARKS.md has a row for every benchmark in bench/, each with its five columns."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "BENCHMARKS.md"
COLUMNS = ["figure", "reference", "ratio", "command", "date"]


def table_rows(text: str) -> list[list[str]]:
    """The cells of every table row (escaped pipes kept inside their cell)."""
    rows = []
    for line in text.splitlines():
        if line.startswith("|") and not re.fullmatch(r"\|(\s*-+\s*\|)+", line):
            cells = re.split(r"(?<!\\)\|", line.strip())[1:-1]
            rows.append([cell.strip() for cell in cells])
    return rows


def test_every_benchmark_has_a_row() -> None:
    text = PAGE.read_text(encoding="utf-8")
    commands = " ".join(row[3] for row in table_rows(text) if len(row) == len(COLUMNS))
    missing = [
        bench.name
        for bench in sorted((ROOT / "bench").glob("bench_*.py"))
        if f"bench/{bench.name}" not in commands
    ]
    assert not missing, f"no row in BENCHMARKS.md for {missing}: add its current figure"


def test_every_table_has_the_five_columns_and_a_date() -> None:
    rows = table_rows(PAGE.read_text(encoding="utf-8"))
    headers = [row for row in rows if row == COLUMNS]
    assert len(headers) >= 5
    for row in rows:
        assert len(row) == len(COLUMNS), row
        if row != COLUMNS:
            assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", row[4]), row
