"""Where a :class:`~visnav.slam.node.SlamNode` runs its :class:`~visnav.slam.SlamSystem`.

* :class:`InlineWorker`: in the caller's thread (each :meth:`~SlamWorker.submit` tracks
  the frame before it returns);
* :class:`ProcessWorker`: in a process of its own (``python -m visnav.slam.worker``), fed
  through a socket pair, so that tracking and mapping use another core while the caller (the
  simulator, the navigation) goes on. Results come back in submission order.

Both give the same results for the same frames: the system sees the same inputs in
the same order, and its random sources are seeded per frame. What differs is only
*when* the caller has the result; :class:`~visnav.slam.node.SlamNode` makes that a
fixed delay in stamp time (``result_latency``), so a run does not depend on the
wall clock either (ORB-SLAM's tracking thread instead uses whatever the mapping thread
has finished, which makes its runs differ from one another).

A frame whose inputs are unusable does not stop the worker: its result carries the
error text (:attr:`WorkerResult.error`), as the inline system would have raised it.

Frames reach the process through shared memory (Linux ``memfd``, handed to the child at
start): :class:`FrameSlots` holds a few frame-sized slots; :meth:`ProcessWorker.submit`
copies the image and depth into a free slot and sends only their layout (pickling a
640x480 RGB-D frame through the socket cost ~4 ms of the caller's CPU, the copy ~0.3 ms);
the worker copies them out before tracking, and a slot is free again once its frame's
result is taken. A frame that does not fit, or finds no free slot, is pickled as before.
The worker process runs OpenCV and BLAS single-threaded: its per-frame work is small
matrices and one image, and on the two cores it shares with the simulation more threads
only contend.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import signal
import socket
import subprocess
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.logsetup import configure_logging, kernel_compilation_notice
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig, TrackResult
from visnav.slam.errors import SlamError
from visnav.slam.localization_mode import check_map_camera
from visnav.slam.map_file import MapFiles, load_slam_map, save_system_map
from visnav.slam.system import SlamSystem
from visnav.slam.trajectory import Trajectory
from visnav.slam.vocabulary import Vocabulary

__all__ = [
    "WORKERS",
    "FrameSlots",
    "InlineWorker",
    "ProcessWorker",
    "SlamStats",
    "SlamWorker",
    "SlamWorkerError",
    "WorkerResult",
    "make_worker",
    "save_at_shutdown",
]

FloatArray = NDArray[np.float64]

WORKERS = ("inline", "process")
"""The ``worker`` parameter's values."""

_START_TIMEOUT_S = 120.0  # importing gtsam / OpenCV in a fresh process on a loaded machine
_SLOTS = 6  # frames in shared memory at once (the car's 0.1 s latency keeps 2-3 in flight)
_ALIGN = 64
_SINGLE_THREADED = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

Layout = tuple[int, tuple[int, ...], str]
"""Where an array lies in a slot: (byte offset in the buffer, shape, dtype string)."""


class SlamWorkerError(SlamError, RuntimeError):
    """The SLAM worker process failed or cannot be started."""


@dataclass(frozen=True)
class WorkerResult:
    """One frame's outcome from a worker.

    Attributes:
        result: the system's result (None when the frame was refused).
        error: why the frame was refused (a :class:`~visnav.slam.SlamInputError` text).
        cpu_s: CPU time the worker spent on the frame (its thread's, s).
        stats: the system's counters after the frame.
    """

    result: TrackResult | None
    error: str = ""
    cpu_s: float = 0.0
    stats: SlamStats | None = None


@dataclass(frozen=True)
class SlamStats:
    """Counters of a SLAM system (the car summary's ``slam`` key reads them)."""

    frames: int = 0
    lost: int = 0
    relocalized: int = 0
    reinitialized: int = 0
    keyframes: int = 0
    loops: int = 0
    ba_runs: int = 0
    ba_failures: int = 0
    ba_last_error: str = ""
    cpu_s: float = 0.0
    stage_cpu_s: dict[str, float] = field(default_factory=dict)


