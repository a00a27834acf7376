"""The report (table, JSON, exit code), the --expect schema, and the catalogue's test coverage."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from visnav.cli.main import main
from visnav.doctor import (
    CATALOGUE,
    Expectations,
    ExpectError,
    Finding,
    Report,
    Severity,
    load_expectations,
)
from visnav.doctor.errors import DoctorError
from visnav.doctor.synthetic import write_bag
from visnav.msgs import ns_to_time

HERE = Path(__file__).parent


def test_every_check_has_a_fault_injection_test() -> None:
    sources = "\n".join(p.read_text() for p in HERE.glob("test_*.py") if p.name != "test_report.py")
    used = set(re.findall(r'"([a-z_]+\.[a-z_]+)"', sources))
    missing = sorted(set(CATALOGUE) - used)
    assert not missing, f"checks without a test: {missing}"


def test_finding_refuses_unknown_check() -> None:
    with pytest.raises(DoctorError, match="not in the doctor catalogue"):
        Finding(Severity.ERROR, "tf.nonsense", "x")


def test_report_orders_and_formats() -> None:
    findings = [
        Finding(Severity.INFO, "topics.no_subscriber", "info one", {"topics": ["/a"]}, "nothing"),
        Finding(Severity.ERROR, "tf.cycle", "a cycle", {"cycle": ("a", "b")}, "fix it", "a"),
        Finding(Severity.WARNING, "rates.gap", "a gap", {"gap_s": 1.23456789}, "look", "/x"),
        Finding(Severity.ERROR, "topics.qos_incompatible", "qos", {}, "make it match", "/y"),
    ]
    report = Report.build(findings, source="test", summary={"topics": 2})
    assert [f.check_id for f in report.findings] == [
        "topics.qos_incompatible",
        "tf.cycle",
        "rates.gap",
        "topics.no_subscriber",
    ]
    assert report.has_errors
    text = report.format()
    assert text.index("ERRORS (2)") < text.index("WARNINGS (1)") < text.index("INFOS (1)")
    assert 'evidence: cycle=["a", "b"]' in text
    assert "fix: fix it" in text
    assert "INFOS" not in report.format(show_info=False)
    data = json.loads(report.to_json())
    assert data["counts"] == {"error": 2, "warning": 1, "info": 1}
    assert data["findings"][2]["evidence"] == {"gap_s": 1.234568}
    assert not Report.build([]).has_errors
    assert "no findings" in Report.build([]).format()


def test_evidence_is_json_ready() -> None:
    import numpy as np

    f = Finding(
        Severity.INFO, "rates.gap", "t", {"a": np.float32(1.5), "b": np.arange(3), "c": {2}}
    )
    assert json.dumps(f.to_dict())
    assert f.evidence == {"a": 1.5, "b": [0, 1, 2], "c": [2]}


def test_expect_file(tmp_path: Path) -> None:
    path = tmp_path / "expect.yaml"
    path.write_text(
        "fixed_frame: odom\n"
        "use_sim_time: true\n"
        "topics:\n"
        "  /camera/image_raw: {type: sensor_msgs/msg/Image, rate: 30, encoding: rgb8}\n"
        "  /camera/camera_info: {hfov: 1.396}\n"
        "  /depth/image: {depth_unit: mm, clip_far: 8}\n"
        "  /scan:\n"
        "tf_chains:\n"
        "  - [odom, camera_optical_frame]\n"
        "planner: {horizon: 7.5, inputs: [/points], base_frame: base_link}\n"
    )
    exp = load_expectations(path)
    assert exp.fixed_frame == "odom"
    assert exp.use_sim_time is True
    assert exp.topics["/camera/image_raw"].rate == 30.0
    assert exp.topics["/depth/image"].depth_unit == "mm"
    assert exp.topics["/scan"].type is None
    assert exp.tf_chains == (("odom", "camera_optical_frame"),)
    assert exp.planner is not None
    assert exp.planner.horizon == 7.5
    assert exp.planner.inputs == ("/points",)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"topic": {}}, "unknown key 'topic': expected one of topics"),
        ({"topics": {"/a": {"rate": "fast"}}}, r"topics./a.rate is 'fast': expected a number"),
        ({"topics": {"/a": {"hz": 3}}}, r"unknown key 'topics./a.hz'"),
        ({"topics": {"a": {}}}, "fully qualified topic name"),
        ({"topics": {"/d": {"depth_unit": "cm"}}}, "'m' \\(32FC1 metres\\) or 'mm'"),
        ({"topics": {"/c": {"hfov": 80}}}, r"radians in \(0, pi\)"),
        ({"tf_chains": [["map"]]}, r"tf_chains\[0\] is \['map'\]: expected a pair"),
        ({"fixed_frame": "/map"}, "without a leading '/'"),
        ({"planner": {"horizon": -1}}, "expected a finite number > 0"),
    ],
)
def test_expect_errors_name_key_and_value(data: Any, match: str) -> None:
    with pytest.raises(ExpectError, match=match):
        Expectations.from_dict(data, source="e.yaml")


def test_expect_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ExpectError, match="the --expect file does not exist"):
        load_expectations(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("topics: [\n")
    with pytest.raises(ExpectError, match="the --expect file does not parse as YAML"):
        load_expectations(bad)


def test_cli_on_bags(dr: Any, clean_events: Any, tmp_path: Path, capsys: Any) -> None:
    clean = write_bag(clean_events, tmp_path / "clean")
    assert main(["doctor", "--bag", str(clean), "--fixed-frame", "odom"]) == 0
    assert "no findings" in capsys.readouterr().out

    def zero(m: Any, i: int) -> Any:
        m.header.stamp = ns_to_time(0)
        return m

    faulty = write_bag(dr.mutate(clean_events, "/camera/camera_info", zero), tmp_path / "faulty")
    expect = tmp_path / "expect.yaml"
    expect.write_text("topics:\n  /scan: {}\n")
    code = main(["doctor", "--bag", str(faulty), "--expect", str(expect), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1
    checks = {f["check"] for f in out["findings"]}
    assert {"time.zero_stamp", "camera_info.stamp_mismatch", "topics.expected_missing"} <= checks
    assert main(["doctor", "--bag", str(faulty), "--duration", "1.0", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["summary"]["duration_s"] <= 1.0


def test_cli_errors(tmp_path: Path, capsys: Any) -> None:
    assert main(["doctor", "--bag", str(tmp_path / "nope")]) == 1
    assert "error:" in capsys.readouterr().err
    assert main(["doctor", "--bag", str(tmp_path), "--duration", "0"]) == 1
