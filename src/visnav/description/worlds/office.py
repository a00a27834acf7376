"""``office``: ten furnished rooms around a corridor loop, 20 x 15 m, textured everywhere.

Layout (x right, y up, metres; walls 0.15 m thick and 2.5 m high, doors 1.2 m wide)::

    y= 7.5 +----------------+-----------------+----------------+
           |  N1            |  N2             |  N3            |
    y= 4.0 +-----+---d------+--------d--------+------d---+-----+
           |     |        corridor (2 m wide, a loop)    |     |
    y= 2.0 |  W  |   +-----d-------+-------------+       |  E  |
           |     d   |  C1         |  C2         |       d     |
    y=-2.0 |     |   +-------------+-------d-----+       |     |
           |     |                                       |     |
    y=-4.0 +-----+---d------+--------d--------+------d---+-----+
           |  S1            |  S2             |  S3            |
    y=-7.5 +----------------+-----------------+----------------+
         x=-10  -7  -5               0               5   7    10

Every wall segment (at most 4 m long), poster, piece of furniture and the floor
carries its own seeded procedural texture, so a camera sees visual features
wherever it looks; the layout is fixed and only colours and textures change
with the seed. ``metadata`` records the rooms (centre, bounds, door), the
corridor rectangles, a spawn pose and a free-space graph (nodes in corridor,
doorways and room centres; edges are straight, collision-free segments) that a
planner or a test can follow.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from visnav.description.worlds._params import Params, random_colour

__all__ = ["DEFAULTS", "generate"]

DEFAULTS: dict[str, Any] = {}

WALL_T = 0.15
WALL_H = 2.5
DOOR_W = 1.2
DOOR_H = 2.1
MAX_SEGMENT = 4.0

# (runs along, fixed coordinate, start, end, door centres along the run)
_WALLS: tuple[tuple[str, float, float, float, tuple[float, ...]], ...] = (
    ("x", -7.5, -10.0, 10.0, ()),
    ("x", 7.5, -10.0, 10.0, ()),
    ("y", -10.0, -7.5, 7.5, ()),
    ("y", 10.0, -7.5, 7.5, ()),
    ("x", 4.0, -10.0, 10.0, (-5.5, 0.0, 5.5)),
    ("x", -4.0, -10.0, 10.0, (-5.5, 0.0, 5.5)),
    ("y", -3.5, 4.0, 7.5, ()),
    ("y", 3.5, 4.0, 7.5, ()),
    ("y", -3.5, -7.5, -4.0, ()),
    ("y", 3.5, -7.5, -4.0, ()),
    ("y", -7.0, -4.0, 4.0, (0.0,)),
    ("y", 7.0, -4.0, 4.0, (0.0,)),
    ("x", 2.0, -5.0, 5.0, (-2.5,)),
    ("x", -2.0, -5.0, 5.0, (2.5,)),
    ("y", -5.0, -2.0, 2.0, ()),
    ("y", 5.0, -2.0, 2.0, ()),
    ("y", 0.0, -2.0, 2.0, ()),
)


@dataclass(frozen=True)
class _Room:
    name: str
    bounds: tuple[float, float, float, float]
    door: tuple[float, float]
    door_side: str
    kind: str

    @property
    def centre(self) -> tuple[float, float]:
        x0, y0, x1, y1 = self.bounds
        return (0.5 * (x0 + x1), 0.5 * (y0 + y1))


_ROOMS: tuple[_Room, ...] = (
    _Room("N1", (-10.0, 4.0, -3.5, 7.5), (-5.5, 4.0), "s", "office"),
    _Room("N2", (-3.5, 4.0, 3.5, 7.5), (0.0, 4.0), "s", "meeting"),
    _Room("N3", (3.5, 4.0, 10.0, 7.5), (5.5, 4.0), "s", "office"),
    _Room("S1", (-10.0, -7.5, -3.5, -4.0), (-5.5, -4.0), "n", "lounge"),
    _Room("S2", (-3.5, -7.5, 3.5, -4.0), (0.0, -4.0), "n", "office"),
    _Room("S3", (3.5, -7.5, 10.0, -4.0), (5.5, -4.0), "n", "meeting"),
    _Room("W", (-10.0, -4.0, -7.0, 4.0), (-7.0, 0.0), "e", "storage"),
    _Room("E", (7.0, -4.0, 10.0, 4.0), (7.0, 0.0), "w", "lounge"),
    _Room("C1", (-5.0, -2.0, 0.0, 2.0), (-2.5, 2.0), "n", "office"),
    _Room("C2", (0.0, -2.0, 5.0, 2.0), (2.5, -2.0), "s", "meeting"),
)

# Free-space graph: corridor nodes, the corridor point in front of each door,
# each doorway and each room centre.
_CORRIDOR_NODES: dict[str, tuple[float, float]] = {
    "corr_nw": (-6.0, 3.0),
    "corr_n": (0.0, 3.0),
    "corr_ne": (6.0, 3.0),
    "corr_e": (6.0, 0.0),
    "corr_se": (6.0, -3.0),
    "corr_s": (0.0, -3.0),
    "corr_sw": (-6.0, -3.0),
    "corr_w": (-6.0, 0.0),
    "front_N1": (-5.5, 3.0),
    "front_C1": (-2.5, 3.0),
    "front_N3": (5.5, 3.0),
    "front_S3": (5.5, -3.0),
    "front_C2": (2.5, -3.0),
    "front_S1": (-5.5, -3.0),
}
_CORRIDOR_LOOP = (
    "corr_nw",
    "front_N1",
    "front_C1",
    "corr_n",
    "front_N3",
    "corr_ne",
    "corr_e",
    "corr_se",
    "front_S3",
    "front_C2",
    "corr_s",
    "front_S1",
    "corr_sw",
    "corr_w",
    "corr_nw",
)
_ROOM_FRONT = {
    "N1": "front_N1",
    "N2": "corr_n",
    "N3": "front_N3",
    "S1": "front_S1",
    "S2": "corr_s",
    "S3": "front_S3",
    "W": "corr_w",
    "E": "corr_e",
    "C1": "front_C1",
    "C2": "front_C2",
}
_CORRIDORS = {
    "north": [-7.0, 2.0, 7.0, 4.0],
    "south": [-7.0, -4.0, 7.0, -2.0],
    "west": [-7.0, -4.0, -5.0, 4.0],
    "east": [5.0, -4.0, 7.0, 4.0],
}


class _Builder:
    """Accumulates objects, textures and materials with seeded colours."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.objects: list[dict[str, Any]] = []
        self.textures: dict[str, Any] = {}
        self.materials: dict[str, Any] = {}

    def texture(
        self,
        name: str,
        *,
        hue: tuple[float, float],
        sat: tuple[float, float],
        light: tuple[float, float],
        dark: tuple[float, float],
        tile: float,
        scale: int = 16,
        size: int = 256,
        checker: bool = False,
    ) -> str:
        rng = self.rng
        rgb1 = random_colour(rng, hue=hue, sat=sat, val=light)
        rgb2 = random_colour(rng, hue=(hue[0] + 0.3, hue[1] + 0.3), sat=sat, val=dark)
        if checker:
            self.textures[name] = {
                "type": "checker",
                "rgb1": rgb1,
                "rgb2": rgb2,
                "width": size,
                "height": size,
                "mark": "random",
                "random": 0.05,
                "markrgb": [0.95, 0.95, 0.95],
            }
        else:
            self.textures[name] = {
                "type": "noise",
                "rgb1": rgb1,
                "rgb2": rgb2,
                "width": size,
                "height": size,
                "scale": scale,
                "seed": int(rng.integers(2**31)),
            }
        self.materials[name] = {"texture": name, "tile": tile, "specular": 0.1}
        return name

    def box(
        self,
        name: str,
        pos: tuple[float, float, float],
        size: tuple[float, float, float],
        *,
        yaw: float = 0.0,
        material: str,
        collision: bool = True,
    ) -> None:
        obj: dict[str, Any] = {
            "type": "box",
            "name": name,
            "pos": [round(v, 4) for v in pos],
            "size": [round(v, 4) for v in size],
            "material": material,
        }
        if yaw:
            obj["yaw"] = round(yaw, 6)
        if not collision:
            obj["collision"] = False
        self.objects.append(obj)

    def cylinder(
        self,
        name: str,
        pos: tuple[float, float, float],
        radius: float,
        length: float,
        *,
        material: str,
    ) -> None:
        self.objects.append(
            {
                "type": "cylinder",
                "name": name,
                "pos": [round(v, 4) for v in pos],
                "radius": radius,
                "length": length,
                "material": material,
            }
        )

    def sphere(
        self, name: str, pos: tuple[float, float, float], radius: float, *, material: str
    ) -> None:
        self.objects.append(
            {
                "type": "sphere",
                "name": name,
                "pos": [round(v, 4) for v in pos],
                "radius": radius,
                "material": material,
            }
        )


