"""``map_saver``: wait for one map on ``map``, write ``NAME.pgm`` + ``NAME.yaml``, end.

ROS 1's ``rosrun map_server map_saver [-f NAME] [--occ 65] [--free 25] [map:=TOPIC]``
as a node type. The node subscribes ``map`` (``nav_msgs/OccupancyGrid``, latched, so a
map published before it started arrives at once), writes the first map it receives with
:func:`visnav.mapping.map_io.save_map` (map_saver's trinary image: cells ``0..free`` are
254, cells ``>= occ`` are 0, the rest 205; the YAML's thresholds are map_server's 0.65
and 0.196 whatever ``--occ``/``--free`` are, as ROS 1 writes them), logs what it wrote
and ends: it destroys itself and, when it was the last node of its process (its own
``process`` in a launch, or a launch of only this node), the process exits 0, as
map_saver does.

Parameters: ``file`` ("map": the path without extension, ``-f``; ``~`` is expanded and
missing directories are created), ``threshold_occupied`` (65, ``--occ``, 1..100),
``threshold_free`` (25, ``--free``, 0..100, below ``threshold_occupied``) and
``save_map_timeout`` (0: wait forever, as ROS 1; > 0: give up after so many seconds,
nav2's name: the node logs an error and ends, exit code 1). :func:`parse_map_saver_args`
turns map_saver's command line (a roslaunch ``args=``) into these parameters and the
``map`` remapping.

Where visnav differs: a non-integer ``--occ``/``--free`` (``65.5``, ``abc``) is refused
(map_saver's ``atoi`` reads them as 65 and 0); ``-h`` is refused with the usage (a node
has no terminal to print help on); the output path is checked before waiting, so a
directory you cannot write is an error at start, not after the map arrived.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from visnav.graph.clock import Clock, ClockType
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import qos_profile_latched
from visnav.mapping.errors import MappingError
from visnav.mapping.map_io import MapFileError, save_map
from visnav.msgs.types import OccupancyGrid
from visnav.outpaths import check_output_file

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "MAP_SAVER_USAGE",
    "MapSaverArgs",
    "MapSaverArgsError",
    "MapSaverNode",
    "MapSaverParams",
    "check_thresholds",
    "map_saver_params_from_args",
    "parse_map_saver_args",
]

MAP_SAVER_USAGE = (
    "map_saver [-f NAME] [--occ 1..100] [--free 0..100] [map:=TOPIC]: writes NAME.pgm and "
    "NAME.yaml (default NAME map) from one nav_msgs/OccupancyGrid on map"
)


class MapSaverArgsError(MappingError, ValueError):
    """map_saver's command line is not ``[-f NAME] [--occ N] [--free N] [map:=TOPIC]``."""


@dataclass(frozen=True)
class MapSaverArgs:
    """map_saver's command line, parsed.

    Attributes:
        file: ``-f``: the output path without extension.
        occ: ``--occ``: cells at or above are occupied (black).
        free: ``--free``: cells ``0..free`` are free (white).
        remaps: ``from:=to`` arguments (``map:=/other_map``) as ``(from, to)``.
    """

    file: str = "map"
    occ: int = 65
    free: int = 25
    remaps: tuple[tuple[str, str], ...] = ()

    def params(self) -> dict[str, Any]:
        """The :class:`MapSaverNode` parameters of these arguments."""
        return {"file": self.file, "threshold_occupied": self.occ, "threshold_free": self.free}


def check_thresholds(occ: int, free: int, *, where: str = "map_saver") -> None:
    """Refuse thresholds map_saver refuses (``--occ`` 1..100, ``--free`` 0..100, free < occ).

    Raises:
        MapSaverArgsError: naming the value and the fix.
    """
    if not 1 <= occ <= 100:
        msg = f"{where}: --occ {occ}: expected 1..100 (map_saver's default 65)"
        raise MapSaverArgsError(msg)
    if not 0 <= free <= 100:
        msg = f"{where}: --free {free}: expected 0..100 (map_saver's default 25)"
        raise MapSaverArgsError(msg)
    if free >= occ:
        msg = (
            f"{where}: --free {free} --occ {occ}: the free threshold must be below the "
            "occupied one. Fix: e.g. --free 25 --occ 65 (map_saver's defaults)"
        )
        raise MapSaverArgsError(msg)


def _int(flag: str, text: str) -> int:
    try:
        return int(text.strip(), 10)
    except ValueError:
        msg = f"map_saver: {flag} {text!r}: expected a whole number. Usage: {MAP_SAVER_USAGE}"
        raise MapSaverArgsError(msg) from None


