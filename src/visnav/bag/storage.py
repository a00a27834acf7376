"""Bag formats on disk: names, compression choices, and recognising a bag from its path.

visnav reads and writes three layouts:

* ``mcap``: a rosbag2 directory (``metadata.yaml`` + ``<name>_0.mcap``), or a bare ``.mcap`` file;
* ``sqlite3``: a rosbag2 directory with ``.db3`` files, or a bare ``.db3`` file;
* ``ros1``: a ROS 1 ``.bag`` file (format 2.0).

Recognition uses the files' magic bytes, not only their names. A storage file that was not
closed (the recorder was killed) is recognised as *incomplete*: readers then recover what
its complete chunks hold.
"""

from __future__ import annotations

import dataclasses
import struct
from pathlib import Path

from visnav.bag.errors import BagNotFoundError, UnknownStorageError
from visnav.safe_yaml import YamlError, load_yaml_file

__all__ = [
    "COMPRESSIONS",
    "FORMATS",
    "MCAP_MAGIC",
    "ROS1_MAGIC",
    "BagLayout",
    "check_format",
    "detect_layout",
]

FORMATS = ("mcap", "ros1", "sqlite3")
COMPRESSIONS: dict[str, tuple[str, ...]] = {
    "mcap": ("none", "zstd", "lz4"),
    "ros1": ("none", "lz4", "bz2"),
    "sqlite3": ("none",),
}
MCAP_MAGIC = b"\x89MCAP0\r\n"
ROS1_MAGIC = b"#ROSBAG V2.0\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
_SUFFIX = {"mcap": ".mcap", "ros1": ".bag", "sqlite3": ".db3"}


def check_format(fmt: str, compression: str) -> tuple[str, str]:
    """Validate a format and compression pair.

    Args:
        fmt: ``"mcap"``, ``"ros1"`` or ``"sqlite3"``.
        compression: ``"none"``, ``"zstd"``, ``"lz4"`` (MCAP chunks) or ``"lz4"``, ``"bz2"``
            (ROS 1 chunks).

    Returns:
        The pair, lower-cased.

    Raises:
        UnknownStorageError: unknown format, or a compression the format does not have.
    """
    f, c = fmt.lower(), (compression or "none").lower()
    if f not in FORMATS:
        msg = f"bag format {fmt!r} is unknown: expected one of {', '.join(FORMATS)}"
        raise UnknownStorageError(msg)
    if c not in COMPRESSIONS[f]:
        msg = (
            f"compression {compression!r} is not available for {f} bags: "
            f"expected one of {', '.join(COMPRESSIONS[f])}"
        )
        raise UnknownStorageError(msg)
    return f, c


@dataclasses.dataclass(frozen=True)
class BagLayout:
    """What a bag path holds.

    Attributes:
        path: the path given (directory or file).
        storage: ``"mcap"``, ``"sqlite3"`` or ``"ros1"``.
        files: the storage files, in order.
        metadata: the rosbag2 ``metadata.yaml``, or None (bare file, or missing).
        incomplete: storage files that were not closed (no MCAP footer / no ROS 1 index).
    """

    path: Path
    storage: str
    files: tuple[Path, ...]
    metadata: Path | None
    incomplete: tuple[Path, ...] = ()

    @property
    def complete(self) -> bool:
        """True when every storage file was closed properly."""
        return not self.incomplete

    @property
    def is_ros1(self) -> bool:
        """True for a ROS 1 bag."""
        return self.storage == "ros1"


def _magic_storage(path: Path) -> str | None:
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError as exc:
        msg = f"cannot read bag file '{path}': {exc.strerror}"
        raise UnknownStorageError(msg) from exc
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(ROS1_MAGIC):
        return "ros1"
    if head.startswith(SQLITE_MAGIC):
        return "sqlite3"
    return None


def _mcap_complete(path: Path) -> bool:
    size = path.stat().st_size
    if size < 2 * len(MCAP_MAGIC) + 37:
        return False
    with path.open("rb") as f:
        f.seek(-len(MCAP_MAGIC), 2)
        return f.read() == MCAP_MAGIC