def _split(start: float, end: float, doors: tuple[float, ...]) -> list[tuple[float, float]]:
    pieces: list[tuple[float, float]] = []
    cursor = start
    for door in sorted(doors):
        pieces.append((cursor, door - DOOR_W / 2))
        cursor = door + DOOR_W / 2
    pieces.append((cursor, end))
    out: list[tuple[float, float]] = []
    for a, b in pieces:
        n = max(1, math.ceil((b - a) / MAX_SEGMENT - 1e-9))
        out.extend((a + (b - a) * i / n, a + (b - a) * (i + 1) / n) for i in range(n))
    return out


def _walls(b: _Builder) -> None:
    count = 0
    for along, fixed, start, end, doors in _WALLS:
        mat = ""
        for a, c in _split(start - WALL_T / 2, end + WALL_T / 2, doors):
            name = f"wall_{count}"
            count += 1
            mat = b.texture(
                name,
                hue=(0.0, 1.0),
                sat=(0.15, 0.6),
                light=(0.7, 0.95),
                dark=(0.2, 0.45),
                tile=1.5,
                scale=int(b.rng.choice([8, 16, 32])),
                checker=count % 5 == 0,
            )
            mid = 0.5 * (a + c)
            pos = (mid, fixed, WALL_H / 2) if along == "x" else (fixed, mid, WALL_H / 2)
            b.box(
                name,
                pos,
                (c - a, WALL_T, WALL_H),
                yaw=0.0 if along == "x" else math.pi / 2,
                material=mat,
            )
        for door in doors:
            name = f"lintel_{count}"
            count += 1
            height = WALL_H - DOOR_H
            pos = (
                (door, fixed, DOOR_H + height / 2)
                if along == "x"
                else (fixed, door, DOOR_H + height / 2)
            )
            b.box(
                name,
                pos,
                (DOOR_W, WALL_T, height),
                yaw=0.0 if along == "x" else math.pi / 2,
                material=mat,
            )


