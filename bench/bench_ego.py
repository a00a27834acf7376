"""ego-planner benchmarks: planning time per replan, and one grid map update from a depth image.

    python bench/bench_ego.py [--seeds 5] [--no-sim]

1. Planning: the replan FSM flies a perfectly tracking vehicle through seeded
   ``forest`` worlds (40 x 40 m, 120 obstacles) whose obstacles are rasterised
   into the grid map; every ``rebound_replan`` call is timed (wall clock, numba
   already compiled). The EGO-Planner paper and code report about 1 ms per
   replan in C++; the ratio to that is printed.
2. Grid map: one 640 x 480 depth image (``skip_pixel`` 2) fused into the map,
   median of repeated updates. The image is a real frame of the simulator's
   quadrotor depth camera hovering at the forest start (``--no-sim``: a
   synthetic image of vertical columns instead).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from visnav.description.world import load_world
from visnav.mapping.grid_map import GridMap, GridMapParams
from visnav.planning.ego_planner.fsm import FSMState, ReplanFSM
from visnav.planning.ego_planner.manager import LocalTrajectory, PlannerManager, warm_up
from visnav.planning.ego_planner.messages import msg_to_trajectory, trajectory_to_msg
from visnav.planning.ego_planner.traj_server import TrajectoryServer
from visnav.sim.world_geometry import shape_aabb, shape_signed_distance

UPSTREAM_MS = 1.0
_NS = 1_000_000_000


def rasterise(world, gm: GridMap) -> None:
    """Mark every voxel whose centre is inside a collision shape (ground excluded)."""
    res = gm.resolution
    for shape in world.collision_shapes:
        lo, hi = shape_aabb(shape)
        lo = np.maximum(lo, gm.origin)
        hi = np.minimum(hi, gm.map_max - 1e-6)
        if np.any(hi <= lo):
            continue
        i0, i1 = gm.pos_to_index(lo), gm.pos_to_index(hi)
        axes = [np.arange(i0[k], i1[k] + 1) for k in range(3)]
        idx = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        centres = gm.index_to_pos(idx)
        inside = centres[shape_signed_distance(shape, centres) <= res * 0.5]
        if len(inside):
            gm.mark_occupied(inside)


def fly(seed: int, *, max_s: float = 60.0) -> tuple[list[float], bool, float]:
    """Fly start -> goal through forest ``seed``; return replan times (ms), success, time (s)."""
    world = load_world("forest", seed=seed)
    gm = GridMap(GridMapParams(map_size=(40.0, 40.0, 3.0)))
    rasterise(world, gm)
    manager = PlannerManager(gm, seed=seed)
    server = TrajectoryServer()

    def on_traj(traj: LocalTrajectory) -> None:
        start_ns, sampled = msg_to_trajectory(trajectory_to_msg(traj, frame_id="world"))
        server.set_trajectory(sampled, start_ns)

    fsm = ReplanFSM(manager, on_trajectory=on_traj)
    start, goal = world.metadata["start"], world.metadata["goal"]
    pos, vel = np.array([start[0], start[1], 1.0]), np.zeros(3)
    now = _NS
    fsm.set_odometry(pos, vel, now_ns=now)
    fsm.step(now)
    fsm.set_goal(goal, now_ns=now)
    ticks = 0
    while fsm.goals_reached == 0 and ticks < max_s * 100:
        ticks += 1
        now += 10_000_000
        ref = server.command(now)
        if ref is not None:
            pos, vel = np.array(ref.position), np.array(ref.velocity)
        fsm.set_odometry(pos, vel, now_ns=now)
        fsm.step(now)
        if ticks % 5 == 0:
            fsm.check_collision(now)
    times = [r.total_s * 1e3 for r in manager.records]
    return times, fsm.state == FSMState.WAIT_TARGET and fsm.goals_reached > 0, ticks / 100


def synthetic_depth(seed: int) -> tuple[np.ndarray, tuple[float, float, float, float], np.ndarray]:
    """A 640 x 480 depth image of random columns seen from (0, 0, 1) along +x."""
    rng = np.random.default_rng(seed)
    fx = fy = 337.2
    cx, cy = 320.0, 240.0
    v, u = np.mgrid[0:480, 0:640]
    rays = np.stack([(u - cx) / fx, (v - cy) / fy, np.ones_like(u, dtype=float)], axis=-1)
    # optical -> world: z forward = +x, x right = -y, y down = -z
    dirs = np.stack([rays[..., 2], -rays[..., 0], -rays[..., 1]], axis=-1)
    depth = np.full((480, 640), np.inf)
    for _ in range(40):
        c = rng.uniform([1.0, -6.0], [12.0, 6.0])
        r = rng.uniform(0.15, 0.45)
        a = dirs[..., 0] ** 2 + dirs[..., 1] ** 2
        b = -2 * (dirs[..., 0] * c[0] + dirs[..., 1] * c[1])
        disc = b * b - 4 * a * (c @ c - r * r)
        t = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
        depth = np.minimum(depth, np.where(t > 0, t, np.inf))  # t is the optical z (unit z)
    ground_t = np.where(dirs[..., 2] < 0, -1.0 / dirs[..., 2], np.inf)
    depth = np.minimum(depth, ground_t)
    depth[~np.isfinite(depth) | (depth > 10.0)] = 0.0
    pose = np.eye(4)
    pose[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]
    pose[:3, 3] = [0.0, 0.0, 1.0]
    return depth.astype(np.float32), (fx, fy, cx, cy), pose


def sim_depth(seed: int) -> tuple[np.ndarray, tuple[float, float, float, float], np.ndarray]:
    """One frame of the simulated quadrotor's depth camera, hovering at the forest start."""
    from visnav.graph import Context, Node
    from visnav.msgs import CameraInfo, Header, Image, PoseStamped, image_to_numpy, make
    from visnav.msgs.time import ns_to_time, time_to_ns
    from visnav.sim.simulator import RobotSpawn, Simulator
    from visnav.tf import Buffer
    from visnav.tf.ros import TransformListener

    with Context(transport="local") as ctx:
        sim = Simulator(
            "forest", [RobotSpawn(source="quadrotor", namespace="/drone")], context=ctx, seed=seed
        )
        probe = Node("bench", context=ctx)
        buffer = Buffer()
        TransformListener(buffer, probe)
        images: list[Image] = []
        infos: list[CameraInfo] = []
        probe.create_subscription(Image, "/drone/depth_camera/depth/image_raw", images.append, 5)
        probe.create_subscription(
            CameraInfo, "/drone/depth_camera/depth/camera_info", infos.append, 5
        )
        hold = probe.create_publisher(PoseStamped, "/drone/command/pose", 1)
        start = sim.world.metadata["start"]
        cmd = make(PoseStamped)
        cmd.header = Header(stamp=ns_to_time(0), frame_id="world")
        cmd.pose.position.x, cmd.pose.position.y, cmd.pose.position.z = start[0], start[1], 1.0
        cmd.pose.orientation.w = 1.0
        hold.publish(cmd)
        sim.run(3.0)
        image = images[-1]
        k = infos[-1].k
        pose = buffer.lookup_transform_matrix(
            "world", image.header.frame_id, time_to_ns(image.header.stamp)
        )
        return image_to_numpy(image).copy(), (k[0], k[4], k[2], k[5]), pose


