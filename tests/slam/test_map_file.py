"""The saved SLAM map: round trip from a real run, PLY, bad files, the node and the car run."""

from __future__ import annotations

import io
import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from visnav.errors import VisnavError
from visnav.graph import Context, Node
from visnav.slam import SlamConfig, SlamSystem
from visnav.slam.features import Frame
from visnav.slam.map_file import (
    MAP_FORMAT,
    SlamMapFileError,
    check_database_path,
    load_slam_map,
    save_slam_map,
    save_system_map,
    summarize_slam_map,
    write_ply,
)
from visnav.slam.node import SlamNode
from visnav.slam.optimizer import LoopConstraint
from visnav.slam.slam_map import SlamMap
from visnav.slam.worker import InlineWorker, ProcessWorker, save_at_shutdown

from .conftest import SMALL, Sequence, feed_rgbd

CONFIG = SlamConfig(n_features=400, vocabulary_keyframes=6, loop_min_inliers=30)


@pytest.fixture(scope="module")
def system(short_sequence: Sequence) -> SlamSystem:
    """A real run: 40 frames with odometry (the ground truth) as T_odom_camera."""
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
    for i, (rgb, depth, t) in enumerate(zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True)):
        slam.track(rgb, depth, int(t), odom_pose=seq.poses[i])
    return slam


def _loops() -> list[LoopConstraint]:
    t = np.eye(4)
    t[:3, 3] = [0.1, -0.2, 0.05]
    return [LoopConstraint(3, 0, t, np.eye(6) * 1e-4), LoopConstraint(5, 1, np.eye(4), None)]


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def test_round_trip_of_a_real_run(system: SlamSystem, tmp_path: Path) -> None:
    m = system.map
    assert len(m.keyframes) >= 5
    assert m.n_points > 500
    path = save_slam_map(m, tmp_path / "a" / "map.npz", camera=system.camera, loops=_loops())
    saved = load_slam_map(path)
    got = saved.map
    assert saved.camera == system.camera
    assert saved.version == 1
    assert len(got.keyframes) == len(m.keyframes)
    for a, b in zip(m.keyframes, got.keyframes, strict=True):
        assert (a.id, a.stamp_ns, a.parent, a.bad) == (b.id, b.stamp_ns, b.parent, b.bad)
        np.testing.assert_allclose(b.t_cw, a.t_cw, rtol=0, atol=1e-12)
        assert a.odom_pose is not None
        assert b.odom_pose is not None
        assert np.array_equal(a.odom_pose, b.odom_pose)
        assert a.connections == b.connections
        for name in ("uv", "octave", "descriptors", "map_points", "inv_sigma2"):
            assert np.array_equal(getattr(a.frame, name), getattr(b.frame, name)), name
        for name in ("depth", "u_right", "points_c"):  # NaN where no depth
            np.testing.assert_array_equal(getattr(a.frame, name), getattr(b.frame, name))
        kp_a, pts_a = m.keyframe_points(a)
        kp_b, pts_b = got.keyframe_points(b)
        assert np.array_equal(kp_a, kp_b)
        assert np.array_equal(pts_a, pts_b)
    n = m.n_points
    assert got.n_points == n
    for name in ("positions", "descriptors", "normals", "ref_kf", "visible", "found", "bad"):
        assert np.array_equal(getattr(m, name)[:n], getattr(got, name)[:n]), name
    assert got.observations == m.observations[:n]
    assert np.array_equal(got.point_cloud(), m.point_cloud())
    np.testing.assert_allclose(got.camera_centres(), m.camera_centres(), atol=1e-12)
    assert np.array_equal(got.local_points([0, 1, 2]), m.local_points([0, 1, 2]))
    # the loops: constraints and the keyframes' loop edges
    assert [(c.i, c.j) for c in saved.loops] == [(3, 0), (5, 1)]
    assert np.array_equal(saved.loops[0].t_ij, _loops()[0].t_ij)
    assert saved.loops[0].covariance is not None
    assert saved.loops[1].covariance is None
    assert got.keyframes[3].loop_edges == {0}
    assert got.keyframes[0].loop_edges == {3}
    # saving the loaded map gives the same file content
    again = save_slam_map(got, tmp_path / "b.npz", camera=saved.camera, loops=saved.loops)
    first, second = _arrays(path), _arrays(again)
    assert first.keys() == second.keys()
    for key, value in first.items():
        if key == "kf_t_wc":  # inverted twice
            np.testing.assert_allclose(second[key], value, rtol=0, atol=1e-12)
        else:
            np.testing.assert_array_equal(second[key], value, err_msg=key)
    assert str(first["format"]) == MAP_FORMAT


