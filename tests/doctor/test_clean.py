"""Clean inputs: doctor reports no error on a healthy car-like stream (observation, bag, live)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from visnav.doctor import doctor_bag
from visnav.doctor.synthetic import write_bag


def test_clean_synthetic_stream_has_no_finding(dr: Any, clean_events: Any) -> None:
    report = dr.run(clean_events, fixed_frame="odom")
    assert not report.findings, report.format()


def test_clean_synthetic_bag_has_no_error(dr: Any, clean_events: Any, tmp_path: Path) -> None:
    bag = write_bag(clean_events, tmp_path / "clean")
    report = doctor_bag(bag, fixed_frame="odom")
    assert not report.findings, report.format()
    assert report.summary["messages"] == len(clean_events)
    assert "topics.qos_incompatible" in report.skipped


def test_header_fast_path_matches_decoding(clean_events: Any) -> None:
    from visnav.doctor.bag_source import read_header
    from visnav.doctor.builder import HEAVY_TYPES, header_of
    from visnav.msgs import serialize, typestore

    heavy = [e for e in clean_events if e.type_name in HEAVY_TYPES][:10]
    assert heavy
    for ev in heavy:
        cdr = serialize(ev.msg)
        assert read_header(cdr) == header_of(ev.msg)
        ros1 = typestore().cdr_to_ros1(cdr, ev.type_name)
        assert read_header(ros1, ros1=True) == header_of(ev.msg)
    assert read_header(b"\x07\x07garbage") is None


def test_clean_ros1_bag_has_no_finding(clean_events: Any, tmp_path: Path) -> None:
    bag = write_bag(clean_events, tmp_path / "clean", fmt="ros1")
    report = doctor_bag(bag, fixed_frame="odom")
    assert not report.findings, report.format()
