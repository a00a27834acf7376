"""The 3D grid map: log-odds steps, ray casting, depth filter, inflation, virtual layers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from visnav.mapping.grid_map import GridMap, GridMapError, GridMapParams, logit

SMALL = GridMapParams(map_size=(10.0, 10.0, 3.0))
# camera at (0, 0, 1) looking along +x (optical z -> world x, x -> -y, y -> -z)
R_WORLD_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _camera(position: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = R_WORLD_OPTICAL
    pose[:3, 3] = position
    return pose


def _log_odds(gm: GridMap, point: tuple[float, float, float]) -> float:
    i, j, k = gm.pos_to_index(point)
    return float(gm.log_odds[i, j, k])


def test_log_odds_steps_match_hand_computed_values() -> None:
    gm = GridMap(SMALL)
    hit, miss = math.log(0.65 / 0.35), math.log(0.35 / 0.65)
    lo, hi, occ = math.log(0.12 / 0.88), math.log(0.9 / 0.1), math.log(0.8 / 0.2)
    assert gm.log_hit == pytest.approx(hit)
    assert gm.log_miss == pytest.approx(miss)
    assert (gm.clamp_min, gm.clamp_max, gm.occupied_log) == pytest.approx((lo, hi, occ))
    target = (3.05, 0.05, 1.05)  # a voxel centre
    free = (1.55, 0.05, 1.05)  # on the ray, between sensor and target
    unknown = lo - 0.01
    assert _log_odds(gm, target) == pytest.approx(unknown)
    expected = unknown
    for n in range(1, 9):
        gm.update_from_points([target], sensor_origin=(0.05, 0.05, 1.05))
        expected = min(max(expected + hit, lo), hi)
        assert _log_odds(gm, target) == pytest.approx(expected, abs=1e-6)
        # unknown + 6 hits = 1.712 > logit(0.8) = 1.386; 5 hits = 1.093 is not enough
        assert gm.occupancy([target])[0] == (1 if n >= 6 else 0)
        # a miss from unknown (below the clamp) lands exactly on logit(p_min)
        assert _log_odds(gm, free) == pytest.approx(lo, abs=1e-6)
    assert expected == pytest.approx(hi)  # clamped at logit(p_max)


def test_ray_casting_clears_space_that_was_occupied() -> None:
    gm = GridMap(SMALL)
    blocker = (1.55, 0.05, 1.05)
    assert gm.mark_occupied([blocker]) == 1
    assert gm.occupancy([blocker])[0] == 1
    assert gm.inflate_occupancy([blocker])[0]
    wall = (3.05, 0.05, 1.05)
    gm.update_from_points([wall], sensor_origin=(0.05, 0.05, 1.05))
    # p_max (2.197) minus one miss (0.619) = 1.578: still above logit(0.8)
    assert _log_odds(gm, blocker) == pytest.approx(gm.clamp_max + gm.log_miss, abs=1e-6)
    assert gm.occupancy([blocker])[0] == 1
    gm.update_from_points([wall], sensor_origin=(0.05, 0.05, 1.05))
    assert gm.occupancy([blocker])[0] == 0
    assert not gm.inflate_occupancy([blocker])[0]  # its inflation went with it


def test_rays_longer_than_max_ray_length_only_clear() -> None:
    gm = GridMap(GridMapParams(map_size=(10.0, 10.0, 3.0), max_ray_length=2.0))
    far = (3.05, 0.05, 1.05)
    for _ in range(8):
        gm.update_from_points([far], sensor_origin=(0.05, 0.05, 1.05))
    assert gm.occupancy([far])[0] == 0
    assert _log_odds(gm, far) < gm.clamp_min  # never touched: still unknown
    # the cut end (2 m from the sensor) and the voxels before it are known free
    assert _log_odds(gm, (2.0, 0.05, 1.05)) == pytest.approx(gm.clamp_min, abs=1e-6)
    assert _log_odds(gm, (1.0, 0.05, 1.05)) == pytest.approx(gm.clamp_min, abs=1e-6)


def test_inflation_is_a_cube_of_ceil_inflation_over_resolution_voxels() -> None:
    for inflation, step in ((0.099, 1), (0.2, 2), (0.0, 0)):
        params = GridMapParams(
            map_size=(10.0, 10.0, 3.0),
            obstacles_inflation=inflation,
            virtual_ceil_height=-1.0,
            virtual_ground_height=None,
        )
        gm = GridMap(params)
        gm.mark_occupied([(0.05, 0.05, 1.05)])
        inflated = np.argwhere(gm.inflated)
        centre = gm.pos_to_index((0.05, 0.05, 1.05))
        assert len(inflated) == (2 * step + 1) ** 3
        assert np.abs(inflated - centre).max() == step


def test_virtual_ceiling_ground_and_outside_of_map() -> None:
    gm = GridMap(SMALL)
    gm.mark_occupied([(0.05, 0.05, 1.05)])
    ceiling = (0.05, 0.05, 2.55)  # virtual_ceil_height 2.5 -> the layer [2.49, 2.59)
    ground = (0.05, 0.05, 0.0)  # virtual_ground_height -0.01 -> the bottom layer
    assert gm.inflate_occupancy([ceiling, ground, (0.05, 0.05, 1.5)]).tolist() == [
        True,
        True,
        False,
    ]
    assert gm.occupancy([ceiling])[0] == 0  # virtual layers are not log-odds obstacles
    outside = [(0.0, 0.0, -0.5), (0.0, 0.0, 3.5), (6.0, 0.0, 1.0)]
    assert gm.inflate_occupancy(outside).all()
    assert (gm.occupancy(outside) == -1).all()
    assert not gm.is_in_map(outside).any()


def test_depth_image_of_a_wall() -> None:
    gm = GridMap(SMALL)
    depth = np.full((48, 64), 3.0, np.float32)
    intrinsics = (40.0, 40.0, 32.0, 24.0)
    for _ in range(6):
        result = gm.update_from_depth(depth, intrinsics=intrinsics, T_world_camera=_camera())
    assert result is not None
    assert result.rays == 22 * 30  # margin 2, every second pixel
    cells = gm.occupied_cells()
    assert len(cells) > 20
    # the wall is the plane x = 3 m (voxel [3.0, 3.1))
    assert np.allclose(cells[:, 0], 3.05)
    assert gm.occupancy([(1.5, 0.0, 1.0)])[0] == 0
    assert _log_odds(gm, (1.55, 0.05, 1.05)) == pytest.approx(gm.clamp_min, abs=1e-6)
    # 16UC1 millimetres give the same map
    gm16 = GridMap(SMALL)
    for _ in range(6):
        gm16.update_from_depth(
            (depth * 1000).astype(np.uint16), intrinsics=intrinsics, T_world_camera=_camera()
        )
    assert np.array_equal(gm16.log_odds, gm.log_odds)


def test_depth_filter() -> None:
    intrinsics = (40.0, 40.0, 32.0, 24.0)
    depth = np.zeros((48, 64), np.float32)  # no return anywhere
    gm = GridMap(SMALL)
    gm.mark_occupied([(2.05, 0.05, 1.05)])
    for _ in range(3):
        gm.update_from_depth(depth, intrinsics=intrinsics, T_world_camera=_camera())
    # no return = a free ray of max_ray_length: clears the voxel 2 m ahead
    assert gm.occupancy([(2.05, 0.05, 1.05)])[0] == 0
    assert len(gm.occupied_cells()) == 0
    near = np.full((48, 64), 0.1, np.float32)  # nearer than depth_filter_mindist: dropped
    result = gm.update_from_depth(near, intrinsics=intrinsics, T_world_camera=_camera())
    assert result is not None
    assert result.rays == 0
    far = np.full((48, 64), 6.0, np.float32)  # beyond depth_filter_maxdist: free ray
    for _ in range(6):
        gm.update_from_depth(far, intrinsics=intrinsics, T_world_camera=_camera())
    assert len(gm.occupied_cells()) == 0
    unfiltered = GridMap(
        GridMapParams(map_size=(10.0, 10.0, 3.0), use_depth_filter=False, max_ray_length=8.0)
    )
    res = unfiltered.update_from_depth(far, intrinsics=intrinsics, T_world_camera=_camera())
    assert res is not None
    assert res.rays == 48 * 64  # every pixel, as measured


def test_local_update_range_forgets_far_voxels() -> None:
    params = GridMapParams(map_size=(20.0, 20.0, 3.0), local_update_range=(2.0, 2.0, 2.0))
    gm = GridMap(params)
    wall = (4.05, 0.05, 1.05)  # within max_ray_length, outside +-2 m of the sensor
    for _ in range(8):
        gm.update_from_points([wall], sensor_origin=(0.05, 0.05, 1.05))
    # each update resets it to logit(p_min) first: one hit never makes it occupied
    assert _log_odds(gm, wall) == pytest.approx(gm.clamp_min + gm.log_hit, abs=1e-6)
    assert gm.occupancy([wall])[0] == 0


def test_sensor_outside_the_map_skips_the_update() -> None:
    gm = GridMap(SMALL)
    assert gm.update_from_points([(0.0, 0.0, 1.0)], sensor_origin=(0.0, 0.0, 5.0)) is None
    assert gm.update_count == 0


def test_invalid_inputs_are_reported() -> None:
    with pytest.raises(GridMapError, match="p_occ"):
        GridMapParams(p_occ=0.95)
    with pytest.raises(GridMapError, match="resolution"):
        GridMapParams(resolution=0.0)
    gm = GridMap(SMALL)
    with pytest.raises(GridMapError, match="depth image"):
        gm.update_from_depth(np.zeros((4, 4, 3)), intrinsics=(1, 1, 1, 1), T_world_camera=np.eye(4))
    with pytest.raises(GridMapError, match="4x4"):
        gm.update_from_depth(np.zeros((4, 4)), intrinsics=(1, 1, 1, 1), T_world_camera=np.eye(3))
    with pytest.raises(GridMapError, match=r"\(N, 3\)"):
        gm.inflate_occupancy(np.zeros((4, 2)))
    assert logit(0.5) == 0.0
