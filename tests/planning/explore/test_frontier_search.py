"""explore_lite's frontier search on synthetic grids, cross-checked against a plain reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from visnav.planning.explore import (
    ExploreCostmap,
    FrontierSearchError,
    cost_translation_table,
    frontier_cost,
    occupancy_to_costs,
    search_frontiers,
)
from visnav.planning.explore.frontier_search import FREE_SPACE, LETHAL, NO_INFORMATION

RES = 0.1


def _grid(h: int, w: int) -> np.ndarray:
    return np.full((h, w), NO_INFORMATION, dtype=np.uint8)


def _centre(col: int, row: int) -> tuple[float, float]:
    return ((col + 0.5) * RES, (row + 0.5) * RES)


def test_translation_table_is_explore_lites() -> None:
    table = cost_translation_table()
    assert table[0] == 0
    assert table[99] == 253
    assert table[100] == 254
    assert table[255] == 255  # -1
    assert table[1] == 1
    assert table[50] == 1 + 251 * 49 // 97
    assert table[98] == 1 + 251 * 97 // 97
    assert np.all(np.diff(table[1:99].astype(int)) >= 0)
    data = np.array([-1, 0, 100, 99, 50], dtype=np.int8)
    assert occupancy_to_costs(data).tolist() == [255, 0, 254, 253, table[50]]


def test_free_square_in_unknown_is_one_ring_frontier() -> None:
    g = _grid(20, 30)
    g[5:15, 5:15] = FREE_SPACE  # 10 x 10 cells
    (f,) = search_frontiers(g, _centre(9, 9), resolution=RES, min_frontier_size=0.0)
    # the four sides (10 cells each); corner cells touch free space only diagonally
    assert f.size == 40
    assert f.points.shape == (40, 2)
    assert f.centroid == pytest.approx((1.0, 1.0))
    # the robot's cell (9, 9) is 5 cells from the west side (column 4)
    assert f.min_distance == pytest.approx(5 * RES)
    assert f.cost == pytest.approx(
        frontier_cost(40, 5 * RES, RES, potential_scale=1e-3, gain_scale=1.0)
    )
    assert f.cost == pytest.approx(1e-3 * 0.5 * RES - 40 * RES)
    # the search meets the frontier first beside the start cell's nearest side
    assert f.initial in [tuple(p) for p in f.points.tolist()]


def _corridor() -> np.ndarray:
    """A corridor of 4 rows from x=2 to x=40, open to unknown at both ends; the west end is
    1 cell wide (a door), the east end 4 cells."""
    g = _grid(10, 45)
    g[2:8, 1:42] = LETHAL
    g[3:7, 2:41] = FREE_SPACE
    g[3:6, 1] = LETHAL  # the west end is a 1-cell door at row 6
    g[6, 1] = FREE_SPACE
    g[3:7, 41] = FREE_SPACE  # east end: open 4-cell frontier at column 42
    return g


def test_sizes_costs_and_order() -> None:
    g = _corridor()
    robot = _centre(8, 4)
    found = search_frontiers(g, robot, resolution=RES, min_frontier_size=0.0)
    sizes = sorted(f.size for f in found)
    assert sizes == [1, 4]
    # default weights: the gain dominates, the bigger (far) frontier first
    assert found[0].size == 4
    assert found[0].centroid == pytest.approx(((42 + 0.5) * RES, 5.0 * RES))
    # a strong potential makes the near door cheaper
    near = search_frontiers(g, robot, resolution=RES, potential_scale=50.0, min_frontier_size=0.0)
    assert near[0].size == 1
    assert near[0].centroid == pytest.approx(_centre(0, 6))
    for f in near:
        assert f.cost == pytest.approx(50.0 * f.min_distance * RES - f.size * RES)


def test_min_frontier_size_in_metres() -> None:
    g = _corridor()
    robot = _centre(8, 4)
    kept = search_frontiers(g, robot, resolution=RES, min_frontier_size=0.4)
    assert [f.size for f in kept] == [4]
    assert search_frontiers(g, robot, resolution=RES, min_frontier_size=0.41) == []
    assert len(search_frontiers(g, robot, resolution=RES, min_frontier_size=0.1)) == 2


def test_walls_and_inflation_bound_the_search() -> None:
    g = _grid(12, 30)
    g[1:11, 1:29] = LETHAL
    g[2:10, 2:12] = FREE_SPACE  # the robot's room, closed
    g[2:10, 18:28] = FREE_SPACE  # another room with unknown inside
    g[5:7, 22:24] = NO_INFORMATION
    assert search_frontiers(g, _centre(5, 5), resolution=RES, min_frontier_size=0.0) == []
    # a passage of inflated cost: explore_lite's descending search does not enter it
    g[5, 12:18] = 120
    assert search_frontiers(g, _centre(5, 5), resolution=RES, min_frontier_size=0.0) == []
    g[5, 12:18] = FREE_SPACE
    (f,) = search_frontiers(g, _centre(5, 5), resolution=RES, min_frontier_size=0.0)
    assert f.size == 4
    assert f.centroid == pytest.approx((23.0 * RES, 6.0 * RES))


def test_start_from_the_nearest_free_cell_and_outside_is_an_error() -> None:
    g = _grid(10, 10)
    g[:, :5] = LETHAL
    g[:, 5:8] = FREE_SPACE  # frontier: column 8
    (f,) = search_frontiers(g, _centre(2, 5), resolution=RES, min_frontier_size=0.0)
    assert f.size == 10
    with pytest.raises(FrontierSearchError, match="outside the costmap"):
        search_frontiers(g, (-0.05, 0.5), resolution=RES)
    with pytest.raises(FrontierSearchError, match="outside the costmap"):
        search_frontiers(g, (0.5, 1.0), resolution=RES)
    with pytest.raises(FrontierSearchError, match="uint8"):
        search_frontiers(g.astype(np.int16), (0.5, 0.5), resolution=RES)
    # origin shifts the grid
    (f2,) = search_frontiers(
        g, (10.25, -4.45), resolution=RES, origin=(10.0, -5.0), min_frontier_size=0.0
    )
    assert f2.centroid == pytest.approx((10.0 + 8.5 * RES, -5.0 + 0.5))


def _reference(costs: np.ndarray, start: tuple[int, int]) -> list[frozenset[tuple[int, int]]]:
    """Frontier groups by a different route: the 4-connected free component of the start,
    the unknown cells with a free 4-neighbour (8-connected components), kept when one of
    their cells borders the component."""
    free = costs == FREE_SPACE
    labels, _ = ndimage.label(free)
    reach = labels == labels[start]
    four = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=bool)
    unknown = costs == NO_INFORMATION
    candidate = unknown & ndimage.binary_dilation(free, structure=four)
    seeds = unknown & ndimage.binary_dilation(reach, structure=four)
    groups, n = ndimage.label(candidate, structure=np.ones((3, 3), dtype=bool))
    out = []
    for k in range(1, n + 1):
        cells = groups == k
        if (cells & seeds).any():
            rows, cols = np.nonzero(cells)
            out.append(frozenset(zip(cols.tolist(), rows.tolist(), strict=True)))
    return out


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), unknown_share=st.floats(0.05, 0.6))
def test_matches_reference_on_random_grids(seed: int, unknown_share: float) -> None:
    rng = np.random.default_rng(seed)
    h, w = 24, 31
    draw = rng.random((h, w))
    g = np.where(draw < unknown_share, NO_INFORMATION, FREE_SPACE).astype(np.uint8)
    g[rng.random((h, w)) < 0.15] = LETHAL
    r, c = int(rng.integers(h)), int(rng.integers(w))
    g[r, c] = FREE_SPACE
    found = search_frontiers(g, _centre(c, r), resolution=RES, min_frontier_size=0.0)
    got = [frozenset((int(x / RES), int(y / RES)) for x, y in f.points.tolist()) for f in found]
    assert sorted(map(sorted, got)) == sorted(map(sorted, _reference(g, (r, c))))
    ref_x, ref_y = _centre(c, r)
    costs = [f.cost for f in found]
    assert costs == sorted(costs)
    for f in found:
        d = np.hypot(f.points[:, 0] - ref_x, f.points[:, 1] - ref_y)
        assert f.min_distance == pytest.approx(d.min())
        assert f.centroid == pytest.approx(tuple(f.points.mean(axis=0)))
        assert f.size == len(f.points)


def test_costmap_from_msg_and_partial_update() -> None:
    from visnav.msgs.construct import make
    from visnav.msgs.types import OccupancyGrid

    msg = make(OccupancyGrid)
    msg.header.frame_id = "map"
    msg.info.width, msg.info.height, msg.info.resolution = 4, 3, 0.05
    msg.info.origin.position.x, msg.info.origin.position.y = -1.0, 2.0
    msg.data = np.array([-1] * 6 + [0] * 5 + [100], dtype=np.int8)
    cm = ExploreCostmap.from_msg(msg)
    assert cm.costs.shape == (3, 4)
    assert cm.frame_id == "map"
    assert cm.origin == (-1.0, 2.0)
    assert cm.costs[0].tolist() == [255] * 4
    assert cm.costs[2].tolist() == [0, 0, 0, 254]
    assert cm.apply_update(1, 0, 2, 1, np.array([0, 99], dtype=np.int8)) == ""
    assert cm.costs[0].tolist() == [255, 0, 253, 255]
    note = cm.apply_update(3, 1, 2, 2, np.array([100, 100, 100, 100], dtype=np.int8))
    assert "only the part inside" in note
    assert cm.costs[1:, 3].tolist() == [254, 254]
    assert "negative" in cm.apply_update(-1, 0, 1, 1, np.array([0], dtype=np.int8))
    msg.data = np.zeros(5, dtype=np.int8)
    with pytest.raises(FrontierSearchError, match="width \\* height"):
        ExploreCostmap.from_msg(msg, topic="map")
