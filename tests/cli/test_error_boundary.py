"""The CLI's one error boundary: every repro of issue 13 ends in one line ``error: ...``.

Each test runs ``visnav`` in-process through :func:`visnav.cli.main.main` and checks
the exit code, that stderr is exactly one ``error:`` line (no traceback), and that
the line names the file or option, the value and a fix.
"""

from __future__ import annotations

import argparse
import errno
import struct
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from visnav.cli._errors import describe_error
from visnav.cli.main import main

LATIN1 = "caf\xe9 = 1\n".encode("latin-1")  # not UTF-8: byte 0xe9


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    """Run visnav; return the exit code and the one stderr line (asserted to be one)."""
    code = main(list(argv))
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip() and "[WARNING]" not in line]
    assert code == 1, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return code, lines[0]


def tum_lists(folder: Path, stamps: list[float]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rgb.txt").write_text("".join(f"{s:.6f} rgb/{s:.6f}.png\n" for s in stamps))
    (folder / "depth.txt").write_text("".join(f"{s:.6f} depth/{s:.6f}.png\n" for s in stamps))
    return folder


# --------------------------------------------------------------------------- non-UTF-8 files
def test_eval_ate_non_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "est.txt"
    bad.write_bytes(b"1.0 0 0 0 0 0 0 1\n" + LATIN1)
    good = tmp_path / "gt.txt"
    good.write_text("1.0 0 0 0 0 0 0 1\n")
    _, line = run(capsys, "eval", "ate", str(bad), str(good))
    assert f"{bad}:2: the TUM trajectory is not UTF-8 text (byte 0xe9" in line
    assert "fix: save it as UTF-8" in line


def test_launch_non_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"launch: []\n# " + LATIN1)
    _, line = run(capsys, "launch", str(bad), "--print")
    assert f"{bad}:2: the launch file is not UTF-8 text" in line


def test_slam_tum_rgb_txt_non_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tum_lists(tmp_path / "seq", [1.0, 2.0])
    (folder / "rgb.txt").write_bytes(b"1.0 rgb/a.png\n" + LATIN1)
    _, line = run(capsys, "slam", "--tum", str(folder))
    assert f"{folder / 'rgb.txt'}:2: the TUM file list is not UTF-8 text" in line


def test_slam_tum_camera_info_non_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tum_lists(tmp_path / "seq", [1.0, 2.0])
    (folder / "camera_info.yaml").write_bytes(b"image_width: 640\n" + LATIN1)
    _, line = run(capsys, "slam", "--tum", str(folder))
    assert "camera_info.yaml:2: the camera_info YAML is not UTF-8 text" in line


def test_camera_info_option_non_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tum_lists(tmp_path / "seq", [1.0, 2.0])
    info = tmp_path / "cam.yaml"
    info.write_bytes(LATIN1)
    _, line = run(capsys, "slam", "--tum", str(folder), "--camera-info", str(info))
    assert f"{info}:1: the camera_info YAML is not UTF-8 text (byte 0xe9 at column 4)" in line


def test_doctor_expect_non_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    expect = tmp_path / "expect.yaml"
    expect.write_bytes(LATIN1)
    _, line = run(capsys, "doctor", "--expect", str(expect), "--bag", str(tmp_path / "x"))
    assert f"{expect}:1: the --expect file is not UTF-8 text" in line