def _read_ply(path: Path) -> tuple[list[str], np.ndarray]:
    raw = path.read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    header = raw[:end].decode("ascii").splitlines()
    assert header[:2] == ["ply", "format binary_little_endian 1.0"]
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    types = {"float": "<f4", "uchar": "u1"}
    fields = [
        (line.split()[2], types[line.split()[1]]) for line in header if line.startswith("property")
    ]
    data = np.frombuffer(raw[end:], dtype=fields)
    assert len(data) == count  # nothing after the vertices
    return header, data


def test_system_map_npz_and_ply(system: SlamSystem, tmp_path: Path) -> None:
    files = save_system_map(system, tmp_path / "slam_map.npz")
    assert files.npz == str(tmp_path / "slam_map.npz")
    assert files.ply == str(tmp_path / "slam_map.ply")
    assert files.keyframes == len(system.map.keyframes)
    cloud = system.map_cloud()
    assert files.points == len(cloud) > 100
    header, data = _read_ply(Path(files.ply))
    assert [h.split()[-1] for h in header if h.startswith("property")] == ["x", "y", "z"]
    assert np.array_equal(np.stack([data["x"], data["y"], data["z"]], axis=1), cloud)
    info = summarize_slam_map(load_slam_map(files.npz))
    assert info["keyframes"] == files.keyframes
    assert info["points_cloud"] == len(cloud)
    assert info["with_odometry"] == files.keyframes
    seq_span = (system.map.keyframes[-1].stamp_ns - system.map.keyframes[0].stamp_ns) * 1e-9
    assert info["duration_s"] == pytest.approx(seq_span)
    centres = system.map.camera_centres()
    np.testing.assert_allclose(info["extent_min"], centres.min(axis=0))
    assert info["path_length_m"] > 0.5  # the camera moves ~2 m along the arc


def test_ply_with_colours_and_bad_input(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(7, 3))
    rgb = rng.integers(0, 256, (7, 3), dtype=np.uint8)
    header, data = _read_ply(write_ply(pts, tmp_path / "c.ply", rgb))
    assert header[-4:-1] == ["property uchar red", "property uchar green", "property uchar blue"]
    np.testing.assert_array_equal(np.stack([data["x"], data["y"], data["z"]], 1), pts.astype("f4"))
    assert np.array_equal(np.stack([data["red"], data["green"], data["blue"]], 1), rgb)
    _, empty = _read_ply(write_ply(np.zeros((0, 3)), tmp_path / "e.ply"))
    assert len(empty) == 0
    with pytest.raises(SlamMapFileError, match=r"points of shape \(7, 2\)"):
        write_ply(pts[:, :2], tmp_path / "x.ply")
    with pytest.raises(SlamMapFileError, match="finite"):
        write_ply(np.full((2, 3), np.nan), tmp_path / "x.ply")
    with pytest.raises(SlamMapFileError, match="colors of shape"):
        write_ply(pts, tmp_path / "x.ply", rgb.astype(np.float32))


def _tiny_map() -> SlamMap:
    """Three keyframes sharing four points: a small file for the fuzz test."""
    rng = np.random.default_rng(0)
    m = SlamMap()
    for k in range(3):
        n = 6
        uv = rng.uniform(0, 100, (n, 2))
        depth = rng.uniform(1, 3, n)
        frame = Frame(
            stamp_ns=1_000 + k,
            uv=uv,
            octave=np.zeros(n, dtype=np.int64),
            descriptors=rng.integers(0, 256, (n, 32), dtype=np.uint8),
            depth=depth,
            u_right=uv[:, 0] - 10 / depth,
            points_c=np.c_[uv, depth],
            inv_sigma2=np.ones(n),
        )
        t_cw = np.eye(4)
        t_cw[0, 3] = -0.1 * k
        kf = m.add_keyframe(frame, t_cw, parent=k - 1)
        kf.odom_pose = np.array(np.linalg.inv(t_cw), dtype=np.float64) if k else None
        if k == 0:
            m.add_points(
                rng.normal(size=(4, 3)) + np.array([0.0, 0.0, 3.0]),
                frame.descriptors[:4],
                kf,
                np.arange(4),
            )
        else:
            for p in range(4):
                m.add_observation(p, kf, p + k)
        m.update_connections(kf)
    return m


