"""``visnav sim --package NAME=DIR``: where package:// and $(find NAME) point."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from visnav.cli.main import main
from visnav.cli.sim import SimArgumentError, parse_packages

TB3 = Path(__file__).parents[1] / "data" / "turtlebot3" / "turtlebot3_description"


def test_parse_packages(tmp_path: Path) -> None:
    assert parse_packages([f"a={tmp_path}", f" b = {tmp_path} "]) == {
        "a": str(tmp_path),
        "b": str(tmp_path),
    }
    with pytest.raises(SimArgumentError, match=r"--package 'a': expected NAME=DIR"):
        parse_packages(["a"])
    with pytest.raises(SimArgumentError, match=r"'/nowhere/x' is not a directory"):
        parse_packages(["a=/nowhere/x"])


@pytest.mark.slow  # two simulator starts over Zenoh: ~15 s on the 2-core machine
def test_sim_finds_the_package_it_is_given(
    tmp_path: Path, domain: int, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot file away from its package: $(find) and package:// need --package."""
    del domain  # a fresh graph domain: the sim refuses one with /clock
    robot = tmp_path / "burger.urdf.xacro"
    shutil.copy(TB3 / "urdf" / "turtlebot3_burger.urdf.xacro", robot)
    argv = ["sim", "--world", "empty", "--robot", str(robot), "--duration", "0.02"]
    assert main(argv) == 1
    assert "turtlebot3_description" in capsys.readouterr().err
    assert main([*argv, "--package", f"turtlebot3_description={TB3}"]) == 0
    assert "real-time factor" in capsys.readouterr().out
