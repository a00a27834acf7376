"""Synthetic RGB-D sequences with exact ground truth, rendered without a simulator.

:class:`SyntheticRoom` is a closed box room whose six walls carry seeded random
textures (shapes, lines and noise at several scales, distinct per wall). Images
are ray cast in numpy: each pixel's ray hits the box from the inside in closed
form, the wall texture is sampled with one ``cv2.remap`` on a texture atlas, and
the depth is exact. :func:`circle_trajectory` moves a camera around a loop, and
:func:`write_tum_folder` writes a TUM RGB-D style folder (``rgb/``, ``depth/``,
``rgb.txt``, ``depth.txt``, ``groundtruth.txt``, ``camera_info.yaml``).

Used by the SLAM tests and benchmark, and handy to try the SLAM CLI.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs import CameraInfo, make
from visnav.perception.camera_info_yaml import write_camera_info_yaml
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.trajectory import Trajectory, write_tum

__all__ = [
    "SyntheticRoom",
    "camera_info_for",
    "circle_trajectory",
    "look_at",
    "write_tum_folder",
]

FloatArray = NDArray[np.float64]


def _texture(rng: np.random.Generator, height: int, width: int) -> NDArray[np.uint8]:
    """Random polygons (sharp corners, like posters and furniture) on a mid-grey ground."""
    base = rng.random((max(height // 32, 2), max(width // 32, 2))).astype(np.float32)
    img = cv2.resize(base, (width, height), interpolation=cv2.INTER_LINEAR) * 40.0 + 100.0
    img = np.clip(img, 0, 255).astype(np.uint8)
    n_shapes = int(height * width / 700)
    for _ in range(n_shapes):
        colour = int(rng.integers(0, 256))
        cx, cy = rng.uniform(0, width), rng.uniform(0, height)
        n = int(rng.integers(3, 6))
        radius = rng.uniform(4.0, 18.0)
        angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, n))
        pts = np.stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)], axis=1)
        cv2.fillPoly(img, [np.rint(pts).astype(np.int32)], colour, lineType=cv2.LINE_AA)
    out: NDArray[np.uint8] = img
    return out


class SyntheticRoom:
    """A textured box room, ``[0, size_x] x [0, size_y] x [0, size_z]`` metres (z up).

    Args:
        size: room extent (m).
        seed: seeds the wall textures.
        texels_per_metre: texture resolution.
    """

    def __init__(
        self,
        size: tuple[float, float, float] = (8.0, 6.0, 3.0),
        *,
        seed: int = 0,
        texels_per_metre: float = 120.0,
    ) -> None:
        self.size = np.asarray(size, dtype=np.float64)
        self.texels_per_metre = float(texels_per_metre)
        rng = np.random.default_rng(seed)
        # wall a (axis) side s (0 min, 1 max) uses texture coords of the other two axes
        self._walls: list[tuple[int, int, int, int]] = []
        dims: list[tuple[int, int]] = []
        for axis in range(3):
            u_axis, v_axis = [a for a in range(3) if a != axis]
            for side in (0, 1):
                self._walls.append((axis, side, u_axis, v_axis))
                w = int(np.ceil(self.size[u_axis] * self.texels_per_metre)) + 2
                h = int(np.ceil(self.size[v_axis] * self.texels_per_metre)) + 2
                dims.append((h, w))
        self._tile_h = max(h for h, _ in dims)
        self._tile_w = max(w for _, w in dims)
        atlas = np.zeros((self._tile_h * 6, self._tile_w), dtype=np.uint8)
        for i, (h, w) in enumerate(dims):
            atlas[i * self._tile_h : i * self._tile_h + h, :w] = _texture(rng, h, w)
        self.atlas = atlas

    def render(
        self,
        cam: CameraIntrinsics,
        t_wc: FloatArray,
        *,
        supersample: int = 2,
    ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """Render the view of a camera at ``T_world_camera`` (optical frame).

        Args:
            cam: intrinsics (image size).
            t_wc: 4x4 camera pose; the camera must be inside the room.
            supersample: anti-aliasing factor for the colour image.

        Returns:
            ``(rgb (H, W, 3) uint8, depth (H, W) float32 metres along the optical axis)``.
        """
        gray = self._cast(cam, t_wc, supersample, want_depth=False)[0]
        if supersample > 1:
            gray = np.asarray(
                cv2.resize(gray, (cam.width, cam.height), interpolation=cv2.INTER_AREA),
                dtype=np.uint8,
            )
        _, depth = self._cast(cam, t_wc, 1, want_depth=True)
        rgb = np.repeat(gray[:, :, None], 3, axis=2)
        return rgb, depth

    def _cast(
        self, cam: CameraIntrinsics, t_wc: FloatArray, ss: int, *, want_depth: bool
    ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        w, h = cam.width * ss, cam.height * ss
        u = ((np.arange(w, dtype=np.float32) + 0.5) / ss - 0.5 - cam.cx) / cam.fx
        v = ((np.arange(h, dtype=np.float32) + 0.5) / ss - 0.5 - cam.cy) / cam.fy
        r = t_wc[:3, :3].astype(np.float32)
        o = t_wc[:3, 3]
        # world direction of each pixel's ray, scaled to unit optical depth
        d = [r[i, 0] * u[None, :] + r[i, 1] * v[:, None] + r[i, 2] for i in range(3)]
        t_axes = []
        for i in range(3):
            with np.errstate(divide="ignore", invalid="ignore"):
                ti = np.where(d[i] > 0, (self.size[i] - o[i]) / d[i], -o[i] / d[i])
            ti[~(ti > 0)] = np.inf
            t_axes.append(ti.astype(np.float32))
        t = np.minimum(t_axes[0], np.minimum(t_axes[1], t_axes[2]))
        if want_depth:
            return np.zeros((0, 0), dtype=np.uint8), t
        p = [o[i] + d[i] * t for i in range(3)]
        map_x = np.zeros((h, w), dtype=np.float32)
        map_y = np.zeros((h, w), dtype=np.float32)
        s = self.texels_per_metre
        for axis in range(3):
            hit = t_axes[axis] <= t
            ua, va = [a for a in range(3) if a != axis]
            positive = d[axis] > 0
            wall = np.where(positive, axis * 2 + 1, axis * 2)
            map_x = np.where(hit, p[ua] * s, map_x)
            map_y = np.where(hit, p[va] * s + wall * self._tile_h, map_y)
        img = cv2.remap(
            self.atlas,
            map_x.astype(np.float32),
            map_y.astype(np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REFLECT,
        )
        return np.asarray(img, dtype=np.uint8), t


def look_at(position: FloatArray, target: FloatArray) -> FloatArray:
    """``T_world_camera`` of an optical camera at ``position`` looking at ``target`` (z up)."""
    z = np.asarray(target, float) - np.asarray(position, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2] = x, y, z
    t[:3, 3] = position
    return t


def circle_trajectory(
    n_frames: int,
    *,
    centre: tuple[float, float] = (4.0, 3.0),
    radius: float = 1.2,
    height: float = 1.3,
    turns: float = 1.0,
    look_offset_deg: float = 60.0,
    wobble: float = 0.05,
) -> FloatArray:
    """Camera poses (N, 4, 4) moving on a horizontal circle, looking outward-forward.

    The camera looks ``look_offset_deg`` away from the outward radial direction
    toward the direction of travel, bobs ``wobble`` metres vertically, and after
    ``turns = 1`` comes back to its start (a loop).
    """
    out = np.zeros((n_frames, 4, 4))
    for i in range(n_frames):
        a = 2.0 * np.pi * turns * i / max(n_frames, 1)
        pos = np.array(
            [
                centre[0] + radius * np.cos(a),
                centre[1] + radius * np.sin(a),
                height + wobble * np.sin(3 * a),
            ]
        )
        look = a + np.radians(look_offset_deg)
        target = pos + np.array([np.cos(look), np.sin(look), 0.05 * np.cos(2 * a)])
        out[i] = look_at(pos, target)
    return out


def camera_info_for(cam: CameraIntrinsics, *, frame_id: str = "camera_optical_frame") -> object:
    """A ``sensor_msgs/CameraInfo`` describing ``cam`` (no distortion)."""
    k = [cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0]
    p = [cam.fx, 0.0, cam.cx, 0.0, 0.0, cam.fy, cam.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    info: object = make(
        CameraInfo,
        width=cam.width,
        height=cam.height,
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=np.array(k),
        r=np.eye(3).reshape(-1),
        p=np.array(p),
    )
    info.header.frame_id = frame_id  # type: ignore[attr-defined]
    return info


def write_tum_folder(
    path: str | Path,
    room: SyntheticRoom,
    cam: CameraIntrinsics,
    poses: FloatArray,
    *,
    rate_hz: float = 30.0,
    start_s: float = 1000.0,
    depth_scale: float = 5000.0,
    depth_offset_s: float = 0.0,
    write_camera_info: bool = True,
) -> Path:
    """Render ``poses`` and write a TUM RGB-D style folder; return its path.

    Args:
        path: output folder.
        room: the scene.
        cam: intrinsics.
        poses: (N, 4, 4) ``T_world_camera``.
        rate_hz: frame rate of the stamps.
        start_s: first stamp (s).
        depth_scale: uint16 units per metre of the depth PNGs (TUM: 5000).
        depth_offset_s: added to the depth stamps (to test association).
        write_camera_info: also write ``camera_info.yaml`` (TUM folders have none).
    """
    out = Path(path)
    (out / "rgb").mkdir(parents=True, exist_ok=True)
    (out / "depth").mkdir(parents=True, exist_ok=True)
    rgb_lines = ["# color images", "# timestamp filename"]
    depth_lines = ["# depth maps", "# timestamp filename"]
    stamps = start_s + np.arange(len(poses)) / rate_hz
    for t, pose in zip(stamps, poses, strict=True):
        rgb, depth = room.render(cam, pose)
        name = f"{t:.6f}.png"
        cv2.imwrite(str(out / "rgb" / name), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        d16 = np.clip(np.rint(np.nan_to_num(depth) * depth_scale), 0, 65535).astype(np.uint16)
        td = t + depth_offset_s
        cv2.imwrite(str(out / "depth" / f"{td:.6f}.png"), d16)
        rgb_lines.append(f"{t:.6f} rgb/{name}")
        depth_lines.append(f"{td:.6f} depth/{td:.6f}.png")
    (out / "rgb.txt").write_text("\n".join(rgb_lines) + "\n", encoding="utf-8")
    (out / "depth.txt").write_text("\n".join(depth_lines) + "\n", encoding="utf-8")
    write_tum(
        out / "groundtruth.txt",
        Trajectory.from_matrices(stamps, poses),
        header="ground truth: timestamp tx ty tz qx qy qz qw",
    )
    if write_camera_info:
        info = camera_info_for(cam)
        assert isinstance(info, CameraInfo)
        write_camera_info_yaml(out / "camera_info.yaml", info, camera_name="synthetic")
    return out