@pytest.fixture(scope="module")
def tiny_file(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = tmp_path_factory.mktemp("tiny") / "tiny.npz"
    loop = LoopConstraint(2, 0, _loops()[0].t_ij, np.eye(6) * 1e-4)
    save_slam_map(_tiny_map(), path, camera=SMALL, loops=[loop])
    return path.read_bytes()


def _save_dict(path: Path, arrays: dict[str, Any]) -> None:
    with path.open("wb") as f:
        np.savez(f, **arrays)


def _use(path: Path) -> None:
    """Load; a map that loads must also be usable."""
    try:
        saved = load_slam_map(path)
    except VisnavError:
        return
    m = saved.map
    summarize_slam_map(saved)
    m.point_cloud(min_observations=1)
    m.camera_centres()
    for kf in m.keyframes:
        m.keyframe_points(kf)
        m.update_connections(kf)
    m.local_points([kf.id for kf in m.keyframes])


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_fuzz_only_visnav_errors_escape(
    tiny_file: bytes, tmp_path: Path, data: st.DataObject
) -> None:
    path = tmp_path / "fuzz.npz"
    how = data.draw(st.sampled_from(["bytes", "truncate", "drop", "replace", "value"]))
    if how in ("bytes", "truncate"):
        raw = bytearray(tiny_file)
        if how == "truncate":
            raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
        else:
            for _ in range(data.draw(st.integers(1, 8))):
                raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
        path.write_bytes(bytes(raw))
    else:
        arrays = dict(np.load(io.BytesIO(tiny_file), allow_pickle=False))
        key = data.draw(st.sampled_from(sorted(arrays)))
        if how == "drop":
            del arrays[key]
        elif how == "replace":
            dtype = data.draw(st.sampled_from([np.int64, np.float64, np.uint8, np.bool_]))
            shape = data.draw(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5))
            arrays[key] = data.draw(hnp.arrays(dtype, shape))
        elif arrays[key].size:  # one value changed, shape and dtype kept
            arr = arrays[key].copy()
            flat = arr.reshape(-1)
            i = data.draw(st.integers(0, flat.size - 1))
            if arr.dtype.kind == "f":
                flat[i] = data.draw(st.floats(allow_nan=True, allow_infinity=True))
            elif arr.dtype.kind in "iu":
                flat[i] = data.draw(st.integers(-3, 40)) % (
                    256 if arr.dtype.kind == "u" else 1 << 40
                )
            elif arr.dtype.kind == "b":
                flat[i] = not flat[i]
            arrays[key] = arr
        _save_dict(path, arrays)
    _use(path)


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        (lambda a: a.pop("point_normal"), "key 'point_normal' is missing"),
        (lambda a: a.update(format=np.array("rtabmap")), "key 'format' is 'rtabmap'"),
        (lambda a: a.update(version=np.array(7)), "key 'version' is 7: expected 1"),
        (lambda a: a.update(kp_depth=a["kp_depth"][:-1]), "key 'kp_depth' is 17 long"),
        (lambda a: a.update(kp_uv=a["kp_uv"][:, :1]), "key 'kp_uv' has shape (18, 1)"),
        (lambda a: a.update(obs_kf=a["obs_kf"] + 5), "key 'obs_kf' is 5 (an id)"),
        (lambda a: a.update(kp_map_point=a["kp_map_point"] * 0 + 9), "key 'kp_map_point' is 9"),
        (lambda a: a["kf_t_wc"].__setitem__((1, 0, 3), np.inf), "key 'kf_t_wc[1]'"),
        (lambda a: a.update(camera=a["camera"] * 0), "key 'camera'"),
    ],
)
def test_bad_files_are_one_line_errors(
    tiny_file: bytes, tmp_path: Path, change: Any, fragment: str
) -> None:
    arrays = dict(np.load(io.BytesIO(tiny_file), allow_pickle=False))
    change(arrays)
    path = tmp_path / "bad.npz"
    _save_dict(path, arrays)
    with pytest.raises(SlamMapFileError) as info:
        load_slam_map(path)
    text = str(info.value)
    assert fragment in text
    assert str(path) in text
    assert "fix:" in text
    assert "\n" not in text


