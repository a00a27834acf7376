"""The saved SLAM map: one numpy ``.npz`` (no pickle) and a PLY of its points.

rtabmap keeps its map in the SQLite database at ``database_path``; ORB-SLAM3 saves its
atlas with boost serialization. visnav writes what its :class:`~visnav.slam.slam_map.SlamMap`
holds to one ``.npz`` read with ``allow_pickle=False``: keyframes (ids, stamps, camera
poses ``T_wc``, odometry poses, parents, their keypoints with descriptors and the map
point each observes), map points (positions, descriptors, viewing directions, counters,
observation lists), the camera intrinsics and the loop constraints. Keyed arrays, all
with fixed dtypes, are listed in ``docs/slam.md``; lists per keyframe or point are stored
flat with an offsets array (CSR: the items of row ``i`` are ``offsets[i]:offsets[i + 1]``).

Not saved: images and depth (rtabmap's database keeps them), the bag-of-words vectors
(recomputed from a vocabulary) and the keyframes' dense cloud samples.

:func:`write_ply` writes points (and optional colours) as a binary little-endian PLY,
read by Open3D, CloudCompare, PCL and MeshLab.
"""

from __future__ import annotations

import contextlib
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.errors import SlamError
from visnav.slam.features import Frame
from visnav.slam.optimizer import LoopConstraint
from visnav.slam.slam_map import Keyframe, SlamMap

if TYPE_CHECKING:
    from visnav.slam.system import SlamSystem

__all__ = [
    "MAP_FORMAT",
    "MAP_VERSION",
    "MapFiles",
    "SavedSlamMap",
    "SlamMapFileError",
    "load_slam_map",
    "save_slam_map",
    "save_system_map",
    "check_database_path",
    "check_saved_map_path",
    "summarize_slam_map",
    "write_ply",
]

FloatArray = NDArray[np.float64]

MAP_FORMAT = "visnav-slam-map"
"""The ``format`` key of a saved map."""
MAP_VERSION = 1
"""The ``version`` key this code writes and reads."""

# key -> (dtype kind "f"/"i"/"u"/"b", trailing shape); the first axis is the count
_KEYS: dict[str, tuple[str, tuple[int, ...]]] = {
    "camera": ("f", ()),  # fx fy cx cy width height baseline (7,)
    "kf_id": ("i", ()),
    "kf_stamp_ns": ("i", ()),
    "kf_t_wc": ("f", (4, 4)),
    "kf_odom_pose": ("f", (4, 4)),  # T_odom_camera; NaN without odometry
    "kf_parent": ("i", ()),
    "kf_bad": ("b", ()),
    "kf_kp_offsets": ("i", ()),
    "kf_conn_offsets": ("i", ()),  # covisibility: keyframe ids and shared points
    "conn_kf": ("i", ()),
    "conn_weight": ("i", ()),
    "kp_uv": ("f", (2,)),
    "kp_octave": ("i", ()),
    "kp_descriptors": ("u", (32,)),
    "kp_depth": ("f", ()),
    "kp_u_right": ("f", ()),
    "kp_points_c": ("f", (3,)),
    "kp_inv_sigma2": ("f", ()),
    "kp_map_point": ("i", ()),
    "point_position": ("f", (3,)),
    "point_descriptor": ("u", (32,)),
    "point_normal": ("f", (3,)),
    "point_ref_kf": ("i", ()),
    "point_first_kf": ("i", ()),
    "point_visible": ("i", ()),
    "point_found": ("i", ()),
    "point_bad": ("b", ()),
    "point_obs_offsets": ("i", ()),
    "obs_kf": ("i", ()),
    "obs_kp": ("i", ()),
    "loop_i": ("i", ()),
    "loop_j": ("i", ()),
    "loop_t_ij": ("f", (4, 4)),
    "loop_covariance": ("f", (6, 6)),  # NaN: the fixed default weight
}
_POINT_KEYS: tuple[str, ...] = ("point_position", "point_descriptor", "point_normal")
_POINT_KEYS += ("point_ref_kf", "point_first_kf", "point_visible", "point_found", "point_bad")
_KF_KEYS = ("kf_id", "kf_stamp_ns", "kf_t_wc", "kf_odom_pose", "kf_parent", "kf_bad")
_KP_KEYS: tuple[str, ...] = ("kp_uv", "kp_octave", "kp_descriptors", "kp_depth", "kp_u_right")
_KP_KEYS += ("kp_points_c", "kp_inv_sigma2", "kp_map_point")
_FIX = "save the map again with visnav (database_path of the slam node, or save_slam_map)"


