"""``DisplaySink``: a :class:`~visnav.viz.RerunSink` fed at a display rate, on its own thread.

A live viewer must not slow the simulation down. Subscription callbacks run on the
thread that steps the simulation, so :meth:`DisplaySink.log` only decides and queues:

* **display rate**: per topic, a message is kept only if its stamp is at least
  ``1 / rate`` after the last one kept (defaults in :data:`DISPLAY_RATES_HZ`: images and
  clouds 5 Hz, depth images 2 Hz, scans and odometry 10 Hz, grids 1 Hz, paths 2 Hz; TF, markers and
  ``robot_description`` are all kept) — RViz draws at most at its frame rate too;
* **bounded queue**: at most ``max_pending`` bulky messages wait; beyond that the newest is
  dropped (TF is never dropped: placing everything else needs it);
* **worker thread**: conversion (JPEG encoding, cloud decimation, TF placement) and
  Rerun's logging run there. OpenCV's encoder and Rerun's Rust side release the GIL.
  The worker wakes at most ``batch_hz`` times a second and takes everything queued at
  once; the ``/tf`` messages of one batch are merged into one (inserted together, the
  data waiting for TF retried and the TF frames re-logged once per batch, not per
  message): a 100 Hz ``/tf`` then costs the simulation's thread a queue append per
  message and the worker ~20 wake-ups a second instead of 100+.

Counts of what was skipped are in :meth:`DisplaySink.stats` (``skipped``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

from visnav.description.worldmodel import WorldDescription
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import TFMessage
from visnav.viz.sink import RerunSink

__all__ = ["BATCH_HZ", "DEPTH", "DISPLAY_RATES_HZ", "DisplaySink"]

_LOG = logging.getLogger("visnav.viz")

DEPTH = "depth"
"""The rate key of depth images (``Image`` 32FC1 / 16UC1, ``compressedDepth``): 16-bit
depth is ~20x a JPEG colour frame, so it is shown less often."""

DISPLAY_RATES_HZ: dict[str, float] = {
    "sensor_msgs/msg/Image": 5.0,
    "sensor_msgs/msg/CompressedImage": 5.0,
    "sensor_msgs/msg/CameraInfo": 5.0,
    "sensor_msgs/msg/PointCloud2": 5.0,
    "sensor_msgs/msg/LaserScan": 10.0,
    "nav_msgs/msg/Odometry": 10.0,
    "geometry_msgs/msg/PoseStamped": 10.0,
    "nav_msgs/msg/Path": 2.0,
    "nav_msgs/msg/OccupancyGrid": 1.0,
    DEPTH: 2.0,
}
"""Messages per second of stamp time shown per topic, by type (others: all)."""

BATCH_HZ = 20.0
"""How often the worker wakes up at most (batches per wall-clock second)."""

_TF_TYPE = "tf2_msgs/msg/TFMessage"

_BULKY = frozenset(DISPLAY_RATES_HZ)
"""Types that may be skipped (display rate, full queue); TF, markers, strings never are."""


def _is_depth(type_name: str, msg: Any) -> bool:
    if type_name == "sensor_msgs/msg/Image":
        return str(getattr(msg, "encoding", "")) in ("32FC1", "16UC1")
    if type_name == "sensor_msgs/msg/CompressedImage":
        return "compressedDepth" in str(getattr(msg, "format", ""))
    return False


class DisplaySink:
    """Throttles and queues messages for a :class:`RerunSink` logged on a worker thread.

    Args:
        sink: the sink that converts and logs.
        rates_hz: display rate per message type (default :data:`DISPLAY_RATES_HZ`; a
            rate of 0 or a type not listed keeps every message).
        max_pending: bulky messages waiting for the worker at most.
        world_loader: called once on a thread of its own; a world it returns is logged
            (see :func:`visnav.viz.scene.world_from_graph`).
        block: a full queue makes :meth:`log` wait instead of dropping (a bag: nothing
            is lost, reading waits for the viewer).
        batch_hz: the worker's wake-ups per second at most (see the module notes; 0:
            one per message, as before batching).
    """

    def __init__(
        self,
        sink: RerunSink,
        *,
        rates_hz: Mapping[str, float] | None = None,
        max_pending: int = 64,
        world_loader: Callable[[], WorldDescription | None] | None = None,
        block: bool = False,
        batch_hz: float = BATCH_HZ,
    ) -> None:
        self._block = block
        self._batch_s = 1.0 / batch_hz if batch_hz > 0 else 0.0
        self.sink = sink
        self._periods = {
            k: int(1e9 / v)
            for k, v in (DISPLAY_RATES_HZ if rates_hz is None else rates_hz).items()
            if v > 0
        }
        self._max_pending = max_pending
        self._last_kept: dict[str, int] = {}
        self._queue: deque[_Item] = deque()
        self._pending = 0
        self._cond = threading.Condition()
        self._stop = False
        self.skipped: dict[str, int] = {}
        """Messages not shown because of the display rate or a full queue, per topic."""
        self.busy_s: dict[str, float] = {}
        """Wall seconds the worker spent showing each topic."""
        self.max_latency_s = 0.0
        """The longest time a message waited in the queue plus its logging (s)."""
        self.world_s = 0.0
        """Wall seconds the worker spent loading and logging the world."""
        self.worker_cpu_s = 0.0
        """CPU seconds of the worker thread (what the viewer takes from the process)."""
        self.batches = 0
        """Times the worker woke up and logged what was queued."""
        self._thread = threading.Thread(target=self._work, name="visnav-viewer", daemon=True)
        self._thread.start()
        self._world_thread: threading.Thread | None = None
        if world_loader is not None:  # beside the worker: messages do not wait for it
            self._world_thread = threading.Thread(
                target=self._load_world, args=(world_loader,), name="visnav-viewer-world"
            )
            self._world_thread.daemon = True
            self._world_thread.start()

    @property
    def fixed_frame(self) -> str | None:
        """The fixed frame (None until chosen)."""
        return self.sink.fixed_frame

    @property
    def pending(self) -> int:
        """Messages waiting for the worker."""
        with self._cond:
            return len(self._queue)

    def log(self, topic: str, msg: Any, stamp_ns: int | None = None) -> bool:
        """Queue ``msg`` if its topic is due (cheap: runs on the caller's thread).

        Returns:
            True if queued, False if skipped (display rate, full queue, closed).
        """
        type_name = getattr(msg, "__msgtype__", type(msg).__name__)
        if _is_depth(type_name, msg):
            type_name = DEPTH
        bulky = type_name in _BULKY
        t: int | None = None
        if bulky:
            header = getattr(msg, "header", None)
            t = time_to_ns(header.stamp) if header is not None else stamp_ns
            last = self._last_kept.get(topic)
            period = self._periods.get(type_name, 0)
            if t is not None and last is not None and 0 <= t - last < period:
                self.skipped[topic] = self.skipped.get(topic, 0) + 1
                return False
        with self._cond:
            if self._stop:
                return False
            if bulky and self._block:
                self._cond.wait_for(lambda: self._pending < self._max_pending or self._stop)
            if bulky and self._pending >= self._max_pending:
                self.skipped[topic] = self.skipped.get(topic, 0) + 1
                return False
            if bulky:
                self._pending += 1
                if t is not None:
                    self._last_kept[topic] = t
            self._queue.append((topic, msg, stamp_ns, bulky, time.perf_counter()))
            if len(self._queue) == 1 or self._block:  # else the worker is awake already
                self._cond.notify_all()
        return True

    def period_s(self, msg: Any) -> float:
        """The display period of ``msg``'s kind in stamp seconds (0: every message is shown).

        A live feed paces its subscriptions with it (see :mod:`visnav.viz.paced_feed`).
        """
        type_name = getattr(msg, "__msgtype__", type(msg).__name__)
        if _is_depth(type_name, msg):
            type_name = DEPTH
        return self._periods.get(type_name, 0) / 1e9

    def log_error(self, topic: str, type_name: str, reason: str) -> None:
        """Count a message that could not be decoded (see :meth:`RerunSink.log_error`)."""
        self.sink.log_error(topic, type_name, reason)

    def log_world(self, world: WorldDescription) -> list[str]:
        """Show the world's geometry now (see :meth:`RerunSink.log_world`)."""
        return self.sink.log_world(world)

    def flush(self, timeout_s: float = 30.0) -> bool:
        """Wait until the worker has logged everything queued; False on timeout."""
        with self._cond:
            self._flushing += 1
            self._cond.notify_all()
            try:
                return self._cond.wait_for(lambda: not self._queue and not self._busy, timeout_s)
            finally:
                self._flushing -= 1

    def poll(self) -> None:
        """Give up on data that waited too long for TF (see :meth:`RerunSink.poll`)."""
        self.sink.poll()

    def close(self) -> None:
        """Log what is queued, stop the worker, close the sink (idempotent)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join()
        if self._world_thread is not None:
            self._world_thread.join()
        self.sink.close()

    def stats(self) -> dict[str, dict[str, Any]]:
        """The sink's per-topic stats plus ``skipped`` (display rate, full queue)."""
        out = self.sink.stats()
        for topic, row in out.items():
            row["skipped"] = self.skipped.get(topic, 0)
            row["busy_s"] = round(self.busy_s.get(topic, 0.0), 3)
        return out

    _busy = False
    _flushing = 0

    def _load_world(self, loader: Callable[[], WorldDescription | None]) -> None:
        start = time.perf_counter()
        try:
            world = loader()
            if world is not None:
                self.sink.log_world(world)
        except Exception as exc:  # noqa: BLE001 - the viewer shows the rest without it
            _LOG.warning("viewer: the world's geometry is not shown: %s", exc)
        self.world_s = time.perf_counter() - start

    def _work(self) -> None:
        last = -1e9
        while True:
            with self._cond:
                self._cond.wait_for(lambda: bool(self._queue) or self._stop)
                if not self._queue:
                    self._cond.notify_all()
                    return
                # a batch per 1 / batch_hz at most: later messages join this one
                due = last + self._batch_s - time.perf_counter()
                if due > 0 and not self._hurry():
                    self._cond.wait_for(self._hurry, due)
                batch = list(self._queue)
                self._queue.clear()
                self._busy = True
            last = time.perf_counter()
            cpu = time.thread_time()
            for item in _merge_tf(batch):
                self._show(item)
            self.worker_cpu_s += time.thread_time() - cpu
            self.batches += 1
            with self._cond:
                self._busy = False
                self._cond.notify_all()

    def _hurry(self) -> bool:
        """No batching wait: stopping, flushing, or a full queue (``block``: reading waits)."""
        return self._stop or self._flushing > 0 or self._pending >= self._max_pending

    def _show(self, item: _Item) -> None:
        topic, msg, stamp_ns, bulky, queued = item
        start = time.perf_counter()
        try:
            self.sink.log(topic, msg, stamp_ns)
        except Exception:  # noqa: BLE001 - the worker survives; the sink counts bad data
            _LOG.exception("viewer: logging a message of %s failed", topic)
        finally:
            done = time.perf_counter()
            self.busy_s[topic] = self.busy_s.get(topic, 0.0) + done - start
            self.max_latency_s = max(self.max_latency_s, done - queued)
            if bulky:
                with self._cond:
                    self._pending -= 1
                    self._cond.notify_all()


_Item = tuple[str, Any, int | None, bool, float]
"""A queued message: (topic, message, stamp_ns, bulky, wall time queued)."""


def _merge_tf(batch: list[_Item]) -> list[_Item]:
    """The batch with each topic's ``/tf`` messages merged into one (at the first's place).

    Only dynamic TF (not ``*tf_static``) is merged: its transforms are inserted in
    arrival order, as if they had come one message at a time. The merged message keeps
    the oldest queue time (the latency counts from the first).
    """
    merged: dict[str, list[Any]] = {}
    out: list[_Item] = []
    for item in batch:
        topic, msg = item[0], item[1]
        if (
            getattr(msg, "__msgtype__", "") != _TF_TYPE
            or topic.rstrip("/").endswith("tf_static")
            or item[2] is not None
        ):
            out.append(item)
            continue
        transforms = merged.get(topic)
        if transforms is None:
            merged[topic] = transforms = list(msg.transforms)
            out.append((topic, transforms, None, item[3], item[4]))
        else:
            transforms.extend(msg.transforms)
    return [
        (i[0], TFMessage(transforms=i[1]), None, i[3], i[4]) if isinstance(i[1], list) else i
        for i in out
    ]
