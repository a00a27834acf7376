"""The compiled search_by_projection gives the numpy reference's matches, ties included."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.slam.features import Frame
from visnav.slam.geometry import se3_exp
from visnav.slam.matching import search_by_projection

from ._projection_reference import search_by_projection_numpy
from .conftest import SMALL


def _scene(seed: int, n_points: int, n_kp: int) -> tuple[Frame, np.ndarray, np.ndarray]:
    """Map points seen by a camera at the origin, keypoints near their projections."""
    rng = np.random.default_rng(seed)
    cam = SMALL
    z = rng.uniform(0.5, 6.0, n_points)
    u = rng.uniform(-20, cam.width + 20, n_points)
    v = rng.uniform(-20, cam.height + 20, n_points)
    points = np.stack([(u - cam.cx) * z / cam.fx, (v - cam.cy) * z / cam.fy, z], axis=1)
    descriptors = rng.integers(0, 256, (n_points, 32), dtype=np.uint8)
    twins = n_points // 8  # points twice in the map: they tie for the same keypoint
    descriptors[twins : 2 * twins] = descriptors[:twins]
    points[twins : 2 * twins] = points[:twins] * 1.001
    src = rng.integers(0, n_points, n_kp)  # keypoints copy points' descriptors, a few bits off
    kp_uv = np.stack([u[src], v[src]], axis=1) + rng.normal(0, 4.0, (n_kp, 2))
    kp_desc = descriptors[src].copy()
    flips = rng.integers(0, 32, (n_kp, 3))
    for j in range(3):
        kp_desc[np.arange(n_kp), flips[:, j]] ^= rng.integers(0, 256, n_kp, dtype=np.uint8)
    kp_desc[: n_kp // 8] = kp_desc[n_kp // 8 : 2 * (n_kp // 8)]  # exact ties in distance
    octave = rng.integers(0, 4, n_kp)
    depth = z[src] * rng.uniform(0.9, 1.1, n_kp)
    depth[rng.random(n_kp) < 0.3] = np.nan
    frame = Frame(
        stamp_ns=0,
        uv=kp_uv,
        octave=octave,
        descriptors=kp_desc,
        depth=depth,
        u_right=np.full(n_kp, np.nan),
        points_c=np.full((n_kp, 3), np.nan),
        inv_sigma2=1.0 / 1.2 ** (2 * octave),
    )
    return frame, points, descriptors


@pytest.mark.parametrize(
    ("seed", "kwargs"),
    [
        (0, {}),
        (1, {"radius": 30.0}),
        (2, {"ratio": 1.0, "max_distance": 60}),
        (3, {"depth_tolerance": 0.02}),
        (4, {"available": "half"}),
    ],
)
def test_compiled_matches_are_the_numpy_matches(seed: int, kwargs: dict[str, object]) -> None:
    frame, points, desc = _scene(seed, 400, 300)
    if kwargs.get("available") == "half":
        kwargs = {**kwargs, "available": np.arange(len(frame)) % 2 == 0}
    t_cw = se3_exp(np.array([0.01, -0.02, 0.0, 0.002, 0.003, -0.001]))
    want = search_by_projection_numpy(frame, SMALL, t_cw, points, desc, **kwargs)  # type: ignore[arg-type]
    got = search_by_projection(frame, SMALL, t_cw, points, desc, **kwargs)  # type: ignore[arg-type]
    assert len(want[0]) > 20  # the scene makes matches
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n_points=st.integers(0, 60), n_kp=st.integers(0, 60))
def test_compiled_matches_any_small_scene(seed: int, n_points: int, n_kp: int) -> None:
    frame, points, desc = _scene(seed, max(n_points, 1), max(n_kp, 1))
    points, desc = points[:n_points], desc[:n_points]
    t_cw = np.eye(4)
    want = search_by_projection_numpy(frame, SMALL, t_cw, points, desc, radius=25.0)
    got = search_by_projection(frame, SMALL, t_cw, points, desc, radius=25.0)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