class _Core:
    """The system and its bookkeeping, the same in both workers."""

    def __init__(
        self,
        camera: CameraIntrinsics,
        config: SlamConfig,
        vocabulary_path: str,
        initial_pose: FloatArray,
        map_path: str = "",
    ) -> None:
        vocab = Vocabulary.load(vocabulary_path) if vocabulary_path else None
        saved = None
        if map_path:  # localisation mode
            saved = load_slam_map(map_path)
            check_map_camera(saved.camera, camera, map_path)
        self.system = SlamSystem(
            camera, config, vocabulary=vocab, initial_pose=initial_pose, saved_map=saved
        )
        self.cpu_s = 0.0
        self.stage_cpu: dict[str, float] = {}

    def track(
        self,
        image: NDArray[Any],
        depth: NDArray[Any] | None,
        stamp_ns: int,
        odom_pose: FloatArray | None,
    ) -> WorkerResult:
        t0 = time.thread_time()
        try:
            res = self.system.track(image, depth, stamp_ns, odom_pose=odom_pose)
        except SlamError as exc:
            cpu = time.thread_time() - t0
            self.cpu_s += cpu
            return WorkerResult(None, str(exc), cpu, self.stats())
        cpu = time.thread_time() - t0
        self.cpu_s += cpu
        for k, v in res.cpu_timings.items():
            self.stage_cpu[k] = self.stage_cpu.get(k, 0.0) + v
        return WorkerResult(res, "", cpu, self.stats())

    def stats(self) -> SlamStats:
        s = self.system
        return SlamStats(
            frames=s.n_frames,
            lost=s.n_lost,
            relocalized=s.n_relocalized,
            reinitialized=s.n_reinitialized,
            keyframes=sum(1 for kf in s.map.keyframes if not kf.bad),
            loops=len(s.loops),
            ba_runs=s.ba_runs,
            ba_failures=s.ba_failures,
            ba_last_error=s.ba_last_error,
            cpu_s=self.cpu_s,
            stage_cpu_s=dict(self.stage_cpu),
        )

    def close(self) -> None:
        """Stop the system's helper process (a background global BA's), if any."""
        self.system.global_ba.close()

    def call(self, name: str, args: tuple[Any, ...]) -> Any:
        if name == "trajectory":
            return self.system.trajectory()
        if name == "map_cloud":
            return self.system.map_cloud()
        if name == "dense_cloud":
            return self.system.dense_cloud(*args)
        if name == "stats":
            return self.stats()
        if name == "save_map":
            return save_system_map(self.system, *args)
        text = f"unknown SLAM worker call {name!r}"
        raise SlamWorkerError(text)


class SlamWorker:
    """The interface of the workers: frames in, results out in order, queries.

    Args:
        camera: the camera intrinsics.
        config: the system's configuration.
        vocabulary_path: a saved vocabulary (``""``: trained from the first keyframes).
        initial_pose: ``T_map_camera`` of the first frame.
        map_path: a saved SLAM map to localise in (``""``: map anew).
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        config: SlamConfig,
        *,
        vocabulary_path: str = "",
        initial_pose: FloatArray | None = None,
        map_path: str = "",
    ) -> None:
        self.camera, self.config = camera, config
        self.vocabulary_path = vocabulary_path
        self.map_path = map_path
        self.initial_pose = np.eye(4) if initial_pose is None else np.asarray(initial_pose, float)
        self.in_flight = 0
        self._start()

    def _start(self) -> None:
        """Build the system where it runs (the end of the constructor)."""
        raise NotImplementedError

    def submit(
        self,
        image: NDArray[Any],
        depth: NDArray[Any] | None,
        stamp_ns: int,
        odom_pose: FloatArray | None = None,
    ) -> None:
        """Queue one frame (the arguments of :meth:`SlamSystem.track`)."""
        raise NotImplementedError

    def next_result(self) -> WorkerResult:
        """The result of the oldest frame not yet taken (waits for it)."""
        raise NotImplementedError

    def _call(self, name: str, *args: Any) -> Any:
        raise NotImplementedError

    def trajectory(self) -> Trajectory:
        """Camera poses of all tracked frames in the map (after every queued frame)."""
        out: Trajectory = self._call("trajectory")
        return out

    def map_cloud(self) -> NDArray[np.float32]:
        """The sparse map (after every queued frame)."""
        out: NDArray[np.float32] = self._call("map_cloud")
        return out

    def dense_cloud(self, voxel: float) -> tuple[NDArray[np.float32], NDArray[np.uint8]]:
        """The dense coloured cloud, ``voxel`` m (after every queued frame)."""
        out: tuple[NDArray[np.float32], NDArray[np.uint8]] = self._call("dense_cloud", voxel)
        return out

    def save_map(self, path: str) -> MapFiles:
        """Write the map to ``path`` (.npz) and its points beside it (.ply), in the worker.

        Raises:
            SlamError: the map cannot be written (a process worker: SlamWorkerError).
        """
        out: MapFiles = self._call("save_map", str(path))
        return out

    def stats(self) -> SlamStats:
        """Counters (after every queued frame)."""
        out: SlamStats = self._call("stats")
        return out

    def close(self) -> None:
        """Stop the worker (idempotent)."""


class InlineWorker(SlamWorker):
    """Tracks each frame in the caller's thread when it is submitted."""

    def _start(self) -> None:
        self.core = _Core(
            self.camera, self.config, self.vocabulary_path, self.initial_pose, self.map_path
        )
        self._done: deque[WorkerResult] = deque()

    @property
    def system(self) -> SlamSystem:
        """The system itself (only an inline worker has it in this process)."""
        return self.core.system

    def submit(
        self,
        image: NDArray[Any],
        depth: NDArray[Any] | None,
        stamp_ns: int,
        odom_pose: FloatArray | None = None,
    ) -> None:
        """Track the frame now; its result waits for :meth:`next_result`."""
        self._done.append(self.core.track(image, depth, stamp_ns, odom_pose))
        self.in_flight += 1

    def next_result(self) -> WorkerResult:
        """The oldest result not yet taken.

        Raises:
            SlamWorkerError: no frame is waiting.
        """
        if not self._done:
            text = "no SLAM frame in flight: submit one before asking for its result"
            raise SlamWorkerError(text)
        self.in_flight -= 1
        return self._done.popleft()

    def close(self) -> None:
        """Stop the system's helper process, if any (idempotent)."""
        self.core.close()

    def _call(self, name: str, *args: Any) -> Any:
        return self.core.call(name, args)


