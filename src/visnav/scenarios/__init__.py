"""Built-in scenarios: worlds (:mod:`visnav.scenarios.worlds`), robots and launch files.

Robot descriptions are data files under ``robots/`` (URDF / Xacro); locate them
with :func:`importlib.resources.files`. Importing this package has no side effects.
"""

from __future__ import annotations

__all__: list[str] = []
