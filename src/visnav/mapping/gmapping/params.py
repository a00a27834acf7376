"""slam_gmapping's parameters: gmapping's names and defaults, one dataclass per concern.

:class:`GmappingParams` holds what the filter uses (OpenSLAM GMapping's laser, scan
matcher, motion model, update and map parameters); :class:`GmappingNodeParams` what the
ROS wrapper adds (frames, map publishing, ``map -> odom`` period, scan throttling).
Both are declared on :class:`~visnav.mapping.gmapping.node.SlamGmappingNode` without a
prefix, so a ROS 1 launch file's ``<param>`` / ``<rosparam>`` names pass through as written.

``maxRange`` and ``maxUrange`` default to ``0.0``, meaning "from the first scan", as
slam_gmapping does when they are not set: ``maxRange = range_max - 0.01`` and
``maxUrange = maxRange``.
"""

from __future__ import annotations

from dataclasses import dataclass

from visnav.graph.param_dataclass import param
from visnav.mapping.errors import MappingError

__all__ = ["GmappingError", "GmappingNodeParams", "GmappingParams"]


class GmappingError(MappingError, ValueError):
    """A gmapping parameter, scan or laser mounting cannot be used (the text says which)."""


@dataclass(frozen=True)
class GmappingParams:
    """The filter's parameters (gmapping's names and slam_gmapping's defaults)."""

    particles: int = param(30, description="number of particles", range=(1, 10000))
    delta: float = param(0.05, description="map resolution (m/cell)", range=(0.001, 10.0))
    maxUrange: float = param(  # noqa: N815 - gmapping's name
        0.0, description="usable laser range (m); 0: maxRange", range=(0.0, 1000.0)
    )
    maxRange: float = param(  # noqa: N815
        0.0,
        description="laser range limit (m); 0: the scan's range_max - 0.01",
        range=(0.0, 1000.0),
    )
    sigma: float = param(0.05, description="scan matcher endpoint sigma (m)", range=(1e-6, 10.0))
    kernelSize: int = param(1, description="scan matcher search window (cells)", range=(0, 10))  # noqa: N815
    lstep: float = param(
        0.05, description="optimizer initial translation step (m)", range=(0.0, 10.0)
    )
    astep: float = param(
        0.05, description="optimizer initial rotation step (rad)", range=(0.0, 3.2)
    )
    iterations: int = param(5, description="optimizer step refinements", range=(0, 100))
    lsigma: float = param(0.075, description="beam likelihood sigma", range=(1e-6, 10.0))
    ogain: float = param(3.0, description="weight smoothing gain", range=(1e-6, 1000.0))
    lskip: int = param(0, description="beams skipped between used beams", range=(0, 1000))
    minimumScore: float = param(  # noqa: N815
        0.0, description="minimum match score to trust the scan matcher", range=(0.0, 1e9)
    )
    srr: float = param(
        0.1, description="odometry error: translation from translation", range=(0.0, 100.0)
    )
    srt: float = param(
        0.2, description="odometry error: rotation from translation", range=(0.0, 100.0)
    )
    str: float = param(
        0.1, description="odometry error: translation from rotation", range=(0.0, 100.0)
    )
    stt: float = param(
        0.2, description="odometry error: rotation from rotation", range=(0.0, 100.0)
    )
    linearUpdate: float = param(  # noqa: N815
        1.0, description="process a scan after this translation (m)", range=(0.0, 1000.0)
    )
    angularUpdate: float = param(  # noqa: N815
        0.5, description="process a scan after this rotation (rad)", range=(0.0, 1000.0)
    )
    temporalUpdate: float = param(  # noqa: N815
        -1.0, description="process a scan after this time (s); < 0: off", range=(-1.0, 1e6)
    )
    resampleThreshold: float = param(  # noqa: N815
        0.5, description="resample when Neff < this * particles", range=(0.0, 1.0)
    )
    xmin: float = param(-100.0, description="initial map x min (m)", range=(-1e5, 1e5))
    ymin: float = param(-100.0, description="initial map y min (m)", range=(-1e5, 1e5))
    xmax: float = param(100.0, description="initial map x max (m)", range=(-1e5, 1e5))
    ymax: float = param(100.0, description="initial map y max (m)", range=(-1e5, 1e5))
    llsamplerange: float = param(
        0.01, description="accepted, unused (as in gmapping)", range=(0.0, 10.0)
    )
    llsamplestep: float = param(
        0.01, description="accepted, unused (as in gmapping)", range=(0.0, 10.0)
    )
    lasamplerange: float = param(
        0.005, description="accepted, unused (as in gmapping)", range=(0.0, 10.0)
    )
    lasamplestep: float = param(
        0.005, description="accepted, unused (as in gmapping)", range=(0.0, 10.0)
    )
    occ_thresh: float = param(0.25, description="occupied above this hit ratio", range=(0.0, 1.0))
    seed: int = param(0, description="random seed (motion noise, resampling)", range=(0, 2**31 - 1))

    def __post_init__(self) -> None:
        """Refuse an empty initial map box (names the bounds and the fix)."""
        if self.xmax <= self.xmin or self.ymax <= self.ymin:
            msg = (
                f"gmapping: map box x [{self.xmin}, {self.xmax}], y [{self.ymin}, {self.ymax}] "
                "is empty; expected xmin < xmax and ymin < ymax. Fix: set xmin/xmax/ymin/ymax"
            )
            raise GmappingError(msg)


@dataclass(frozen=True)
class GmappingNodeParams:
    """slam_gmapping's wrapper parameters (frames, publishing, throttling)."""

    base_frame: str = param("base_link", description="robot base frame", read_only=True)
    odom_frame: str = param("odom", description="odometry frame", read_only=True)
    map_frame: str = param("map", description="map frame", read_only=True)
    map_update_interval: float = param(
        5.0, description="seconds (scan time) between map rebuilds", range=(0.0, 1e6)
    )
    transform_publish_period: float = param(
        0.05, description="map -> odom period (s); 0: never", range=(0.0, 100.0)
    )
    throttle_scans: int = param(1, description="use every n-th scan", range=(1, 1000))
