"""The SLAM node's parameters (:class:`visnav.slam.node.SlamNode`; see its module docstring)."""

from __future__ import annotations

from dataclasses import dataclass

from visnav.graph.param_dataclass import param
from visnav.slam.config import SlamConfig

__all__ = ["SlamParams"]


@dataclass(frozen=True)
class SlamParams:
    """The SLAM node's parameters (read once at start; see the module docstring)."""

    map_frame: str = param("map", description="the map frame SLAM publishes")
    odom_frame: str = param("odom", description="odometry frame ('': publish map -> base)")
    base_frame: str = param("base_link", description="the robot's base frame")
    publish_tf: bool = param(True, description="publish map -> odom on /tf")
    transform_tolerance: float = param(0.1, description="s the map -> odom stamp is post-dated")
    tf_publish_period: float = param(0.05, description="s between map -> odom publications")
    queue_size: int = param(10, description="synchroniser queue size")
    approx_sync: bool = param(True, description="ApproximateTime (false: exact stamps)")
    depth_scale: float = param(1000.0, description="16UC1 depth units per metre")
    map_cloud_period: float = param(1.0, description="s between slam/map_points clouds")
    path_publish_period: float = param(1.0, description="s of stamps between paths (0: every)")
    dense_cloud_period: float = param(0.0, description="s between dense clouds (0: on request)")
    dense_voxel: float = param(0.05, description="dense cloud voxel size (m)")
    vocabulary: str = param("", description="a saved vocabulary .npz ('': built online)")
    worker: str = param("inline", description="where SLAM runs: inline or process")
    result_latency: float = param(0.0, description="s of stamp time a result is applied after")
    set_initial_pose: bool = param(False, description="start at initial_pose.x/y/yaw")
    max_frame_rate: float = param(0.0, description="Hz of processed frames (0: every frame)")
    odometry_prior: bool = param(
        True, description="odom -> base predicts and constrains the camera motion"
    )
    odometry_sigma_t: float = param(
        SlamConfig.odometry_sigma_t, description="m: odometry sigma per axis at rest"
    )
    odometry_sigma_t_rel: float = param(
        SlamConfig.odometry_sigma_t_rel, description="odometry sigma per m moved"
    )
    odometry_sigma_r_deg: float = param(
        SlamConfig.odometry_sigma_r_deg, description="deg: odometry sigma per axis at rest"
    )
    odometry_sigma_r_rel: float = param(
        SlamConfig.odometry_sigma_r_rel, description="odometry sigma per radian turned"
    )
    odometry_sigma_r_per_m: float = param(
        SlamConfig.odometry_sigma_r_per_m, description="rad: odometry heading sigma per m moved"
    )
    odometry_model: str = param(
        SlamConfig.odometry_model,
        description="diff: a wheeled base that cannot move sideways (amcl's odom_model_type); omni",
    )
    odometry_sigma_t_lateral: float = param(
        SlamConfig.odometry_sigma_t_lateral,
        description="m: diff odometry's sideways sigma at rest (+ distance x heading sigma)",
    )
    force_3dof: bool = param(
        False, description="map -> odom keeps the base level: x, y, yaw only (Reg/Force3DoF)"
    )
    odometry_wait: float = param(
        0.1, description="s of clock time a frame waits for odom -> base at its stamp"
    )
    n_features: int = param(1000, description="ORB features per frame")
    far_point_limit: int = param(
        -1,
        description="keypoints past 3 m make points only until this many counted "
        "(ORB-SLAM2: 100); -1: every depth",
    )
    seed: int = param(0, description="random seed")
    loop_closure: bool = param(True, description="detect and close loops")
    global_ba_after_loop: bool = param(
        SlamConfig.global_ba_after_loop, description="bundle-adjust the whole map after a loop"
    )
    global_ba_delay: int = param(
        0, description="frames after a loop its global BA (helper process) is merged; 0: inline"
    )
    local_ba: bool = param(True, description="local bundle adjustment")
    icp_refinement: bool = param(True, description="dense ICP refinement of each pose")
    depth_noise: float = param(SlamConfig.depth_noise, description="sigma_z / z^2 of the depth")
    sensor: str = param("rgbd", description="rgbd or mono")
    mono_scale: str = param("depth", description="what scales a mono map: depth or odometry")
    diagnostic_period: float = param(1.0, description="s between /diagnostics (0: on changes)")
    database_path: str = param(
        "", description="the SLAM map .npz (+ .ply) written at shutdown ('': none; rtabmap's name)"
    )
    localization: bool = param(
        False, description="localise in the map at database_path (read, not written; rtabmap's)"
    )
