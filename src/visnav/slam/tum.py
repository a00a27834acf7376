"""TUM RGB-D dataset folders: file lists, stamp association, intrinsics.

A TUM RGB-D sequence folder holds ``rgb.txt`` and ``depth.txt`` (``timestamp
path`` per line, ``#`` comments), the images they name (colour PNGs; 16-bit depth
PNGs with 5000 units per metre) and optionally ``groundtruth.txt`` (a TUM
trajectory). Colour and depth frames are paired as the benchmark's
``associate.py`` does: candidate pairs within ``max_difference`` (0.02 s) are
taken greedily by smallest stamp difference, each frame used once.

TUM folders carry no intrinsics; :func:`find_intrinsics` reads a
``camera_info.yaml`` (ROS calibration format) in the folder or takes them from
the caller.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.perception.camera_info_yaml import read_camera_info_yaml
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.errors import AssociationError, SlamInputError
from visnav.textfile import read_text

__all__ = [
    "TUM_DEPTH_SCALE",
    "TumFrame",
    "TumSequence",
    "associate_stamps",
    "read_file_list",
]

TUM_DEPTH_SCALE = 5000.0
"""Units per metre of TUM RGB-D depth PNGs."""

_CAMERA_FILES = ("camera_info.yaml", "camera.yaml", "calibration.yaml")


def read_file_list(path: Path) -> list[tuple[float, str]]:
    """Read a TUM ``rgb.txt`` / ``depth.txt``: ``(stamp, relative path)`` per frame.

    Raises:
        SlamInputError: the file is missing or a line is malformed.
    """
    if not path.is_file():
        text = (
            f"{path} does not exist: a TUM RGB-D folder needs rgb.txt and depth.txt "
            "('timestamp filename' per line)"
        )
        raise SlamInputError(text)
    out: list[tuple[float, str]] = []
    text = read_text(path, what="the TUM file list", error=SlamInputError)
    for lineno, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        parts = stripped.replace(",", " ").split()
        try:
            stamp = float(parts[0])
        except (ValueError, IndexError):  # IndexError: a line of only commas
            text = f"{path}:{lineno}: {stripped!r} does not start with a timestamp"
            raise SlamInputError(text) from None
        if not math.isfinite(stamp):
            text = f"{path}:{lineno}: timestamp {parts[0]!r} is not a finite number of seconds"
            raise SlamInputError(text)
        if len(parts) < 2:
            text = f"{path}:{lineno}: {stripped!r} has no file name after the timestamp"
            raise SlamInputError(text)
        out.append((stamp, parts[1]))
    return out


def associate_stamps(
    first: NDArray[np.float64],
    second: NDArray[np.float64],
    *,
    max_difference: float = 0.02,
    offset: float = 0.0,
) -> list[tuple[int, int]]:
    """Pair two stamp lists like TUM's ``associate.py``; return sorted index pairs.

    Candidate pairs with ``|a - (b + offset)| < max_difference`` are taken in order
    of increasing difference (ties: lower indices first), each stamp at most once.
    """
    a = np.asarray(first, dtype=np.float64)
    b = np.asarray(second, dtype=np.float64) + offset
    order_b = np.argsort(b, kind="stable")
    sb = b[order_b]
    lo = np.searchsorted(sb, a - max_difference, side="left")
    hi = np.searchsorted(sb, a + max_difference, side="right")
    counts = hi - lo
    ia = np.repeat(np.arange(len(a)), counts)
    offsets = np.cumsum(counts) - counts
    jb_sorted = np.arange(int(counts.sum())) - np.repeat(offsets, counts) + np.repeat(lo, counts)
    jb = order_b[jb_sorted] if len(jb_sorted) else np.zeros(0, dtype=np.int64)
    diff = np.abs(a[ia] - b[jb])
    keep = diff < max_difference
    ia, jb, diff = ia[keep], jb[keep], diff[keep]
    used_a = np.zeros(len(a), dtype=bool)
    used_b = np.zeros(len(b), dtype=bool)
    pairs: list[tuple[int, int]] = []
    for k in np.lexsort((jb, ia, diff)).tolist():
        i, j = int(ia[k]), int(jb[k])
        if not used_a[i] and not used_b[j]:
            used_a[i] = used_b[j] = True
            pairs.append((i, j))
    pairs.sort()
    return pairs


@dataclass(frozen=True)
class TumFrame:
    """One associated colour + depth pair of a TUM folder."""

    stamp: float
    rgb_path: Path
    depth_path: Path
    depth_stamp: float


class TumSequence:
    """A TUM RGB-D folder: associated frames, ground truth, intrinsics.

    Args:
        folder: the sequence folder.
        max_difference: colour/depth association tolerance in seconds.
        logger: receives warnings (frames without a partner); default module logger.

    Raises:
        SlamInputError: the folder is missing or empty, or no colour frame has a
            depth partner.
    """

    def __init__(
        self,
        folder: str | Path,
        *,
        max_difference: float = 0.02,
        logger: logging.Logger | None = None,
    ) -> None:
        self.folder = Path(folder)
        log = logger or logging.getLogger(__name__)
        if not self.folder.is_dir():
            text = f"TUM folder {self.folder} does not exist or is not a directory"
            raise SlamInputError(text)
        rgb = read_file_list(self.folder / "rgb.txt")
        depth = read_file_list(self.folder / "depth.txt")
        if not rgb or not depth:
            which = "rgb.txt" if not rgb else "depth.txt"
            text = f"TUM folder {self.folder}: {which} lists no frames (empty sequence)"
            raise SlamInputError(text)
        rs = np.array([s for s, _ in rgb])
        ds = np.array([s for s, _ in depth])
        pairs = associate_stamps(rs, ds, max_difference=max_difference)
        if not pairs:
            text = (
                f"TUM folder {self.folder}: no colour stamp ({len(rs)}, {rs.min():.6f}.."
                f"{rs.max():.6f} s) has a depth stamp ({len(ds)}, {ds.min():.6f}.."
                f"{ds.max():.6f} s) within {max_difference} s; the two lists do not "
                "associate (different clocks or an offset?)"
            )
            raise AssociationError(text)
        unpaired = len(rs) - len(pairs)
        if unpaired:
            log.warning(
                "TUM folder %s: %d of %d colour frames have no depth within %g s and are skipped",
                self.folder,
                unpaired,
                len(rs),
                max_difference,
            )
        backwards = np.flatnonzero(np.diff(rs) < 0)
        if len(backwards):
            k = int(backwards[0])
            log.warning(
                "TUM folder %s: rgb.txt is not in time order (entry %d, stamp %.6f, comes after "
                "%.6f); the frames are processed sorted by stamp, as TUM's associate.py does",
                self.folder,
                k + 2,
                rs[k + 1],
                rs[k],
            )
        pairs = sorted(pairs, key=lambda p: (rgb[p[0]][0], p[0]))
        self.frames = [
            TumFrame(rgb[i][0], self.folder / rgb[i][1], self.folder / depth[j][1], depth[j][0])
            for i, j in pairs
        ]

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def groundtruth_path(self) -> Path | None:
        """``groundtruth.txt`` if the folder has one."""
        p = self.folder / "groundtruth.txt"
        return p if p.is_file() else None

    def find_intrinsics(self) -> CameraIntrinsics | None:
        """Intrinsics from a ``camera_info.yaml`` (or ``camera.yaml``) in the folder, if any."""
        for name in _CAMERA_FILES:
            p = self.folder / name
            if p.is_file():
                cam, _ = CameraIntrinsics.from_camera_info(read_camera_info_yaml(p), source=str(p))
                return cam
        return None

    def images(self) -> Iterator[tuple[TumFrame, NDArray[np.uint8], NDArray[np.uint16]]]:
        """Yield ``(frame, rgb (H, W, 3) uint8, depth (H, W) uint16)`` in stamp order.

        Raises:
            SlamInputError: an image cannot be read or the depth is not 16-bit.
        """
        for f in self.frames:
            bgr = cv2.imread(str(f.rgb_path), cv2.IMREAD_COLOR)
            if bgr is None:
                text = f"cannot read colour image {f.rgb_path} (listed in rgb.txt)"
                raise SlamInputError(text)
            depth = cv2.imread(str(f.depth_path), cv2.IMREAD_UNCHANGED)
            if depth is None:
                text = f"cannot read depth image {f.depth_path} (listed in depth.txt)"
                raise SlamInputError(text)
            if depth.dtype != np.uint16 or depth.ndim != 2:
                text = (
                    f"depth image {f.depth_path} is {depth.dtype} with shape {depth.shape}: "
                    "TUM depth must be a one-channel 16-bit PNG"
                )
                raise SlamInputError(text)
            rgb = np.asarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), dtype=np.uint8)
            yield f, rgb, np.asarray(depth, dtype=np.uint16)