def sim_flight(seed: int, *, inflation: float = 0.3, limit_s: float = 60.0) -> dict[str, float]:
    """Fly the simulated quadrotor start -> goal through forest ``seed`` (closed loop).

    Take-off to 1 m with a hold command, then ego_planner_node + traj_server (depth
    camera -> grid map, commands -> the SO(3) controller), goal on
    /move_base_simple/goal. Contacts are MuJoCo contacts between the drone and
    anything else; clearance is the obstacle distance of the body centre.
    ``inflation`` is ``grid_map.obstacles_inflation``: upstream's 0.099 m suits a
    point-like vehicle; the built-in quadrotor's collision box (0.36 m square,
    0.26 m circumscribed radius) needs 0.3 m.
    """
    import mujoco

    from visnav.graph import Context, Node
    from visnav.msgs import Header, Odometry, PoseStamped, make
    from visnav.msgs.time import ns_to_time
    from visnav.planning.ego_planner.nodes import EgoPlannerNode, TrajServerNode
    from visnav.sim.simulator import RobotSpawn, Simulator
    from visnav.sim.world_geometry import obstacle_distance

    world = load_world("forest", seed=seed)
    wall0 = time.perf_counter()
    with Context(transport="local") as ctx:
        sim = Simulator(
            world, [RobotSpawn(source="quadrotor", namespace="/drone")], context=ctx, seed=seed
        )
        root = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, sim.robot().handles.root_body)
        drone = {b for b in range(sim.model.nbody) if sim.model.body_rootid[b] == root}
        probe = Node("scenario", context=ctx, use_sim_time=True)
        odoms: list[Odometry] = []
        probe.create_subscription(Odometry, "/drone/odom", odoms.append, 100)
        hold = probe.create_publisher(PoseStamped, "/drone/command/pose", 1)
        goal_pub = probe.create_publisher(PoseStamped, "/move_base_simple/goal", 1)
        start, goal = world.metadata["start"], world.metadata["goal"]
        cmd = make(PoseStamped)
        cmd.header = Header(stamp=ns_to_time(0), frame_id="world")
        cmd.pose.position.x, cmd.pose.position.y, cmd.pose.position.z = start[0], start[1], 1.0
        cmd.pose.orientation.w = 1.0
        hold.publish(cmd)
        sim.run(3.0)
        common = {"use_sim_time": True}
        planner = EgoPlannerNode(
            context=ctx,
            namespace="/drone",
            parameter_overrides={**common, "grid_map.obstacles_inflation": inflation},
        )
        TrajServerNode(context=ctx, namespace="/drone", parameter_overrides=common)
        sim.run(0.5)
        target = make(PoseStamped)
        target.header = Header(stamp=ns_to_time(sim.now_ns), frame_id="world")
        target.pose.position.x, target.pose.position.y = goal[0], goal[1]
        target.pose.orientation.w = 1.0
        goal_pub.publish(target)
        first, t0, contacts = len(odoms), sim.now_ns, 0

        def done() -> bool:
            nonlocal contacts
            for c in sim.data.contact[: sim.data.ncon]:
                b1, b2 = sim.model.geom_bodyid[c.geom1], sim.model.geom_bodyid[c.geom2]
                contacts += int((b1 in drone) != (b2 in drone))
            return planner.fsm.goals_reached > 0

        stats = sim.run(limit_s, until=done)
        flight_s = (sim.now_ns - t0) / 1e9
        pos = np.array(
            [
                [o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z]
                for o in odoms[first:]
            ]
        )
        times = [r.total_s * 1e3 for r in planner.manager.records[1:]]
        return {
            "reached": float(planner.fsm.goals_reached > 0 and math.dist(pos[-1, :2], goal) < 0.5),
            "contacts": float(contacts),
            "clearance": float(obstacle_distance(world, pos).min()),
            "mean_speed": float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()) / flight_s,
            "flight_s": flight_s,
            "plan_median_ms": float(np.median(times)) if times else math.nan,
            "plan_p95_ms": percentile(times, 95),
            "plans": float(len(times) + 1),
            "failed_plans": float(sum(not r.success for r in planner.manager.records)),
            "rtf": stats.real_time_factor,
            "wall_s": time.perf_counter() - wall0,
        }


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else math.nan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="forest seeds to fly (default 5)")
    parser.add_argument("--no-sim", action="store_true", help="synthetic depth image")
    parser.add_argument(
        "--flights",
        type=int,
        default=0,
        help="also fly the simulated quadrotor through this many seeded forests",
    )
    parser.add_argument(
        "--inflation",
        type=float,
        default=0.3,
        help="grid_map.obstacles_inflation of the flights (default 0.3 m)",
    )
    args = parser.parse_args()

    warm_up()  # compile, or load from the caches, every numba kernel
    all_times: list[float] = []
    if args.seeds:
        print("planning: kinematic flights through seeded forests (map known in advance)")
    for seed in range(args.seeds):
        t0 = time.perf_counter()
        times, ok, flight_s = fly(seed)
        all_times += times
        print(
            f"  seed {seed}: {'reached' if ok else 'NOT reached'} in {flight_s:.1f} s sim, "
            f"{len(times)} replans, median {np.median(times):.2f} ms, p95 "
            f"{percentile(times, 95):.2f} ms, max {max(times):.1f} ms "
            f"({time.perf_counter() - t0:.1f} s wall)"
        )
    med, p95 = float(np.median(all_times or [math.nan])), percentile(all_times, 95)
    print(
        f"planning time per replan over {len(all_times)} replans: median {med:.2f} ms "
        f"(target <= 5), p95 {p95:.2f} ms (target <= 20); upstream C++ ~{UPSTREAM_MS:.0f} ms: "
        f"visnav / upstream = {med / UPSTREAM_MS:.2f}x (median), {p95 / UPSTREAM_MS:.2f}x (p95)"
    )

    if args.no_sim:
        depth, intr, pose = synthetic_depth(0)
        source = "synthetic columns"
    else:
        depth, intr, pose = sim_depth(0)
        source = "simulator frame, forest seed 0"
    gm = GridMap(GridMapParams(map_size=(40.0, 40.0, 3.0)))
    gm.update_from_depth(depth, intrinsics=intr, T_world_camera=pose)  # warm up
    walls = []
    for _ in range(30):
        t0 = time.perf_counter()
        result = gm.update_from_depth(depth, intrinsics=intr, T_world_camera=pose)
        walls.append((time.perf_counter() - t0) * 1e3)
    assert result is not None
    valid = float(np.mean(depth > 0))
    print(
        f"grid map update, one {depth.shape[1]}x{depth.shape[0]} depth image ({source}, "
        f"{100 * valid:.0f}% valid pixels), skip_pixel 2: {result.rays} rays, {result.voxels} "
        f"voxels touched; median {np.median(walls):.2f} ms, p95 {percentile(walls, 95):.2f} ms "
        "(target <= 10)"
    )

    if args.flights:
        print(
            f"closed loop in the simulator, {args.flights} seeded forests, obstacles_inflation "
            f"{args.inflation} m (issue 8 acceptance):"
        )
        runs = []
        for seed in range(args.flights):
            r = sim_flight(seed, inflation=args.inflation)
            runs.append(r)
            print(
                f"  seed {seed}: {'reached' if r['reached'] else 'NOT reached'}, contacts "
                f"{r['contacts']:.0f}, min clearance {r['clearance']:.2f} m, mean speed "
                f"{r['mean_speed']:.2f} m/s over {r['flight_s']:.1f} s, {r['plans']:.0f} plans "
                f"({r['failed_plans']:.0f} failed), median {r['plan_median_ms']:.2f} ms, p95 "
                f"{r['plan_p95_ms']:.2f} ms, real-time factor {r['rtf']:.2f} "
                f"({r['wall_s']:.0f} s wall)"
            )
        ok = [r["reached"] and r["contacts"] == 0 for r in runs]
        print(
            f"reached without collision: {sum(ok)}/{len(runs)} ({100 * np.mean(ok):.0f}%, "
            f"target >= 95%); mean speed {np.mean([r['mean_speed'] for r in runs]):.2f} m/s "
            f"(target >= 1.5); min clearance {min(r['clearance'] for r in runs):.2f} m"
        )


if __name__ == "__main__":
    main()
