"""Findings and the report: severity, check id, title, evidence, fix; text table and JSON.

A :class:`Finding` is one fault with its evidence (topic, field, measured values, as a
JSON-able mapping) and the concrete fix. A :class:`Report` holds the findings of one
run, sorted by severity then check id, and renders them as a table grouped by
severity (:meth:`Report.format`) or as JSON (:meth:`Report.to_json`).
"""

from __future__ import annotations

import enum
import json
import math
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from visnav.doctor.catalogue import CATALOGUE
from visnav.doctor.errors import DoctorError

__all__ = ["Finding", "Report", "Severity"]


class Severity(enum.Enum):
    """How bad a finding is: errors break the data chain, warnings degrade it."""

    ERROR = "error"
    WARNING = "warning"
    INFO = "info"

    @property
    def rank(self) -> int:
        """0 for errors, 1 for warnings, 2 for info (report order)."""
        return {"error": 0, "warning": 1, "info": 2}[self.value]


def _plain(value: Any) -> Any:
    """Return ``value`` as JSON-able data (numpy scalars and arrays, tuples, sets)."""
    if isinstance(value, bool | str) or value is None:
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return round(value, 6) if math.isfinite(value) else str(value)
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        items = sorted(value, key=str) if isinstance(value, set | frozenset) else value
        return [_plain(v) for v in items]
    item = getattr(value, "item", None)
    if callable(item) and getattr(value, "ndim", 1) == 0:
        return _plain(item())
    tolist = getattr(value, "tolist", None)
    if callable(tolist):
        return _plain(tolist())
    return str(value)


@dataclass(frozen=True)
class Finding:
    """One fault doctor found.

    Attributes:
        severity: error, warning or info.
        check_id: the catalogue id (:data:`visnav.doctor.catalogue.CATALOGUE`).
        title: one line naming the fault and its subject.
        evidence: what was measured: topic, field, values (JSON-able).
        fix: the concrete fix.
        subject: the topic, frame or node the finding is about.
    """

    severity: Severity
    check_id: str
    title: str
    evidence: Mapping[str, Any] = field(default_factory=dict)
    fix: str = ""
    subject: str = ""

    def __post_init__(self) -> None:
        if self.check_id not in CATALOGUE:
            msg = f"finding check id {self.check_id!r} is not in the doctor catalogue"
            raise DoctorError(msg)
        object.__setattr__(self, "evidence", _plain(dict(self.evidence)))

    @property
    def category(self) -> str:
        """The check's category (``tf``, ``images``, ...)."""
        return CATALOGUE[self.check_id].category

    def to_dict(self) -> dict[str, Any]:
        """Return the finding as JSON-able data."""
        return {
            "severity": self.severity.value,
            "check": self.check_id,
            "category": self.category,
            "subject": self.subject,
            "title": self.title,
            "evidence": dict(self.evidence),
            "fix": self.fix,
        }


def _evidence_text(evidence: Mapping[str, Any]) -> str:
    parts = []
    for key, value in evidence.items():
        text = json.dumps(value) if isinstance(value, dict | list) else str(value)
        parts.append(f"{key}={text}")
    return ", ".join(parts)