class SlamMapFileError(SlamError, ValueError):
    """A saved SLAM map cannot be written or read (the text names the file and key)."""


@dataclass(frozen=True)
class MapFiles:
    """What :func:`save_system_map` wrote: the two paths and the counts."""

    npz: str
    ply: str
    keyframes: int
    points: int


@dataclass
class SavedSlamMap:
    """A loaded SLAM map.

    Attributes:
        map: the keyframes (with their covisibility weights) and map points.
        camera: the intrinsics the map was built with.
        loops: the loop constraints (also as each keyframe's ``loop_edges``).
        version: the file's format version.
    """

    map: SlamMap
    camera: CameraIntrinsics
    loops: list[LoopConstraint]
    version: int


def _offsets(counts: list[int]) -> NDArray[np.int64]:
    return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)


def _map_arrays(m: SlamMap) -> dict[str, NDArray[Any]]:
    kfs = m.keyframes
    nan44 = np.full((4, 4), np.nan)
    n = m.n_points
    frames = [kf.frame for kf in kfs]
    obs = m.observations[:n]

    def stack(name: str, shape: tuple[int, ...], dtype: Any) -> NDArray[Any]:
        parts = [np.asarray(getattr(f, name), dtype=dtype).reshape(-1, *shape) for f in frames]
        return np.concatenate(parts) if parts else np.zeros((0, *shape), dtype=dtype)

    return {
        "kf_id": np.array([kf.id for kf in kfs], dtype=np.int64),
        "kf_stamp_ns": np.array([kf.stamp_ns for kf in kfs], dtype=np.int64),
        "kf_t_wc": np.array([kf.t_wc for kf in kfs], dtype=np.float64).reshape(-1, 4, 4),
        "kf_odom_pose": np.array(
            [nan44 if kf.odom_pose is None else kf.odom_pose for kf in kfs], dtype=np.float64
        ).reshape(-1, 4, 4),
        "kf_parent": np.array([kf.parent for kf in kfs], dtype=np.int64),
        "kf_bad": np.array([kf.bad for kf in kfs], dtype=bool),
        "kf_kp_offsets": _offsets([len(f) for f in frames]),
        "kf_conn_offsets": _offsets([len(kf.connections) for kf in kfs]),
        "conn_kf": np.array([k for kf in kfs for k in kf.connections], dtype=np.int64),
        "conn_weight": np.array([w for kf in kfs for w in kf.connections.values()], np.int64),
        "kp_uv": stack("uv", (2,), np.float64),
        "kp_octave": stack("octave", (), np.int64),
        "kp_descriptors": stack("descriptors", (32,), np.uint8),
        "kp_depth": stack("depth", (), np.float64),
        "kp_u_right": stack("u_right", (), np.float64),
        "kp_points_c": stack("points_c", (3,), np.float64),
        "kp_inv_sigma2": stack("inv_sigma2", (), np.float64),
        "kp_map_point": stack("map_points", (), np.int64),
        "point_position": m.positions[:n].copy(),
        "point_descriptor": m.descriptors[:n].copy(),
        "point_normal": m.normals[:n].copy(),
        "point_ref_kf": m.ref_kf[:n].copy(),
        "point_first_kf": m.first_kf[:n].copy(),
        "point_visible": m.visible[:n].copy(),
        "point_found": m.found[:n].copy(),
        "point_bad": m.bad[:n].copy(),
        "point_obs_offsets": _offsets([len(o) for o in obs]),
        "obs_kf": np.array([k for o in obs for k in sorted(o)], dtype=np.int64),
        "obs_kp": np.array([o[k] for o in obs for k in sorted(o)], dtype=np.int64),
    }


