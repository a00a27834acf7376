"""Built-in scenarios: launch files and the observer (worlds and robots: :mod:`visnav.description`).

``launch/car.launch.yaml`` and ``launch/drone.launch.yaml`` (shipped in the package) are
the scenarios; :mod:`visnav.scenarios.missions` holds the nodes that send their goals,
:mod:`visnav.scenarios.observer` the node that scores a run from topics, and
:mod:`visnav.scenarios.runner` ``visnav run`` (launch + bag + summary). Sweeps:
:mod:`visnav.scenarios.sweep`. Importing this package has no side effects.
"""

from __future__ import annotations

__all__: list[str] = []