# --------------------------------------------------------------------------- launch YAML
def test_launch_arg_choices_not_a_list(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    file = tmp_path / "a.yaml"
    file.write_text("launch:\n  - arg: {name: x, default: a, choices: 3.5}\n")
    _, line = run(capsys, "launch", str(file), "--print")
    assert f"{file}:2: arg 'x': choices is 3.5: expected a list of values" in line
    assert "fix: write e.g. choices: [low, high]" in line


def test_launch_c1_control_character(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    file = tmp_path / "c1.yaml"
    file.write_text('launch:\n  - arg: {name: x, default: "a\x85\x80b"}\n', encoding="utf-8")
    _, line = run(capsys, "launch", str(file), "--print")
    assert f"{file}:2: the launch file contains the character U+0080" in line
    assert "fix: delete it" in line


def test_launch_alias_bomb_is_refused_quickly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for prev, name in zip("abcdefgh", "bcdefghi", strict=True):
        lines.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    file = tmp_path / "bomb.yaml"
    file.write_text("\n".join(lines) + "\nlaunch: []\n")
    assert file.stat().st_size < 500
    start = time.perf_counter()
    _, line = run(capsys, "launch", str(file), "--print")
    assert time.perf_counter() - start < 5.0
    assert f"{file}:1: the launch file does not parse as YAML" in line
    assert "aliases expand to" in line
    assert "over visnav's limit of 100,000" in line


# --------------------------------------------------------------------------- slam, eval
def test_slam_negative_features(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tum_lists(tmp_path / "seq", [1.0, 2.0])
    _, line = run(capsys, "slam", "--tum", str(folder), "--features", "-5")
    assert "n_features (--features) is -5: expected a positive integer" in line


def test_slam_output_directory_fails_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the listed images do not exist: had the run started, it would fail on them instead
    folder = tum_lists(tmp_path / "seq", [1.0, 2.0])
    out = tmp_path / "out"
    out.mkdir()
    _, line = run(capsys, "slam", "--tum", str(folder), "-o", str(out))
    assert f"{out}: is a directory; the trajectory is a file" in line
    assert "fix: give a file name" in line


def test_eval_ate_zero_quaternion(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    est = tmp_path / "est.txt"
    est.write_text("# header\n1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 0\n")
    gt = tmp_path / "gt.txt"
    gt.write_text("1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n")
    _, line = run(capsys, "eval", "ate", str(est), str(gt), "-r", "angle_deg")
    assert f"{est}:3: quaternion qx qy qz qw = 0 0 0 0 has (near) zero length" in line
    assert "fix: write a unit quaternion" in line


# --------------------------------------------------------------------------- calibrate, run
def test_calibrate_on_1x1_images(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i}.png"), np.zeros((1, 1), np.uint8))
    _, line = run(capsys, "calibrate", "--images", str(tmp_path))
    assert line.startswith("error: only 0 of 3 images show the full 9x6")
    assert "0.png: the image is 1x1 px, too small to show a 9x6 chessboard" in caplog.text


def test_calibrate_output_directory_fails_before_the_views(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    images = tmp_path / "images"
    images.mkdir()
    cv2.imwrite(str(images / "0.png"), np.zeros((1, 1), np.uint8))
    _, line = run(capsys, "calibrate", "--images", str(images), "-o", str(tmp_path))
    assert f"{tmp_path}: is a directory; the camera_info YAML (-o) is a file" in line
    assert "too small" not in caplog.text  # no image was looked at


def test_run_out_dev_null(capsys: pytest.CaptureFixture[str]) -> None:
    _, line = run(capsys, "run", "car", "--out", "/dev/null", "--duration", "1")
    assert "/dev/null: is not a directory" in line
    assert "fix: give a directory path" in line


# --------------------------------------------------------------------------- sim
def test_sim_spawn_far_outside(capsys: pytest.CaptureFixture[str], domain: int) -> None:
    _, line = run(
        capsys, "--domain", str(domain), "sim", "--world", "office", "--robot", "car",
        "--spawn", "1e300", "0", "0", "0", "--duration", "1",
    )  # fmt: skip
    assert "robot 'car': spawn x y z = 1e+300 0 0 lies outside world 'office'" in line


def test_sim_unknown_xacro_arg(capsys: pytest.CaptureFixture[str], domain: int) -> None:
    _, line = run(
        capsys, "--domain", str(domain), "sim", "--world", "office", "--robot", "car",
        "--arg", "nope:=1", "--duration", "1",
    )  # fmt: skip
    assert "unknown Xacro argument nope (given as nope:=1)" in line
    assert "camera_rate" in line


# --------------------------------------------------------------------------- the boundary
def test_library_errors_reaching_main_become_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import visnav.cli.eval as verb

    def raise_cv2(args: argparse.Namespace) -> int:
        del args
        cv2.cvtColor(np.zeros((0, 0, 3), np.uint8), cv2.COLOR_RGB2GRAY)
        return 0

    monkeypatch.setattr(verb, "cmd_eval", raise_cv2)
    _, line = run(capsys, "eval", "ate", "a", "b")
    assert "OpenCV could not process the data in cvtColor(): !_src.empty()" in line

    def raise_os(args: argparse.Namespace) -> int:
        raise OSError(errno.EFBIG, "File too large", "/tmp/out.bag")

    monkeypatch.setattr(verb, "cmd_eval", raise_os)
    _, line = run(capsys, "eval", "ate", "a", "b")
    assert line == (
        "error: /tmp/out.bag: File too large; fix: the file is too large for this filesystem; "
        "write to another filesystem"
    )

    def raise_bug(args: argparse.Namespace) -> int:
        return int({}["missing"])

    monkeypatch.setattr(verb, "cmd_eval", raise_bug)
    _, line = run(capsys, "eval", "ate", "a", "b")
    assert "internal error KeyError: 'missing'; this is a bug in visnav" in line
    # --debug adds the traceback
    assert main(["--debug", "eval", "ate", "a", "b"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_describe_error_kinds() -> None:
    with pytest.raises(UnicodeDecodeError) as info:
        b"ab\xff".decode("utf-8")
    assert "byte 0xff at offset 2" in describe_error(info.value)
    assert describe_error(FileNotFoundError(errno.ENOENT, "No such file", "x.yaml")) == (
        "x.yaml: No such file; fix: check the path"
    )
    assert describe_error(MemoryError()).startswith("out of memory; fix:")
    with pytest.raises(struct.error) as short:
        struct.unpack("<I", b"ab")
    assert describe_error(short.value).startswith("binary data ends early or is corrupt")
    assert "bug in visnav" in describe_error(ZeroDivisionError("division by zero"))