_POSTERS: tuple[tuple[float, float, float], ...] = (
    # x, y, yaw of the poster's outward normal (the corridor side of the wall)
    (-3.0, 4.0 - WALL_T / 2, -math.pi / 2),
    (2.8, 4.0 - WALL_T / 2, -math.pi / 2),
    (-2.8, -4.0 + WALL_T / 2, math.pi / 2),
    (3.0, -4.0 + WALL_T / 2, math.pi / 2),
    (-7.0 + WALL_T / 2, 2.2, 0.0),
    (-7.0 + WALL_T / 2, -2.0, 0.0),
    (7.0 - WALL_T / 2, -2.2, math.pi),
    (7.0 - WALL_T / 2, 2.0, math.pi),
    (1.5, 2.0 + WALL_T / 2, math.pi / 2),
    (3.6, 2.0 + WALL_T / 2, math.pi / 2),
    (-1.5, -2.0 - WALL_T / 2, -math.pi / 2),
    (-3.6, -2.0 - WALL_T / 2, -math.pi / 2),
    (-5.0 - WALL_T / 2, 0.0, math.pi),
    (5.0 + WALL_T / 2, 0.0, 0.0),
)


def _poster(b: _Builder, name: str, x: float, y: float, normal_yaw: float) -> None:
    mat = b.texture(
        name,
        hue=(0.0, 1.0),
        sat=(0.5, 0.9),
        light=(0.8, 1.0),
        dark=(0.05, 0.3),
        tile=0.6,
        scale=8,
        size=128,
    )
    depth = 0.02
    cx = x + math.cos(normal_yaw) * depth / 2
    cy = y + math.sin(normal_yaw) * depth / 2
    # the poster's local x runs along the wall; its normal is local y
    b.box(name, (cx, cy, 1.45), (0.9, depth, 0.7), yaw=normal_yaw - math.pi / 2, material=mat)


