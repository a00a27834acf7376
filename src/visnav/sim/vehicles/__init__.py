"""Vehicles: Gazebo's differential drive and an SO(3)-controlled quadrotor.

Each module holds the controller as a plain class operating on ``mujoco.MjModel`` /
``mujoco.MjData`` (no graph); the simulator wires topics to them.
"""

from __future__ import annotations

__all__: list[str] = []
