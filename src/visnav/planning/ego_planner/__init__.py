"""EGO-Planner: ESDF-free gradient-based local planning for quadrotors, on visnav.

A re-implementation of Zhou, Wang, Xu and Gao, "EGO-Planner: An ESDF-free
Gradient-based Local Planner for Quadrotors" (RA-L 2021, arXiv 2008.08835) and
of ZJU FAST-Lab's ego-planner code, with its defaults:

* :mod:`~visnav.planning.ego_planner.bspline` - uniform cubic B-splines;
* :mod:`~visnav.planning.ego_planner.polynomial` - quintic initial and global paths;
* :mod:`~visnav.planning.ego_planner.astar` - A* on the inflated grid map;
* :mod:`~visnav.planning.ego_planner.rebound` - the ``{p, v}`` collision pairs;
* :mod:`~visnav.planning.ego_planner.costs` and :mod:`~visnav.planning.ego_planner.lbfgs` -
  the objective terms and the L-BFGS solver (numba);
* :mod:`~visnav.planning.ego_planner.optimizer` - rebound and refinement runs;
* :mod:`~visnav.planning.ego_planner.manager` - one replan, time re-allocation;
* :mod:`~visnav.planning.ego_planner.fsm` - the replan state machine;
* :mod:`~visnav.planning.ego_planner.traj_server` - position commands and yaw;
* :mod:`~visnav.planning.ego_planner.messages` - trajectories and commands as
  ``trajectory_msgs/MultiDOFJointTrajectory``;
* :mod:`~visnav.planning.ego_planner.nodes` - ``EgoPlannerNode`` and ``TrajServerNode``.

The map is :mod:`visnav.mapping.grid_map`. Modules are imported on use (numba
compiles on first call and caches the machine code next to the sources).
"""

from __future__ import annotations

__all__: list[str] = []