def _furnish(b: _Builder, room: _Room, materials: dict[str, str]) -> None:
    x0, y0, x1, y1 = room.bounds
    cx, cy = room.centre
    far = {"s": (0.0, 1.0), "n": (0.0, -1.0), "e": (-1.0, 0.0), "w": (1.0, 0.0)}[room.door_side]
    u = (far[1], -far[0])
    width = abs(u[0]) * (x1 - x0) + abs(u[1]) * (y1 - y0) - WALL_T
    depth = abs(far[0]) * (x1 - x0) + abs(far[1]) * (y1 - y0) - WALL_T
    yaw = math.atan2(u[1], u[0])
    door_u = (room.door[0] - cx) * u[0] + (room.door[1] - cy) * u[1]
    away = -1.0 if door_u >= 0 else 1.0  # side of the room away from the door

    def at(uu: float, vv: float, z: float) -> tuple[float, float, float]:
        return (cx + uu * u[0] + vv * far[0], cy + uu * u[1] + vv * far[1], z)

    n = room.name
    wall_v = depth / 2
    side_u = width / 2
    if room.kind in ("office", "meeting"):
        # desk (or meeting table) with chairs along the far wall
        tw = 1.4 if room.kind == "office" else 2.0
        tu = -side_u + 0.2 + tw / 2 if away < 0 else side_u - 0.2 - tw / 2
        tv = wall_v - 0.45
        b.box(
            f"{n}_table_top", at(tu, tv, 0.73), (tw, 0.8, 0.04), yaw=yaw, material=materials["wood"]
        )
        for i, (du, dv) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
            b.cylinder(
                f"{n}_table_leg{i}",
                at(tu + du * (tw / 2 - 0.06), tv + dv * 0.34, 0.355),
                0.025,
                0.71,
                material=materials["metal"],
            )
        chairs = (tu,) if room.kind == "office" else (tu - 0.55, tu + 0.55)
        for i, chu in enumerate(chairs):
            b.box(
                f"{n}_chair{i}_seat",
                at(chu, tv - 0.65, 0.23),
                (0.45, 0.45, 0.46),
                yaw=yaw,
                material=materials["fabric"],
            )
            b.box(
                f"{n}_chair{i}_back",
                at(chu, tv - 0.9, 0.7),
                (0.45, 0.06, 0.5),
                yaw=yaw,
                material=materials["fabric"],
            )
        if room.kind == "office":
            b.box(
                f"{n}_monitor",
                at(tu, tv + 0.2, 0.95),
                (0.55, 0.04, 0.36),
                yaw=yaw,
                material=b.texture(
                    f"{n}_screen",
                    hue=(0.5, 0.7),
                    sat=(0.5, 0.9),
                    light=(0.6, 0.9),
                    dark=(0.0, 0.2),
                    tile=0.5,
                    size=64,
                    scale=8,
                ),
            )
    if room.kind in ("lounge",):
        su = -side_u + 1.2 if away < 0 else side_u - 1.2
        b.box(
            f"{n}_sofa_seat",
            at(su, wall_v - 0.45, 0.22),
            (1.8, 0.8, 0.44),
            yaw=yaw,
            material=materials["fabric"],
        )
        b.box(
            f"{n}_sofa_back",
            at(su, wall_v - 0.12, 0.6),
            (1.8, 0.18, 0.8),
            yaw=yaw,
            material=materials["fabric"],
        )
        b.box(
            f"{n}_low_table",
            at(su, wall_v - 1.35, 0.2),
            (1.0, 0.5, 0.4),
            yaw=yaw,
            material=materials["wood"],
        )
    # a tall bookshelf in the other far corner (storage rooms: a row of them)
    shelves = [(side_u - 0.7) * -away] if room.kind != "storage" else [-2.5, -1.2, 1.2, 2.5]
    for i, shu in enumerate(shelves):
        book = b.texture(
            f"{n}_books{i}",
            hue=(0.0, 1.0),
            sat=(0.4, 0.9),
            light=(0.6, 0.95),
            dark=(0.1, 0.35),
            tile=0.8,
            scale=4,
            size=128,
        )
        b.box(f"{n}_shelf{i}", at(shu, wall_v - 0.2, 0.9), (1.0, 0.36, 1.8), yaw=yaw, material=book)
    # a cabinet in the near corner away from the door, a plant on the side wall
    b.box(
        f"{n}_cabinet",
        at(away * (side_u - 0.3), -wall_v + 0.5, 0.5),
        (0.5, 0.8, 1.0),
        yaw=yaw,
        material=materials["metal"],
    )
    b.cylinder(
        f"{n}_pot",
        at(away * (side_u - 0.35), 0.2 * wall_v, 0.2),
        0.2,
        0.4,
        material=materials["clay"],
    )
    b.sphere(
        f"{n}_leaves",
        at(away * (side_u - 0.35), 0.2 * wall_v, 0.72),
        0.3,
        material=materials["leaves"],
    )
    # a poster on each side wall and a carpet (visual only) in the middle
    for i, sign in enumerate((-1.0, 1.0)):
        px, py, _ = at(sign * side_u, 0.25 * wall_v, 0.0)
        normal = yaw + (0.0 if sign < 0 else math.pi)
        _poster(b, f"{n}_poster{i}", px, py, normal)
    carpet = b.texture(
        f"{n}_carpet",
        hue=(0.0, 1.0),
        sat=(0.3, 0.7),
        light=(0.5, 0.8),
        dark=(0.15, 0.35),
        tile=1.0,
        scale=16,
    )
    b.box(
        f"{n}_carpet",
        at(0.0, 0.0, 0.003),
        (0.45 * width, 0.45 * depth, 0.006),
        yaw=yaw,
        material=carpet,
        collision=False,
    )


