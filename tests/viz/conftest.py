"""Helpers of the viewer tests: message factories and reading a saved .rrd back."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from visnav.msgs import (
    Header,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Vector3,
    ns_to_time,
)


def header(frame: str, t_ns: int) -> Header:
    return Header(stamp=ns_to_time(t_ns), frame_id=frame)


def tf_stamped(
    parent: str,
    child: str,
    t_ns: int,
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
    q: tuple[float, float, float, float] | np.ndarray = (0.0, 0.0, 0.0, 1.0),
) -> TransformStamped:
    return TransformStamped(
        header=header(parent, t_ns),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
            rotation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])),
        ),
    )


def tf_msg(*transforms: TransformStamped) -> TFMessage:
    return TFMessage(transforms=list(transforms))


class Rrd:
    """The chunks of a saved recording, by entity path (leading '/' dropped)."""

    def __init__(self, path: Path) -> None:
        from rerun.chunk import RrdReader

        self.chunks: dict[str, list[Any]] = defaultdict(list)
        for chunk in RrdReader(path).stream().to_chunks():
            self.chunks[chunk.entity_path.lstrip("/")].append(chunk)

    @property
    def entities(self) -> set[str]:
        return set(self.chunks)

    def rows(self, entity: str, column: str) -> list[Any]:
        """Values of one component column over all (time-sorted) rows of an entity."""
        out: list[tuple[int, int, Any]] = []
        for chunk in self.chunks.get(entity, []):
            batch = chunk.to_record_batch()
            if column not in batch.schema.names:
                continue
            values = batch.column(column).to_pylist()
            if "ros_time" in batch.schema.names:
                times = batch.column("ros_time").cast("int64").to_pylist()
            else:
                times = [-1] * len(values)
            out.extend(
                (t, i, v)
                for i, (t, v) in enumerate(zip(times, values, strict=True))
                if v is not None
            )
        return [v for _, _, v in sorted(out, key=lambda x: (x[0], x[1]))]

    def times(self, entity: str, column: str) -> list[int]:
        out: list[int] = []
        for chunk in self.chunks.get(entity, []):
            batch = chunk.to_record_batch()
            if column in batch.schema.names and "ros_time" in batch.schema.names:
                values = batch.column(column).to_pylist()
                times = batch.column("ros_time").cast("int64").to_pylist()
                out.extend(t for t, v in zip(times, values, strict=True) if v is not None)
        return sorted(out)

    def columns(self, entity: str) -> set[str]:
        names: set[str] = set()
        for chunk in self.chunks.get(entity, []):
            names.update(n for n in chunk.to_record_batch().schema.names if ":" in n)
        return names


class Session:
    """A RerunSink saving to an .rrd in tmp_path; finish() closes it and reads the file back."""

    def __init__(self, path: Path, **sink_kwargs: Any) -> None:
        from visnav.viz import RerunSink, open_viewer

        self.path = path
        self.viewer = open_viewer(save=path)
        self.sink = RerunSink(self.viewer.recording, **sink_kwargs)

    def log(self, topic: str, msg: Any, stamp_ns: int | None = None) -> bool:
        return bool(self.sink.log(topic, msg, stamp_ns))

    def finish(self) -> Rrd:
        self.sink.close()
        self.viewer.close()
        return Rrd(self.path)


@pytest.fixture
def vz() -> SimpleNamespace:
    """The helpers of this folder (tests import no conftest module)."""
    return SimpleNamespace(header=header, tf=tf_stamped, tf_msg=tf_msg, Rrd=Rrd)


@pytest.fixture
def session(tmp_path: Path) -> Iterator[Callable[..., Session]]:
    """Make Sessions saving to tmp_path (needs rerun); closes any left open."""
    pytest.importorskip("rerun")
    made: list[Session] = []

    def make(**sink_kwargs: Any) -> Session:
        s = Session(tmp_path / f"rec{len(made)}.rrd", **sink_kwargs)
        made.append(s)
        return s

    yield make
    for s in made:
        s.viewer.close()