def parse_map_saver_args(args: Sequence[str]) -> MapSaverArgs:
    """Parse map_saver's command line (a roslaunch ``args=`` split on whitespace).

    Raises:
        MapSaverArgsError: an unknown or incomplete argument, a bad threshold, a private
            parameter (map_saver has none) or a special ``__name:=`` argument.
    """
    file, occ, free = "map", 65, 25
    remaps: list[tuple[str, str]] = []
    items = [str(a) for a in args]
    i = 0
    while i < len(items):
        item = items[i]
        if item in ("-f", "--occ", "--free"):
            if i + 1 >= len(items):
                msg = f"map_saver: {item} needs a value. Usage: {MAP_SAVER_USAGE}"
                raise MapSaverArgsError(msg)
            value = items[i + 1]
            if item == "-f":
                if not value.strip():
                    msg = f"map_saver: -f {value!r}: expected a file name without extension"
                    raise MapSaverArgsError(msg)
                file = value
            elif item == "--occ":
                occ = _int(item, value)
            else:
                free = _int(item, value)
            i += 2
            continue
        if item in ("-h", "--help"):
            msg = f"map_saver: {item}: a node cannot print its help. Usage: {MAP_SAVER_USAGE}"
            raise MapSaverArgsError(msg)
        name, sep, target = item.partition(":=")
        if not sep:
            msg = f"map_saver: unknown argument {item!r}. Usage: {MAP_SAVER_USAGE}"
            raise MapSaverArgsError(msg)
        if name.startswith("__") or not name:
            msg = (
                f"map_saver: argument {item!r}: special ROS arguments are not taken here; "
                "set the node's name and namespace in the launch file"
            )
            raise MapSaverArgsError(msg)
        if name.startswith("_"):
            msg = (
                f"map_saver: argument {item!r}: map_saver has no private parameters; use "
                f"-f, --occ, --free. Usage: {MAP_SAVER_USAGE}"
            )
            raise MapSaverArgsError(msg)
        if not target.strip():
            msg = f"map_saver: remapping {item!r} has no target topic; write {name}:=TOPIC"
            raise MapSaverArgsError(msg)
        remaps.append((name, target))
        i += 1
    check_thresholds(occ, free)
    return MapSaverArgs(file=file, occ=occ, free=free, remaps=tuple(remaps))


def map_saver_params_from_args(args: Sequence[str]) -> dict[str, Any]:
    """map_saver's command line as :class:`MapSaverNode` parameters (a YAML launch ``args:``).

    Raises:
        MapSaverArgsError: as :func:`parse_map_saver_args`, and for a ``map:=TOPIC``
            remapping (a YAML launch file gives it as ``remap: {map: TOPIC}``).
    """
    parsed = parse_map_saver_args(args)
    if parsed.remaps:
        (name, target), *_ = parsed.remaps
        msg = (
            f"map_saver args: {name}:={target} is a remapping; in a YAML launch file write "
            f"remap: {{{name}: {target}}} beside args"
        )
        raise MapSaverArgsError(msg)
    return parsed.params()


@dataclass(frozen=True)
class MapSaverParams:
    """map_saver's options as parameters (read once)."""

    file: str = param("map", description="output path without extension (-f)")
    threshold_occupied: int = param(65, description="cells >= this are black (--occ)")
    threshold_free: int = param(25, description="cells 0..this are white (--free)")
    save_map_timeout: float = param(
        0.0, description="give up after this many seconds (0: wait forever)", range=(0.0, 1e9)
    )

    def __post_init__(self) -> None:
        check_thresholds(self.threshold_occupied, self.threshold_free, where="map_saver params")
        if not self.file.strip():
            msg = "map_saver: parameter file is empty: expected a path without extension (-f)"
            raise MapSaverArgsError(msg)


class MapSaverNode(Node):
    """Saves one map and ends (module docstring).

    Args:
        name: Node name (default ``map_saver``).
        exit_when_done: After saving, end the process (``SystemExit``) when this was its
            last node.
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (remap ``map`` here).

    Attributes:
        saved: ``(yaml, pgm)`` paths once written, else None.
        finished: True once the node saved (or timed out) and was destroyed.

    Raises:
        MapSaverArgsError: Bad thresholds or an empty ``file``.
        OutputPathError: The output files cannot be written there.
    """

    saved: tuple[Path, Path] | None = None
    finished: bool = False

    def __init__(
        self,
        name: str = "map_saver",
        *,
        exit_when_done: bool = True,
        **node_kwargs: Unpack[NodeOptions],
    ) -> None:
        super().__init__(name, **node_kwargs)
        self._exit_when_done = exit_when_done
        try:
            self.params = p = declare_params(self, MapSaverParams)
            self.base = Path(p.file).expanduser()
            for suffix in (".yaml", ".pgm"):
                check_output_file(
                    self.base.with_name(self.base.name + suffix), what=f"the map {suffix[1:]}"
                )
        except BaseException:
            Node.destroy_node(self)
            raise
        self._sub = self.create_subscription(
            OccupancyGrid, "map", self._on_map, qos_profile_latched
        )
        self.map_topic = self._sub.topic_name
        self._deadline: float | None = None
        if p.save_map_timeout > 0.0:
            self._deadline = time.monotonic() + p.save_map_timeout
            self.create_timer(0.1, self._check_timeout, clock=Clock(ClockType.STEADY_TIME))
        self.get_logger().info(f"waiting for the map on {self.map_topic}")

    def _on_map(self, grid: OccupancyGrid) -> None:
        if self.finished:
            return
        info = grid.info
        self.get_logger().info(
            f"received a {info.width} x {info.height} map at {info.resolution:.3f} m/cell"
        )
        self.base.parent.mkdir(parents=True, exist_ok=True)
        p = self.params
        self.saved = save_map(grid, self.base, occupied=p.threshold_occupied, free=p.threshold_free)
        self.get_logger().info(f"wrote {self.saved[1]} and {self.saved[0]}")
        self._end(0)

    def _check_timeout(self) -> None:
        if self.finished or self._deadline is None or time.monotonic() < self._deadline:
            return
        error = MapFileError(
            f"map_saver: no nav_msgs/OccupancyGrid on {self.map_topic} within "
            f"{self.params.save_map_timeout:g} s (save_map_timeout). Fix: start the mapper "
            "(or map_server), or remap map:=TOPIC to the map's topic"
        )
        self.get_logger().error(str(error))
        self._end(1)

    def _end(self, code: int) -> None:
        self.finished = True
        self.destroy_node()
        if self._exit_when_done and not [n for n in self.context.nodes if n is not self]:
            raise SystemExit(code)