def _graph() -> tuple[dict[str, list[float]], list[list[str]]]:
    nodes = {k: [v[0], v[1]] for k, v in _CORRIDOR_NODES.items()}
    edges = [[a, c] for a, c in itertools.pairwise(_CORRIDOR_LOOP)]
    for room in _ROOMS:
        doorway = f"door_{room.name}"
        nodes[doorway] = [room.door[0], room.door[1]]
        nodes[room.name] = [room.centre[0], room.centre[1]]
        edges.append([_ROOM_FRONT[room.name], doorway])
        edges.append([doorway, room.name])
    return nodes, edges


def generate(*, seed: int | None = None, params: dict[str, Any] | None = None) -> dict[str, Any]:
    """Generate the office world document.

    Args:
        seed: Random seed of colours and textures (default 0); the layout is fixed.
        params: No parameters are accepted yet (an empty mapping).

    Returns:
        A world document for :func:`visnav.description.world_yaml.world_from_dict`.

    Raises:
        ValueError: An unknown parameter was given.
    """
    Params("office", params or {}, DEFAULTS)
    world_seed = 0 if seed is None else int(seed)
    b = _Builder(np.random.default_rng(world_seed))
    materials = {
        "wood": b.texture(
            "wood",
            hue=(0.05, 0.1),
            sat=(0.4, 0.7),
            light=(0.55, 0.75),
            dark=(0.25, 0.4),
            tile=0.8,
            scale=8,
        ),
        "metal": b.texture(
            "metal",
            hue=(0.5, 0.7),
            sat=(0.0, 0.15),
            light=(0.6, 0.8),
            dark=(0.3, 0.45),
            tile=0.7,
            scale=8,
            checker=True,
        ),
        "fabric": b.texture(
            "fabric",
            hue=(0.0, 1.0),
            sat=(0.4, 0.8),
            light=(0.4, 0.7),
            dark=(0.1, 0.3),
            tile=0.5,
            scale=4,
            size=128,
        ),
        "clay": b.texture(
            "clay",
            hue=(0.02, 0.06),
            sat=(0.5, 0.7),
            light=(0.5, 0.7),
            dark=(0.25, 0.4),
            tile=0.4,
            scale=8,
            size=64,
        ),
        "leaves": b.texture(
            "leaves",
            hue=(0.25, 0.38),
            sat=(0.5, 0.8),
            light=(0.4, 0.7),
            dark=(0.1, 0.25),
            tile=0.3,
            scale=4,
            size=64,
        ),
    }
    floor = b.texture(
        "floor",
        hue=(0.06, 0.1),
        sat=(0.25, 0.45),
        light=(0.6, 0.75),
        dark=(0.3, 0.45),
        tile=3.0,
        scale=16,
        size=512,
    )
    _walls(b)
    for i, (x, y, normal) in enumerate(_POSTERS):
        _poster(b, f"corridor_poster{i}", x, y, normal)
    for room in _ROOMS:
        _furnish(b, room, materials)
    for i, (x, y) in enumerate(((-6.6, 3.6), (6.6, 3.6), (6.6, -3.6), (-6.6, -3.6))):
        b.cylinder(f"corridor_pot{i}", (x, y, 0.2), 0.2, 0.4, material=materials["clay"])
        b.sphere(f"corridor_leaves{i}", (x, y, 0.72), 0.3, material=materials["leaves"])
    nodes, edges = _graph()
    return {
        "name": "office",
        "seed": world_seed,
        "ground": {"size": [24.0, 19.0], "material": floor},
        "headlight": {"ambient": [0.4, 0.4, 0.4], "diffuse": [0.45, 0.45, 0.45]},
        "textures": b.textures,
        "materials": b.materials,
        "objects": b.objects,
        "lights": [
            {
                "name": "sun",
                "type": "directional",
                "dir": [-0.3, 0.2, -1.0],
                "diffuse": [0.35, 0.35, 0.35],
            },
        ],
        "metadata": {
            "kind": "office",
            "bounds": [-10.0, -7.5, 10.0, 7.5],
            "wall_height": WALL_H,
            "rooms": {
                r.name: {
                    "centre": list(r.centre),
                    "bounds": list(r.bounds),
                    "door": list(r.door),
                    "kind": r.kind,
                }
                for r in _ROOMS
            },
            "corridors": _CORRIDORS,
            "graph": {"nodes": nodes, "edges": edges},
            "spawn": [-6.0, -1.5, math.pi / 2],
        },
    }