def _ros1_complete(path: Path) -> bool:
    """A ROS 1 bag is complete when its header points at an index inside the file."""
    size = path.stat().st_size
    with path.open("rb") as f:
        f.seek(len(ROS1_MAGIC))
        raw = f.read(4)
        if len(raw) < 4:
            return False
        (hlen,) = struct.unpack("<I", raw)
        header = f.read(min(hlen, 4096))
    pos = 0
    while pos + 4 <= len(header):
        (flen,) = struct.unpack_from("<I", header, pos)
        field = header[pos + 4 : pos + 4 + flen]
        pos += 4 + flen
        key, _, value = field.partition(b"=")
        if key == b"index_pos" and len(value) == 8:
            (index_pos,) = struct.unpack("<Q", value)
            return bool(0 < index_pos < size)
    return False


def _file_layout(path: Path) -> BagLayout:
    storage = _magic_storage(path)
    if storage is None:
        msg = (
            f"'{path}' is not a bag: expected a rosbag2 directory (metadata.yaml + .mcap/.db3), "
            "an .mcap or .db3 file, or a ROS 1 .bag file (checked the magic bytes)"
        )
        raise UnknownStorageError(msg)
    if path.suffix != _SUFFIX[storage]:
        msg = (
            f"'{path}' holds a {storage} bag but is named '{path.suffix or '(no suffix)'}': "
            f"rename it to end in {_SUFFIX[storage]}"
        )
        raise UnknownStorageError(msg)
    incomplete: tuple[Path, ...] = ()
    if (storage == "mcap" and not _mcap_complete(path)) or (
        storage == "ros1" and not _ros1_complete(path)
    ):
        incomplete = (path,)
    return BagLayout(path, storage, (path,), None, incomplete)


def _dir_layout(path: Path) -> BagLayout:
    meta = path / "metadata.yaml"
    storage: str | None = None
    files: list[Path] = []
    if meta.is_file():
        try:
            info = load_yaml_file(meta, what="rosbag2 metadata")["rosbag2_bagfile_information"]
            storage = str(info["storage_identifier"])
            files = [path / Path(str(p)).name for p in info["relative_file_paths"]]
        except (YamlError, KeyError, TypeError) as exc:
            msg = (
                f"'{meta}' is not rosbag2 metadata ({type(exc).__name__}: {exc}); "
                "move it away to read the storage files directly"
            )
            raise UnknownStorageError(msg) from exc
        if storage not in ("mcap", "sqlite3"):
            msg = (
                f"'{meta}': storage_identifier {storage!r} is unknown: expected 'mcap' or 'sqlite3'"
            )
            raise UnknownStorageError(msg)
        files = [f for f in files if f.exists()] or files
    else:
        for kind, pattern in (("mcap", "*.mcap"), ("sqlite3", "*.db3")):
            found = sorted(path.glob(pattern))
            if found:
                storage, files = kind, found
                break
        if storage is None:
            msg = (
                f"directory '{path}' holds no metadata.yaml, .mcap or .db3 file: "
                "it is not a rosbag2 bag"
            )
            raise UnknownStorageError(msg)
    missing = [f for f in files if not f.exists()]
    if missing:
        msg = f"bag '{path}' lists storage files that are missing: {', '.join(map(str, missing))}"
        raise UnknownStorageError(msg)
    incomplete = tuple(
        f for f in files if f.suffix == ".mcap" and storage == "mcap" and not _mcap_complete(f)
    )
    return BagLayout(path, storage, tuple(files), meta if meta.is_file() else None, incomplete)


def detect_layout(path: str | Path) -> BagLayout:
    """Recognise the bag at ``path``.

    Args:
        path: a rosbag2 directory, an ``.mcap``/``.db3`` file or a ROS 1 ``.bag`` file.

    Returns:
        The layout, with the storage files that were not closed in ``incomplete``.

    Raises:
        BagNotFoundError: nothing at ``path``.
        UnknownStorageError: the path is no bag visnav reads.
    """
    p = Path(path)
    if not p.exists():
        hint = ""
        if p.suffix == "" and p.with_suffix(".bag").exists():
            hint = f"; did you mean {p.with_suffix('.bag')}?"
        msg = f"bag '{p}' does not exist{hint}"
        raise BagNotFoundError(msg)
    if p.is_dir():
        return _dir_layout(p)
    return _file_layout(p)