class FrameSlots:
    """Frame-sized slots in one shared buffer (an anonymous ``memfd``; Linux only).

    Args:
        slot_bytes: bytes of one slot (image + depth, each aligned to 64 bytes).
        count: number of slots.
        fd: an existing buffer's file descriptor (the worker's side); None creates one.

    Raises:
        OSError: the buffer cannot be created or mapped.
    """

    def __init__(self, slot_bytes: int, count: int, *, fd: int | None = None) -> None:
        self.slot_bytes = -(-int(slot_bytes) // _ALIGN) * _ALIGN
        self.count = int(count)
        size = self.slot_bytes * self.count
        if fd is None:
            fd = os.memfd_create("visnav-slam-frames", os.MFD_CLOEXEC)
            try:
                os.ftruncate(fd, size)
            except OSError:
                os.close(fd)
                raise
        self.fd = fd
        self._map = mmap.mmap(fd, size)
        self.free = list(range(self.count))

    def put(self, slot: int, arrays: tuple[NDArray[Any], ...]) -> tuple[Layout, ...] | None:
        """Copy ``arrays`` into ``slot``; their layouts, or None when they do not fit."""
        offset = slot * self.slot_bytes
        end = offset + self.slot_bytes
        layouts = []
        for arr in arrays:
            if offset + arr.nbytes > end:
                return None
            view = np.frombuffer(self._map, dtype=arr.dtype, count=arr.size, offset=offset)
            view.reshape(arr.shape)[...] = arr
            layouts.append((offset, tuple(arr.shape), arr.dtype.str))
            offset += -(-arr.nbytes // _ALIGN) * _ALIGN
        return tuple(layouts)

    def get(self, layout: Layout) -> NDArray[Any]:
        """A copy of the array at ``layout`` (the slot may be reused once the frame is done)."""
        offset, shape, dtype = layout
        count = int(np.prod(shape))
        view = np.frombuffer(self._map, dtype=np.dtype(dtype), count=count, offset=offset)
        out: NDArray[Any] = view.reshape(shape).copy()
        return out

    def close(self) -> None:
        """Unmap and close the buffer (idempotent)."""
        if self.fd >= 0:
            self._map.close()
            os.close(self.fd)
            self.fd = -1


def _serve(conn: Connection, slots: FrameSlots | None = None) -> None:
    """The worker process: build the system, then answer requests until told to stop."""
    core: _Core | None = None
    while True:
        try:
            msg: tuple[Any, ...] = conn.recv()
        except (EOFError, OSError):  # the parent is gone
            if core is not None:
                core.close()
            return
        kind = msg[0]
        try:
            if kind == "init":
                core = _Core(*msg[1:])
                conn.send(("ok", None))
            elif core is None:
                conn.send(("error", f"{kind!r} before the system was built"))
            elif kind == "track":
                conn.send(("ok", core.track(*msg[1:])))
            elif kind == "track_slot" and slots is not None:
                _, image_at, depth_at, stamp, odom = msg
                image = slots.get(image_at)
                depth = None if depth_at is None else slots.get(depth_at)
                conn.send(("ok", core.track(image, depth, stamp, odom)))
            elif kind == "call":
                conn.send(("ok", core.call(msg[1], msg[2])))
            else:  # "close"
                if core is not None:
                    core.close()
                conn.send(("ok", None))
                return
        except Exception as exc:  # noqa: BLE001 - every failure goes back to the node
            conn.send(("error", f"{type(exc).__name__}: {exc}"))


class ProcessWorker(SlamWorker):
    """Tracks frames in a process of its own (see the module docstring).

    Raises:
        SlamWorkerError: the process cannot be started or dies.
    """

    def _start(self) -> None:
        self._slots: FrameSlots | None = None
        self._frame_slots: deque[int | None] = deque()  # slot of each frame in flight
        pixels = self.camera.width * self.camera.height
        with contextlib.suppress(OSError, AttributeError):  # no memfd: frames are pickled
            self._slots = FrameSlots(pixels * 3 + _ALIGN + pixels * 4, _SLOTS)
        slot_fd = -1 if self._slots is None else self._slots.fd
        # a fresh interpreter (never a fork of one holding MuJoCo / GL state), started by
        # module name: multiprocessing's "spawn" would re-run the caller's __main__ script
        parent, child = socket.socketpair()
        env = {**_SINGLE_THREADED, **os.environ}
        try:
            self._proc = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "visnav.slam.worker",
                    str(child.fileno()),
                    str(slot_fd),
                    str(0 if self._slots is None else self._slots.slot_bytes),
                ],
                pass_fds=(child.fileno(),) if slot_fd < 0 else (child.fileno(), slot_fd),
                stdin=subprocess.DEVNULL,
                env=env,
                # out of the terminal's process group: a Ctrl-C is the parent's to handle,
                # even while this interpreter starts (before it can ignore SIGINT); the
                # worker ends when the parent's socket closes
                start_new_session=True,
            )
        except OSError as exc:
            parent.close()
            if self._slots is not None:
                self._slots.close()
            text = (
                f"cannot start the SLAM worker process ({sys.executable} -m "
                f"visnav.slam.worker): {exc}. Fix: check that Python can start from there"
            )
            raise SlamWorkerError(text) from exc
        finally:
            child.close()
        self._conn = Connection(parent.detach())
        self._closed = False
        self._broken = ""  # why the connection is out of step (an interrupted wait)
        self._received: deque[WorkerResult] = deque()
        try:
            init = (
                "init",
                self.camera,
                self.config,
                self.vocabulary_path,
                self.initial_pose,
                self.map_path,
            )
            self._conn.send(init)
            self._answer("start", timeout_s=_START_TIMEOUT_S)
        except (SlamWorkerError, OSError):
            self.close()  # a child that refused to start is not left running
            raise

    def _answer(self, what: str, *, timeout_s: float | None = None) -> Any:
        if self._broken:
            text = f"SLAM worker connection unusable ({self._broken}): no answer to {what}"
            raise SlamWorkerError(text)
        try:
            if timeout_s is not None and not self._conn.poll(timeout_s):
                self.close()
                text = f"SLAM worker process did not answer {what} within {timeout_s:.0f} s"
                raise SlamWorkerError(text)
            status, value = self._conn.recv()
        except (EOFError, OSError) as exc:
            code = self._proc.poll()
            text = f"SLAM worker process ended (exit code {code}) during {what}: {exc!r}"
            raise SlamWorkerError(text) from None
        except (KeyboardInterrupt, SystemExit):
            # the answer (or the rest of it) is still on its way: a later read would take
            # it for the answer to another request
            self._broken = f"interrupted while waiting for {what}"
            raise
        if status == "error":
            text = f"SLAM worker process failed during {what}: {value}"
            raise SlamWorkerError(text)
        return value

    def submit(
        self,
        image: NDArray[Any],
        depth: NDArray[Any] | None,
        stamp_ns: int,
        odom_pose: FloatArray | None = None,
    ) -> None:
        """Send the frame to the process (returns at once; the arrays are copied)."""
        slots, slot, layouts = self._slots, None, None
        if slots is not None and slots.free:
            arrays = (np.asarray(image),) if depth is None else (image, depth)
            slot = slots.free.pop()
            layouts = slots.put(slot, tuple(np.asarray(a) for a in arrays))
            if layouts is None:  # larger than the camera's size: pickled
                slots.free.append(slot)
                slot = None
        if layouts is None:
            self._conn.send(("track", image, depth, int(stamp_ns), odom_pose))
        else:
            depth_at = None if depth is None else layouts[1]
            self._conn.send(("track_slot", layouts[0], depth_at, int(stamp_ns), odom_pose))
        self._frame_slots.append(slot)
        self.in_flight += 1

    def _release(self) -> None:
        """The oldest frame in flight is done: its slot may take another frame."""
        slot = self._frame_slots.popleft() if self._frame_slots else None
        if slot is not None and self._slots is not None:
            self._slots.free.append(slot)

    def next_result(self) -> WorkerResult:
        """Wait for the oldest frame's result.

        Raises:
            SlamWorkerError: no frame in flight, or the process died.
        """
        if self.in_flight <= 0:
            text = "no SLAM frame in flight: submit one before asking for its result"
            raise SlamWorkerError(text)
        if self._received:
            self.in_flight -= 1
            return self._received.popleft()
        out: WorkerResult = self._answer("tracking")
        self.in_flight -= 1  # only once received: an interrupted wait leaves it in flight
        self._release()
        return out

    def _call(self, name: str, *args: Any) -> Any:
        """A query, answered after every frame in flight (their results are kept)."""
        while len(self._received) < self.in_flight:
            self._received.append(self._answer("tracking"))
            self._release()
        self._conn.send(("call", name, args))
        return self._answer(name)

    def close(self) -> None:
        """Ask the process to stop; kill it if it does not within 5 s."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(OSError, ValueError):
            self._conn.send(("close",))
        try:
            self._proc.wait(5.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait(5.0)
        self._conn.close()
        if self._slots is not None:
            self._slots.close()


def make_worker(
    kind: str,
    camera: CameraIntrinsics,
    config: SlamConfig,
    *,
    vocabulary_path: str = "",
    initial_pose: FloatArray | None = None,
    map_path: str = "",
) -> SlamWorker:
    """A worker by its ``worker`` parameter value (``inline`` or ``process``).

    ``map_path``: a saved SLAM map to localise in (``""``: map anew).

    Raises:
        SlamWorkerError: an unknown kind.
    """
    if kind in WORKERS:
        cls = InlineWorker if kind == "inline" else ProcessWorker
        return cls(
            camera,
            config,
            vocabulary_path=vocabulary_path,
            initial_pose=initial_pose,
            map_path=map_path,
        )
    text = f"worker {kind!r}: expected one of {', '.join(WORKERS)} (inline: in the node's thread)"
    raise SlamWorkerError(text)


def save_at_shutdown(worker: SlamWorker | None, database_path: str) -> tuple[str, str]:
    """Save the map to ``database_path`` ('': nothing) before the worker closes.

    Returns:
        ``(level, text)`` for the node's log: ``info`` with the paths and counts,
        ``warning`` when no frame started the system, ``error`` when writing failed;
        ``("", "")`` without a ``database_path``.
    """
    if not database_path:
        return "", ""
    if worker is None:
        return "warning", f"no frame was processed: no SLAM map written to {database_path}"
    t0 = time.perf_counter()
    try:
        files = worker.save_map(database_path)
    except (SlamError, OSError) as exc:  # OSError: the worker process's socket is gone
        return "error", f"SLAM map not saved to {database_path}: {exc}"
    text = (
        f"SLAM map saved: {files.npz} ({files.keyframes} keyframes, {files.points} map "
        f"points in {files.ply}; {time.perf_counter() - t0:.2f} s)"
    )
    return "info", text


def _main(argv: list[str]) -> int:
    """``python -m visnav.slam.worker FD [SLOTS_FD SLOT_BYTES]``: serve the connection on FD.

    With ``SLOTS_FD`` >= 0, frames may come in the shared :class:`FrameSlots` buffer.
    """
    # Ctrl-C and SIGTERM (systemd signals every process of a service) are the parent's to
    # handle: it stops this worker by closing the connection once the map is saved
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    import cv2  # noqa: PLC0415 - only the worker process goes single-threaded

    cv2.setNumThreads(1)
    slots = None
    if len(argv) > 3 and int(argv[2]) >= 0:
        slot_bytes = int(argv[3])
        size = os.fstat(int(argv[2])).st_size
        slots = FrameSlots(slot_bytes, size // slot_bytes, fd=int(argv[2]))
    configure_logging()  # as the visnav command: [LEVEL] lines, library warnings at debug
    try:
        with kernel_compilation_notice(
            "compiling the SLAM kernels (first run only, about a minute)"
        ):
            _serve(Connection(int(argv[1])), slots)
    finally:
        if slots is not None:
            slots.close()
    return 0


if __name__ == "__main__":  # run the imported module's copy: results pickle by its name
    from visnav.slam import worker as _worker  # noqa: PLW0406 - see the comment above

    sys.exit(_worker._main(sys.argv))
