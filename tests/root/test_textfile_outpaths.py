"""visnav.textfile (UTF-8 user files) and visnav.outpaths (output paths checked up front)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from visnav.outpaths import OutputPathError, check_output_dir, check_output_file
from visnav.textfile import TextFileError, decode_text, read_text


def test_read_text_drops_a_bom_and_reads_utf8(tmp_path: Path) -> None:
    file = tmp_path / "a.txt"
    file.write_bytes(b"\xef\xbb\xbfcaf\xc3\xa9\n")
    assert read_text(file) == "café\n"


def test_non_utf8_names_line_column_and_byte() -> None:
    with pytest.raises(TextFileError) as info:
        decode_text(b"ok\nab\xe9cd\n", source="f.txt", what="the list")
    assert str(info.value).startswith(
        "f.txt:2: the list is not UTF-8 text (byte 0xe9 at column 3); fix: save it as UTF-8"
    )


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(TextFileError, match=r"missing\.txt: the file does not exist; fix"):
        read_text(tmp_path / "missing.txt")
    with pytest.raises(TextFileError, match="is a directory, expected a file"):
        read_text(tmp_path)
    if os.geteuid() != 0:  # root reads anything
        locked = tmp_path / "locked.txt"
        locked.write_text("x")
        locked.chmod(0)
        with pytest.raises(TextFileError, match="permission denied"):
            read_text(locked)


def test_output_file_checks(tmp_path: Path) -> None:
    assert check_output_file(tmp_path / "new" / "t.txt") == tmp_path / "new" / "t.txt"
    (tmp_path / "old.txt").write_text("x")
    check_output_file(tmp_path / "old.txt")  # replaced, as ROS tools do
    with pytest.raises(OutputPathError, match="is a directory; the output file is a file"):
        check_output_file(tmp_path)
    with pytest.raises(OutputPathError, match="is not a regular file"):
        check_output_file("/dev/null")
    with pytest.raises(OutputPathError, match=r"old\.txt is a file, not a directory"):
        check_output_file(tmp_path / "old.txt" / "t.txt")


def test_output_dir_checks(tmp_path: Path) -> None:
    assert check_output_dir(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    check_output_dir(tmp_path)
    with pytest.raises(OutputPathError, match="is not a directory"):
        check_output_dir("/dev/null")
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputPathError, match="is not a directory"):
        check_output_dir(tmp_path / "f")
    with pytest.raises(OutputPathError, match="is a file, not a directory"):
        check_output_dir(tmp_path / "f" / "sub")
