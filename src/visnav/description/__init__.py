"""Robot and world descriptions: URDF / Xacro / SDF / Gazebo tags parsed into plain specs.

Pure parsing, no MuJoCo and no graph (the layer between :mod:`visnav.msgs` and
:mod:`visnav.graph`): :mod:`visnav.sim` builds MuJoCo models from these specs,
:mod:`visnav.tf`'s robot_state_publisher, :mod:`visnav.doctor` and :mod:`visnav.launch`
read robots through them. Modules:

* :mod:`~visnav.description.robot` (``load_robot``, ``expand_xacro``),
  :mod:`~visnav.description.robots` (the built-in ``car`` and ``quadrotor``, ``resolve_robot``);
* :mod:`~visnav.description.urdf`, :mod:`~visnav.description.urdf_model` (URDF),
  :mod:`~visnav.description.gazebo`, :mod:`~visnav.description.gazebo_specs` (``<gazebo>``
  sensors and plugins), :mod:`~visnav.description.noise_specs`,
  :mod:`~visnav.description.vehicle_params`;
* :mod:`~visnav.description.world` (``load_world``), :mod:`~visnav.description.worldmodel`,
  :mod:`~visnav.description.world_yaml`, :mod:`~visnav.description.sdf_world`,
  :mod:`~visnav.description.mesh_files` (mesh vertices), and the
  built-in world generators in :mod:`~visnav.description.worlds`;
* :mod:`~visnav.description.warning_summary` (the one grouped warning block a load logs),
  :mod:`~visnav.description.xacro_locations` (file:line of each element through Xacro);
* :mod:`~visnav.description.rigid` (rotation helpers), :mod:`~visnav.description.errors`.

Submodules are imported explicitly; importing this package imports nothing else.
"""

from __future__ import annotations

__all__: list[str] = []