def test_missing_and_non_npz_files(tmp_path: Path) -> None:
    with pytest.raises(SlamMapFileError, match="no such SLAM map file"):
        load_slam_map(tmp_path / "none.npz")
    (tmp_path / "text.npz").write_text("image: map.pgm\n")
    with pytest.raises(SlamMapFileError, match=r"not an \.npz .* starts with b'imag'"):
        load_slam_map(tmp_path / "text.npz")
    with pytest.raises(SlamMapFileError, match=r"ending in \.npz"):
        check_database_path("/tmp/rtabmap.db")
    assert check_database_path("") == ""


def test_node_saves_its_map_when_destroyed(
    short_sequence: Sequence, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    target = tmp_path / "run" / "slam_map.npz"
    overrides = {"odom_frame": "", "base_frame": "camera_optical", "n_features": 400}
    with Context(transport="local") as ctx:
        slam = SlamNode(
            context=ctx, parameter_overrides={**overrides, "database_path": str(target)}
        )
        feed_rgbd(Node("feeder", context=ctx), short_sequence, 10)
        assert slam.system is not None
        before = slam.system.trajectory().positions.copy()
        keyframes = len(slam.system.map.keyframes)
        assert not target.exists()  # only at shutdown
        caplog.set_level(logging.INFO)
        slam.destroy_node()
        slam.destroy_node()  # again: saved once
        assert np.array_equal(slam.system.trajectory().positions, before)  # not changed
    saved = load_slam_map(target)
    assert len(saved.map.keyframes) == keyframes
    assert target.with_suffix(".ply").is_file()
    assert caplog.text.count(f"SLAM map saved: {target} ({keyframes} keyframes") == 1  # once
    with pytest.raises(SlamMapFileError, match=r"database_path 'x\.db'"):
        SlamNode(context=Context(transport="local"), parameter_overrides={"database_path": "x.db"})


def test_nothing_to_save_and_unwritable_paths(system: SlamSystem, tmp_path: Path) -> None:
    assert save_at_shutdown(None, "") == ("", "")
    level, text = save_at_shutdown(None, str(tmp_path / "m.npz"))
    assert level == "warning"
    assert "no frame was processed" in text
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(SlamMapFileError, match="cannot write the SLAM map"):
        save_slam_map(system.map, blocker / "m.npz", camera=system.camera)


def test_process_worker_saves_the_inline_map(short_sequence: Sequence, tmp_path: Path) -> None:
    seq = short_sequence
    cfg = SlamConfig(n_features=400, seed=3)
    inline = InlineWorker(seq.camera, cfg, initial_pose=seq.poses[0])
    proc = ProcessWorker(seq.camera, cfg, initial_pose=seq.poses[0])
    try:
        for worker in (inline, proc):
            for i in range(8):
                worker.submit(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]), seq.poses[i])
            # frames still in flight: the save waits for them
        a = inline.save_map(str(tmp_path / "inline.npz"))
        b = proc.save_map(str(tmp_path / "process.npz"))
        level, text = save_at_shutdown(proc, str(tmp_path / "again.npz"))
        assert level == "info", text
    finally:
        proc.close()
    level, text = save_at_shutdown(proc, str(tmp_path / "late.npz"))  # a closed worker
    assert level == "error"
    assert "SLAM map not saved" in text
    assert not (tmp_path / "late.npz").exists()
    assert (a.keyframes, a.points) == (b.keyframes, b.points)
    assert a.keyframes >= 2
    first, second = _arrays(Path(a.npz)), _arrays(Path(b.npz))
    for key, value in first.items():
        np.testing.assert_array_equal(second[key], value, err_msg=key)  # bit for bit
    assert Path(b.ply).read_bytes() == Path(a.ply).read_bytes()


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_car_run_writes_the_slam_map(tmp_path: Path, domain: int) -> None:
    del domain  # VISNAV_DOMAIN: a private graph domain
    exe = shutil.which("visnav") or f"{sys.executable} -m visnav.cli.main"
    out = tmp_path / "run"
    cmd = [*exe.split(), "run", "car", "--duration", "8", "--out", str(out)]
    done = subprocess.run(
        cmd, check=False, capture_output=True, text=True, timeout=850, env=os.environ.copy()
    )
    assert done.returncode == 0, done.stderr[-3000:]
    saved = load_slam_map(out / "slam_map.npz")
    assert len(saved.map.keyframes) >= 2
    assert saved.camera.width > 0
    _, data = _read_ply(out / "slam_map.ply")
    assert len(data) > 100
    assert (out / "summary.json").is_file()
    assert (out / "map.yaml").is_file()
