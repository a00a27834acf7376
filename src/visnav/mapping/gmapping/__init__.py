"""gmapping: Rao-Blackwellised particle filter SLAM on a 2D laser (OpenSLAM GMapping).

:class:`GmappingFilter` is the algorithm (numpy in and out, no graph);
:class:`SlamGmappingNode` (in :mod:`visnav.mapping.gmapping.node`, registry name
``slam_gmapping``) wires it to ``scan``, TF, ``map`` and ``dynamic_map`` as ROS's
slam_gmapping does. See docs/gmapping.md.
"""

from __future__ import annotations

from visnav.mapping.gmapping.maps import ParticleMaps
from visnav.mapping.gmapping.params import GmappingError, GmappingNodeParams, GmappingParams
from visnav.mapping.gmapping.particle_filter import GmappingFilter, GridMap, LaserGeometry

__all__ = [
    "GmappingError",
    "GmappingFilter",
    "GmappingNodeParams",
    "GmappingParams",
    "GridMap",
    "LaserGeometry",
    "ParticleMaps",
]
