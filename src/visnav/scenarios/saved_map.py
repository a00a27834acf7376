"""The launch args of a car run in a saved map (``visnav run car --map``).

A car run writes ``map.yaml`` + ``map.pgm`` (map_server's format) and ``slam_map.npz``
(the SLAM map) into its output directory. Localising in that directory's map takes one
of two sources of ``map -> odom`` (``map_localization``, docs/navigation.md):

* ``slam`` (the default): the visual SLAM in localisation mode against ``slam_map.npz``
  beside ``map.yaml`` (rtabmap's localization mode; :mod:`visnav.slam.localization_mode`);
* ``amcl``: AMCL on the depth camera's scan in ``map.yaml`` (for a map without a SLAM
  map beside it, e.g. a map_server map from elsewhere, or a run without SLAM).

Either way ``map.yaml`` is the costmaps' static layer (map_server).
"""

from __future__ import annotations

from pathlib import Path

from visnav.scenarios.errors import ScenarioError

__all__ = ["MAP_LOCALIZATIONS", "SLAM_MAP_NAME", "saved_map_launch_args"]

MAP_LOCALIZATIONS = ("slam", "amcl")
"""The values of ``map_localization`` (the launch arg and ``--map-localization``)."""
SLAM_MAP_NAME = "slam_map.npz"
"""The SLAM map's file name beside a run's ``map.yaml``."""


def saved_map_launch_args(
    map_yaml: str, localization: str = "slam", *, slam: bool = True, check: bool = False
) -> dict[str, str]:
    """The car launch's args to localise in the map ``map_yaml`` (map_server's YAML).

    Args:
        map_yaml: the saved map's ``map.yaml``.
        localization: ``slam`` (SLAM in the ``slam_map.npz`` beside it) or ``amcl``.
        slam: whether the run has SLAM at all (without it the source is always AMCL).
        check: refuse a missing ``slam_map.npz`` now (the CLI) instead of at the SLAM
            node's start (a sweep's run reports it as that run's failure).

    Raises:
        ScenarioError: an unknown ``localization``, or with ``check`` no SLAM map beside
            ``map_yaml``.
    """
    if localization not in MAP_LOCALIZATIONS:
        text = (
            f"map localization {localization!r}: expected one of {', '.join(MAP_LOCALIZATIONS)}"
            " (slam: SLAM in the saved SLAM map, amcl: AMCL on the scan)"
        )
        raise ScenarioError(text)
    args = {"use_map": "true", "map": map_yaml, "map_localization": localization}
    if localization == "slam" and slam:
        slam_map = Path(map_yaml).parent / SLAM_MAP_NAME
        if check and not slam_map.is_file():
            text = (
                f"{map_yaml}: no SLAM map beside it ({slam_map} is missing) to localise in; "
                "a car run with SLAM and --out DIR writes DIR/slam_map.npz, or localise with "
                "AMCL instead (--map-localization amcl)"
            )
            raise ScenarioError(text)
        args["slam_map"] = str(slam_map)
    return args