@dataclass(frozen=True)
class Report:
    """The findings of one doctor run.

    Attributes:
        findings: sorted by severity, then check id, then subject.
        source: what was observed (``live graph, domain 0`` or the bag path).
        summary: facts about the input (duration, topics, nodes, messages).
        skipped: checks not run and why (e.g. graph checks on a bag).
    """

    findings: tuple[Finding, ...]
    source: str = ""
    summary: Mapping[str, Any] = field(default_factory=dict)
    skipped: Mapping[str, str] = field(default_factory=dict)

    @classmethod
    def build(
        cls,
        findings: Iterable[Finding],
        *,
        source: str = "",
        summary: Mapping[str, Any] | None = None,
        skipped: Mapping[str, str] | None = None,
    ) -> Report:
        """Sort and de-duplicate ``findings`` into a report."""
        order = {cid: i for i, cid in enumerate(CATALOGUE)}
        unique: dict[tuple[str, str, str], Finding] = {}
        for f in findings:
            unique.setdefault((f.check_id, f.subject, f.title), f)
        ranked = sorted(
            unique.values(), key=lambda f: (f.severity.rank, order[f.check_id], f.subject, f.title)
        )
        return cls(tuple(ranked), source, _plain(dict(summary or {})), dict(skipped or {}))

    @property
    def has_errors(self) -> bool:
        """True when an error-level finding exists (doctor then exits non-zero)."""
        return any(f.severity is Severity.ERROR for f in self.findings)

    def by_severity(self, severity: Severity) -> list[Finding]:
        """The findings of one severity."""
        return [f for f in self.findings if f.severity is severity]

    def find(self, check_id: str, subject: str | None = None) -> list[Finding]:
        """The findings of one check (optionally about one subject)."""
        return [
            f
            for f in self.findings
            if f.check_id == check_id and (subject is None or f.subject == subject)
        ]

    @property
    def check_ids(self) -> set[str]:
        """The ids of every check that produced a finding."""
        return {f.check_id for f in self.findings}

    def to_dict(self) -> dict[str, Any]:
        """Return the report as JSON-able data."""
        counts = {s.value: len(self.by_severity(s)) for s in Severity}
        return {
            "source": self.source,
            "summary": dict(self.summary),
            "counts": counts,
            "findings": [f.to_dict() for f in self.findings],
            "skipped": dict(self.skipped),
        }

    def to_json(self, *, indent: int | None = 2) -> str:
        """Return the report as JSON text."""
        return json.dumps(self.to_dict(), indent=indent)

    def format(self, *, width: int = 100, show_info: bool = True) -> str:
        """Return the report as a table grouped by severity, evidence and fix under each row."""
        lines = [f"visnav doctor: {self.source}"]
        if self.summary:
            lines.append("  " + _evidence_text(self.summary))
        counts = [f"{len(self.by_severity(s))} {s.value}s" for s in Severity]
        lines.append("  " + ", ".join(counts))
        for severity in Severity:
            group = self.by_severity(severity)
            if not group or (severity is Severity.INFO and not show_info):
                continue
            lines.append("")
            lines.append(f"{severity.value.upper()}S ({len(group)})")
            lines.extend(_table(group, width))
        if self.skipped:
            lines.append("")
            lines.append("SKIPPED")
            lines.extend(f"  {cid}: {why}" for cid, why in self.skipped.items())
        if not self.findings:
            lines.append("")
            lines.append("no findings: the data chain looks healthy")
        return "\n".join(lines) + "\n"


def _table(findings: Sequence[Finding], width: int) -> list[str]:
    check_w = max(len("CHECK"), *(len(f.check_id) for f in findings))
    subj_w = min(32, max(len("SUBJECT"), *(len(f.subject) for f in findings)))
    head = f"  {'CHECK':<{check_w}}  {'SUBJECT':<{subj_w}}  FINDING"
    out = [head]
    title_indent = " " * (6 + check_w + subj_w)
    title_w = max(30, width - len(title_indent))
    detail_w = max(40, width - 6)
    for f in findings:
        subject = f.subject if len(f.subject) <= subj_w else "..." + f.subject[-(subj_w - 3) :]
        title = textwrap.wrap(f.title, title_w) or [""]
        out.append(f"  {f.check_id:<{check_w}}  {subject:<{subj_w}}  {title[0]}")
        out.extend(title_indent + t for t in title[1:])
        for label, text in (("evidence", _evidence_text(f.evidence)), ("fix", f.fix)):
            if text:
                wrapped = textwrap.wrap(
                    f"{label}: {text}",
                    detail_w,
                    initial_indent="      ",
                    subsequent_indent="        ",
                    break_on_hyphens=False,
                )
                out.extend(wrapped)
    return out