def save_slam_map(
    slam_map: SlamMap,
    path: str | os.PathLike[str],
    *,
    camera: CameraIntrinsics,
    loops: list[LoopConstraint] | tuple[LoopConstraint, ...] = (),
) -> Path:
    """Write a SLAM map to one ``.npz`` (written to a temporary file, then renamed).

    Args:
        slam_map: the map.
        path: the file to write (parent directories are created).
        camera: the intrinsics the map was built with.
        loops: the system's loop constraints (``SlamSystem.loops``).

    Returns:
        The written path.

    Raises:
        SlamMapFileError: the file cannot be written.
    """
    out = Path(path)
    arrays = _map_arrays(slam_map)
    cam = camera
    arrays["camera"] = np.array(
        [cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height, cam.baseline], dtype=np.float64
    )
    arrays["loop_i"] = np.array([c.i for c in loops], dtype=np.int64)
    arrays["loop_j"] = np.array([c.j for c in loops], dtype=np.int64)
    arrays["loop_t_ij"] = np.array([c.t_ij for c in loops], dtype=np.float64).reshape(-1, 4, 4)
    cov = [np.full((6, 6), np.nan) if c.covariance is None else c.covariance for c in loops]
    arrays["loop_covariance"] = np.array(cov, dtype=np.float64).reshape(-1, 6, 6)
    keyed: dict[str, NDArray[Any]] = {
        "format": np.array(MAP_FORMAT),
        "version": np.array(MAP_VERSION, dtype=np.int64),
        **arrays,
    }
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")  # renamed once complete
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        # the layout of np.savez_compressed, but deflated at zlib level 1: 2-4 times faster
        # than its level 6 for files about 2 percent larger (see bench/bench_slam_map_file.py)
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as z:
            for key, value in keyed.items():
                with z.open(f"{key}.npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
        tmp.replace(out)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        text = f"{out}: cannot write the SLAM map: {exc}; fix: choose a writable path"
        raise SlamMapFileError(text) from None
    return out


def _read(path: Path) -> dict[str, NDArray[Any]]:
    if not path.is_file():
        text = f"{path}: no such SLAM map file; fix: check the path (database_path of the run)"
        raise SlamMapFileError(text)
    try:
        with path.open("rb") as f:  # np.load given a path leaks it when the zip is bad
            magic = f.read(4)
            if magic not in (b"PK\x03\x04", b"PK\x05\x06"):
                text = (
                    f"{path}: not an .npz (a zip of .npy arrays): it starts with {magic!r}; "
                    f"expected a SLAM map saved by visnav; fix: {_FIX}"
                )
                raise SlamMapFileError(text)
            f.seek(0)
            with np.load(f, allow_pickle=False) as npz:
                return {k: np.asarray(npz[k]) for k in npz.files}
    except SlamMapFileError:
        raise
    except Exception as exc:  # noqa: BLE001 - zip, zlib, npy header, pickle refusal, OSError
        text = (
            f"{path}: not a readable .npz ({type(exc).__name__}: {exc}); expected a SLAM map "
            f"saved by visnav; fix: {_FIX}"
        )
        raise SlamMapFileError(text) from None


def _check_header(path: Path, d: dict[str, NDArray[Any]]) -> int:
    fmt = d.get("format")
    is_text = fmt is not None and fmt.shape == () and fmt.dtype.kind == "U"
    if fmt is None or not is_text or str(fmt[()]) != MAP_FORMAT:
        shown = (
            "missing"
            if fmt is None
            else repr(str(fmt[()]))
            if is_text
            else f"an array of shape {fmt.shape} dtype {fmt.dtype}"
        )
        text = (
            f"{path}: key 'format' is {shown}: expected {MAP_FORMAT!r} (is this a visnav SLAM "
            f"map? a map_server map is a .yaml); fix: {_FIX}"
        )
        raise SlamMapFileError(text)
    ver = d.get("version")
    if ver is None or ver.shape != () or ver.dtype.kind not in "iu" or int(ver) != MAP_VERSION:
        text = (
            f"{path}: key 'version' is {None if ver is None else ver.tolist()!r}: expected "
            f"{MAP_VERSION} (this visnav reads version {MAP_VERSION}); fix: {_FIX}"
        )
        raise SlamMapFileError(text)
    for key, (kind, trailing) in _KEYS.items():
        if key not in d:
            text = (
                f"{path}: key {key!r} is missing: a version {MAP_VERSION} map has it; fix: {_FIX}"
            )
            raise SlamMapFileError(text)
        arr = d[key]
        if arr.dtype.kind != kind or arr.ndim != 1 + len(trailing) or arr.shape[1:] != trailing:
            want = f"(N, {', '.join(map(str, trailing))})" if trailing else "(N,)"
            text = (
                f"{path}: key {key!r} has shape {arr.shape} dtype {arr.dtype}: expected shape "
                f"{want} of kind {kind!r}; fix: {_FIX}"
            )
            raise SlamMapFileError(text)
    return MAP_VERSION


def _fail(path: Path, key: str, value: object, expected: str) -> SlamMapFileError:
    return SlamMapFileError(f"{path}: key {key!r} is {value}: expected {expected}; fix: {_FIX}")


def _check_lengths(path: Path, d: dict[str, NDArray[Any]], keys: tuple[str, ...], n: int) -> None:
    for key in keys:
        if len(d[key]) != n:
            raise _fail(path, key, f"{len(d[key])} long", f"{n} entries like {keys[0]!r}")


def _check_offsets(path: Path, key: str, offsets: NDArray[Any], rows: int, items: int) -> None:
    if len(offsets) != rows + 1:
        raise _fail(path, key, f"{len(offsets)} long", f"{rows + 1} (one per row, plus one)")
    bad = offsets[0] != 0 or offsets[-1] != items or np.any(np.diff(offsets) < 0)
    if bad:
        value = f"[{offsets[0]} .. {offsets[-1]}]"
        raise _fail(path, key, value, f"non-decreasing offsets from 0 to {items}")


def _check_range(path: Path, key: str, arr: NDArray[Any], low: int, high: int) -> None:
    out = (arr < low) | (arr >= high)
    if np.any(out):
        value = int(arr[np.flatnonzero(out)[0]])
        raise _fail(path, key, f"{value} (an id)", f"ids in [{low}, {high})")


def _check_poses(path: Path, key: str, poses: FloatArray, *, allow_nan: bool = False) -> None:
    for i, t in enumerate(poses):
        if allow_nan and np.all(np.isnan(t)):
            continue
        rot = t[:3, :3]
        ok = bool(np.all(np.isfinite(t))) and np.allclose(t[3], [0, 0, 0, 1])
        with np.errstate(all="ignore"):  # a huge entry overflows: not orthonormal either
            ok = ok and np.allclose(rot @ rot.T, np.eye(3), atol=1e-6)
        if not ok:
            what = "a 4x4 rigid transform (finite, orthonormal rotation, last row 0 0 0 1)"
            raise _fail(path, f"{key}[{i}]", np.array2string(t.ravel(), precision=3), what)


def _validate(path: Path, d: dict[str, NDArray[Any]]) -> None:
    k = len(d["kf_id"])
    _check_lengths(path, d, _KF_KEYS, k)
    if not np.array_equal(d["kf_id"], np.arange(k)):
        raise _fail(path, "kf_id", d["kf_id"][:5].tolist(), f"0, 1, ..., {k - 1}")
    n_kp = len(d["kp_uv"])
    _check_lengths(path, d, _KP_KEYS, n_kp)
    _check_offsets(path, "kf_kp_offsets", d["kf_kp_offsets"], k, n_kp)
    _check_lengths(path, d, ("conn_kf", "conn_weight"), len(d["conn_kf"]))
    _check_offsets(path, "kf_conn_offsets", d["kf_conn_offsets"], k, len(d["conn_kf"]))
    m = len(d["point_position"])
    _check_lengths(path, d, _POINT_KEYS, m)
    n_obs = len(d["obs_kf"])
    _check_lengths(path, d, ("obs_kf", "obs_kp"), n_obs)
    _check_offsets(path, "point_obs_offsets", d["point_obs_offsets"], m, n_obs)
    _check_lengths(path, d, ("loop_i", "loop_j", "loop_t_ij", "loop_covariance"), len(d["loop_i"]))
    if len(d["camera"]) != 7:
        raise _fail(path, "camera", d["camera"].tolist(), "fx fy cx cy width height baseline")
    _check_range(path, "kf_parent", d["kf_parent"], -1, k)
    _check_range(path, "kp_map_point", d["kp_map_point"], -1, m)
    for key in ("point_ref_kf", "point_first_kf", "obs_kf", "conn_kf", "loop_i", "loop_j"):
        _check_range(path, key, d[key], 0, k)
    # each observation's keypoint lies within its keyframe's keypoints
    per_kf = np.diff(d["kf_kp_offsets"])
    _check_range(path, "obs_kp", d["obs_kp"], 0, 1 << 62)
    over = d["obs_kp"] >= per_kf[d["obs_kf"]]
    if np.any(over):
        i = int(np.flatnonzero(over)[0])
        value = f"{int(d['obs_kp'][i])} (keypoint of keyframe {int(d['obs_kf'][i])})"
        raise _fail(path, "obs_kp", value, f"< {int(per_kf[d['obs_kf'][i]])} keypoints")
    _check_poses(path, "kf_t_wc", d["kf_t_wc"])
    _check_poses(path, "kf_odom_pose", d["kf_odom_pose"], allow_nan=True)
    _check_poses(path, "loop_t_ij", d["loop_t_ij"])
    for i, cov in enumerate(d["loop_covariance"]):
        if not (np.all(np.isnan(cov)) or np.all(np.isfinite(cov))):
            raise _fail(path, f"loop_covariance[{i}]", "partly NaN", "finite, or all NaN")
    good = ~d["point_bad"].astype(bool)
    if not np.all(np.isfinite(d["point_position"][good])):
        raise _fail(path, "point_position", "not finite", "finite positions of good points")


def _camera(path: Path, values: FloatArray) -> CameraIntrinsics:
    fx, fy, cx, cy, w, h, b = (float(v) for v in values)
    if not (np.isfinite(w) and np.isfinite(h)) or w != int(w) or h != int(h):
        raise _fail(path, "camera", values.tolist(), "an integer width and height")
    try:
        return CameraIntrinsics(fx, fy, cx, cy, int(w), int(h), b)
    except SlamError as exc:
        raise _fail(path, "camera", values.tolist(), f"usable intrinsics ({exc})") from None


def _rebuild(d: dict[str, NDArray[Any]]) -> SlamMap:
    m = SlamMap()
    kp_off, obs_off = d["kf_kp_offsets"], d["point_obs_offsets"]
    for i in range(len(d["kf_id"])):
        s = slice(int(kp_off[i]), int(kp_off[i + 1]))
        frame = Frame(
            stamp_ns=int(d["kf_stamp_ns"][i]),
            uv=d["kp_uv"][s].astype(np.float64),
            octave=d["kp_octave"][s].astype(np.int64),
            descriptors=d["kp_descriptors"][s].astype(np.uint8),
            depth=d["kp_depth"][s].astype(np.float64),
            u_right=d["kp_u_right"][s].astype(np.float64),
            points_c=d["kp_points_c"][s].astype(np.float64),
            inv_sigma2=d["kp_inv_sigma2"][s].astype(np.float64),
            map_points=d["kp_map_point"][s].astype(np.int64),
        )
        t_wc = d["kf_t_wc"][i].astype(np.float64)
        t_cw = np.eye(4)
        t_cw[:3, :3] = t_wc[:3, :3].T
        t_cw[:3, 3] = -t_wc[:3, :3].T @ t_wc[:3, 3]
        frame.t_cw = t_cw.copy()
        odom = d["kf_odom_pose"][i].astype(np.float64)
        kf = Keyframe(id=i, frame=frame, t_cw=t_cw, parent=int(d["kf_parent"][i]))
        kf.bad = bool(d["kf_bad"][i])
        kf.odom_pose = None if np.all(np.isnan(odom)) else odom
        m.keyframes.append(kf)
    n = len(d["point_position"])
    m._grow(n)
    m.positions[:n] = d["point_position"]
    m.descriptors[:n] = d["point_descriptor"]
    m.normals[:n] = d["point_normal"]
    m.ref_kf[:n] = d["point_ref_kf"]
    m.first_kf[:n] = d["point_first_kf"]
    m.visible[:n] = d["point_visible"]
    m.found[:n] = d["point_found"]
    m.bad[:n] = d["point_bad"]
    m._n = n
    obs_kf, obs_kp, off = d["obs_kf"].tolist(), d["obs_kp"].tolist(), obs_off.tolist()
    m.observations = [
        dict(zip(obs_kf[off[p] : off[p + 1]], obs_kp[off[p] : off[p + 1]], strict=True))
        for p in range(n)
    ]
    conn_off, conn_kf, conn_w = d["kf_conn_offsets"].tolist(), d["conn_kf"], d["conn_weight"]
    for i, kf in enumerate(m.keyframes):
        s = slice(conn_off[i], conn_off[i + 1])
        kf.connections = dict(zip(conn_kf[s].tolist(), conn_w[s].tolist(), strict=True))
    return m


def load_slam_map(path: str | os.PathLike[str]) -> SavedSlamMap:
    """Read a map written by :func:`save_slam_map` (``allow_pickle=False``).

    Raises:
        SlamMapFileError: a missing or unreadable file, another format or version, a missing
            key, arrays of the wrong shape or of inconsistent lengths, ids out of range,
            non-finite poses or unusable intrinsics (one line naming the file and key).
    """
    p = Path(path)
    d = _read(p)
    version = _check_header(p, d)
    _validate(p, d)
    camera = _camera(p, d["camera"])
    m = _rebuild(d)
    loops = []
    for i, j, t, cov in zip(
        d["loop_i"], d["loop_j"], d["loop_t_ij"], d["loop_covariance"], strict=True
    ):
        c = None if np.all(np.isnan(cov)) else cov.astype(np.float64)
        loops.append(LoopConstraint(int(i), int(j), t.astype(np.float64), c))
        m.keyframes[int(i)].loop_edges.add(int(j))
        m.keyframes[int(j)].loop_edges.add(int(i))
    return SavedSlamMap(map=m, camera=camera, loops=loops, version=version)


def write_ply(
    points: NDArray[Any],
    path: str | os.PathLike[str],
    colors: NDArray[Any] | None = None,
) -> Path:
    """Write points (and colours) as a binary little-endian PLY (``x y z [red green blue]``).

    Args:
        points: (N, 3) positions (written as float32).
        path: the ``.ply`` to write (parent directories are created).
        colors: (N, 3) uint8 RGB, or None.

    Returns:
        The written path.

    Raises:
        SlamMapFileError: wrong shapes, non-finite points, or the file cannot be written.
    """
    out = Path(path)
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        text = f"{out}: points of shape {pts.shape}: expected finite (N, 3) positions"
        raise SlamMapFileError(text)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    props = ["property float x", "property float y", "property float z"]
    if colors is not None:
        rgb = np.asarray(colors)
        if rgb.shape != pts.shape or rgb.dtype != np.uint8:
            text = (
                f"{out}: colors of shape {rgb.shape} dtype {rgb.dtype}: expected uint8 "
                f"{pts.shape} (one RGB per point)"
            )
            raise SlamMapFileError(text)
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
        props += ["property uchar red", "property uchar green", "property uchar blue"]
    data = np.zeros(len(pts), dtype=fields)
    for axis, name in enumerate("xyz"):
        data[name] = pts[:, axis]
    if colors is not None:
        for axis, name in enumerate(("red", "green", "blue")):
            data[name] = rgb[:, axis]
    header = "\n".join(
        [
            "ply",
            "format binary_little_endian 1.0",
            "comment visnav SLAM map points (frame: map)",
            f"element vertex {len(pts)}",
            *props,
            "end_header",
        ]
    )
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("wb") as f:
            f.write(header.encode("ascii") + b"\n")
            f.write(data.tobytes())
    except OSError as exc:
        text = f"{out}: cannot write the PLY: {exc}; fix: choose a writable path"
        raise SlamMapFileError(text) from None
    return out


def save_system_map(system: SlamSystem, path: str | os.PathLike[str]) -> MapFiles:
    """Write a :class:`~visnav.slam.SlamSystem`'s map: ``path`` (.npz) and the PLY beside it.

    The PLY (same stem, ``.ply``) holds the good map points seen by at least two keyframes
    (``SlamSystem.map_cloud``, the ``slam/map_points`` cloud).

    Raises:
        SlamMapFileError: ``path`` does not end in ``.npz``, or a file cannot be written.
    """
    npz = Path(check_database_path(str(path)))
    save_slam_map(system.map, npz, camera=system.camera, loops=list(system.loops))
    cloud = np.asarray(system.map_cloud())
    ply = write_ply(cloud, npz.with_suffix(".ply"))
    kfs = sum(1 for kf in system.map.keyframes if not kf.bad)
    return MapFiles(str(npz), str(ply), kfs, len(cloud))


def check_database_path(path: str) -> str:
    """Check the SLAM node's ``database_path`` parameter ('' = no map saved).

    Raises:
        SlamMapFileError: a path that does not end in ``.npz``.
    """
    if path and Path(path).suffix != ".npz":
        text = (
            f"database_path {path!r}: expected a file name ending in .npz (visnav saves its "
            "SLAM map as numpy arrays, not rtabmap's SQLite .db); fix: e.g. slam_map.npz"
        )
        raise SlamMapFileError(text)
    return path


def check_saved_map_path(path: str) -> str:
    """Check ``database_path`` when the SLAM node localises (``localization`` true).

    Raises:
        SlamMapFileError: an empty path or no such file.
    """
    if not path:
        text = (
            "localization is true but database_path is empty: set it to the slam_map.npz a "
            "mapping run wrote (beside its map.yaml), or set localization false to map"
        )
        raise SlamMapFileError(text)
    if not Path(path).is_file():
        text = (
            f"database_path {path!r}: no such file to localise in; expected the slam_map.npz "
            "a mapping run wrote (visnav run car --out DIR writes DIR/slam_map.npz)"
        )
        raise SlamMapFileError(text)
    return path


def summarize_slam_map(saved: SavedSlamMap) -> dict[str, Any]:
    """What ``visnav map info`` prints about a saved SLAM map.

    Returns:
        ``keyframes`` / ``keyframes_total`` (not culled / all), ``points`` (good) and
        ``points_cloud`` (good, seen by two keyframes or more: the PLY), ``observations``,
        ``loops``, ``with_odometry`` (keyframes with an odometry pose), ``start_s`` /
        ``end_s`` / ``duration_s`` (keyframe stamps), ``extent_min`` / ``extent_max``
        (x, y, z of the keyframe camera centres in the map frame, m), ``path_length_m``
        (between consecutive keyframes) and ``camera`` (fx, fy, cx, cy, width, height).
    """
    m = saved.map
    kfs = [kf for kf in m.keyframes if not kf.bad]
    centres = m.camera_centres()[[kf.id for kf in kfs]] if kfs else np.zeros((0, 3))
    stamps = np.array([kf.stamp_ns for kf in kfs], dtype=np.int64)
    good = m.good_points()
    with np.errstate(all="ignore"):  # a file's absurd (finite) positions print as inf
        steps = np.linalg.norm(np.diff(centres, axis=0), axis=1) if len(centres) > 1 else []
    cam = saved.camera
    return {
        "keyframes": len(kfs),
        "keyframes_total": len(m.keyframes),
        "points": len(good),
        "points_cloud": len(m.point_cloud()),
        "observations": sum(len(m.observations[p]) for p in good.tolist()),
        "loops": len(saved.loops),
        "with_odometry": sum(1 for kf in kfs if kf.odom_pose is not None),
        "start_s": float(stamps.min()) * 1e-9 if len(stamps) else None,
        "end_s": float(stamps.max()) * 1e-9 if len(stamps) else None,
        "duration_s": float(stamps.max() - stamps.min()) * 1e-9 if len(stamps) else 0.0,
        "extent_min": (centres.min(axis=0) + 0.0).tolist() if len(centres) else None,  # no -0
        "extent_max": (centres.max(axis=0) + 0.0).tolist() if len(centres) else None,
        "path_length_m": float(np.sum(steps)),
        "camera": [cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height],
    }
