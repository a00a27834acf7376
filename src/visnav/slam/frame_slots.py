"""Frame-sized slots in shared memory between the SLAM node and its worker process.

:meth:`~visnav.slam.worker.ProcessWorker.submit` copies a frame's image and depth into a
free slot and sends only their layout; the worker copies them out (:mod:`visnav.slam.worker`).
"""

from __future__ import annotations

import mmap
import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ALIGN", "FrameSlots", "Layout"]

ALIGN = 64
"""Byte alignment of each array in a slot."""

Layout = tuple[int, tuple[int, ...], str]
"""Where an array lies in a slot: (byte offset in the buffer, shape, dtype string)."""


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
        self.slot_bytes = -(-int(slot_bytes) // ALIGN) * ALIGN
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
            offset += -(-arr.nbytes // ALIGN) * ALIGN
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
