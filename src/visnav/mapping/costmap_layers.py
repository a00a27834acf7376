"""Costmap layer plugins by type, and the parameters of a costmap and its layers.

A costmap's ``plugins`` parameter lists layer names (nav2 / costmap_2d:
``["static_layer", "obstacle_layer", "inflation_layer"]``); each layer's parameters
live under its name (``<costmap>.<layer>.<param>``) and ``<layer>.plugin`` names its
type (``nav2_costmap_2d::StaticLayer``, ``costmap_2d::ObstacleLayer``, or just
``InflationLayer``). An empty ``plugin`` is guessed from the layer's name (a name
holding ``static`` / ``obstacle`` / ``inflat``), so the three default names need no
``plugin`` line.

:data:`COSTMAP_LAYERS` maps a type to a ``module:function`` factory
``(costmap, name, defaults) -> Layer``, imported when the layer is built. Adding a
layer type: write its module (layer class, params dataclass, factory) and add one
line here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from visnav.graph.param_dataclass import declare_params, param
from visnav.mapping.errors import CostmapError
from visnav.plugin_registry import UnknownPluginError, resolve_factory

if TYPE_CHECKING:
    from visnav.mapping.costmap_ros import CostmapROS
    from visnav.mapping.layer import Layer

T = TypeVar("T")

__all__ = [
    "COSTMAP_LAYERS",
    "CostmapParams",
    "InflationLayerParams",
    "ObservationSourceParams",
    "ObstacleLayerParams",
    "StaticLayerParams",
    "layer_defaults",
    "layer_type",
    "make_inflation_layer",
    "make_layer",
    "make_obstacle_layer",
    "make_static_layer",
]

COSTMAP_LAYERS: Mapping[str, str] = {
    "StaticLayer": "visnav.mapping.costmap_layers:make_static_layer",
    "ObstacleLayer": "visnav.mapping.costmap_layers:make_obstacle_layer",
    "InflationLayer": "visnav.mapping.costmap_layers:make_inflation_layer",
}

_GUESSES = (("static", "StaticLayer"), ("obstacle", "ObstacleLayer"), ("inflat", "InflationLayer"))


@dataclass(frozen=True)
class CostmapParams:
    """costmap_2d's parameters of the costmap itself (names and defaults are costmap_2d's)."""

    global_frame: str = param("map", description="frame of the costmap")
    robot_base_frame: str = param("base_link", description="frame of the robot")
    transform_tolerance: float = param(0.3, description="oldest robot pose used (s)")
    update_frequency: float = param(5.0, description="update rate (Hz); 0 off")
    publish_frequency: float = param(0.0, description="costmap publishing rate (Hz); 0 off")
    rolling_window: bool = param(False, description="centre the costmap on the robot")
    width: float = param(10.0, description="width (m)")
    height: float = param(10.0, description="height (m)")
    resolution: float = param(0.05, description="cell size (m)")
    origin_x: float = param(0.0, description="origin x (m)")
    origin_y: float = param(0.0, description="origin y (m)")
    track_unknown_space: bool = param(False, description="keep unknown cells unknown")
    footprint: str = param("[]", description="polygon '[[x, y], ...]'; '[]' uses robot_radius")
    robot_radius: float = param(0.46, description="circular robot radius (m)")
    footprint_padding: float = param(0.01, description="footprint padding (m)")
    plugins: list[str] = param(  # noqa: RUF009
        ["static_layer", "obstacle_layer", "inflation_layer"],
        description="layer names, bottom to top; each layer's type in '<name>.plugin'",
    )


@dataclass(frozen=True)
class StaticLayerParams:
    """costmap_2d's StaticLayer parameters."""

    enabled: bool = param(True, description="use the layer")
    map_topic: str = param("map", description="nav_msgs/OccupancyGrid input (latched)")
    lethal_cost_threshold: int = param(100, description="occupancy from which a cell is lethal")
    unknown_cost_value: int = param(-1, description="occupancy value meaning unknown")
    trinary_costmap: bool = param(True, description="free / lethal / unknown only")
    use_maximum: bool = param(False, description="max into the master instead of overwrite")
    first_map_only: bool = param(False, description="ignore maps after the first")


@dataclass(frozen=True)
class ObstacleLayerParams:
    """costmap_2d's ObstacleLayer parameters (sources: :class:`ObservationSourceParams`)."""

    enabled: bool = param(True, description="use the layer")
    observation_sources: str = param("", description="space separated source names")
    max_obstacle_height: float = param(2.0, description="highest obstacle marked (m)")
    combination_method: int = param(1, description="0 overwrite, 1 maximum")
    footprint_clearing_enabled: bool = param(True, description="clear under the robot")


@dataclass(frozen=True)
class ObservationSourceParams:
    """One observation source of an ObstacleLayer (``<layer>.<source>.*``)."""

    topic: str = param("", description="input topic (empty: the source's name)")
    data_type: str = param("PointCloud2", description="PointCloud2 or LaserScan")
    sensor_frame: str = param("", description="frame the data are in (empty: the header's)")
    observation_persistence: float = param(0.0, description="keep observations (s)")
    expected_update_rate: float = param(0.0, description="oldest data still current (s)")
    min_obstacle_height: float = param(0.0, description="lowest point used (m)")
    max_obstacle_height: float = param(2.0, description="highest point used (m)")
    obstacle_range: float = param(2.5, description="farthest point marked (m)")
    raytrace_range: float = param(3.0, description="farthest ray cleared (m)")
    inf_is_valid: bool = param(False, description="inf ranges clear to raytrace_range")
    clearing: bool = param(False, description="ray trace free space")
    marking: bool = param(True, description="mark obstacles")


@dataclass(frozen=True)
class InflationLayerParams:
    """costmap_2d's InflationLayer parameters."""

    enabled: bool = param(True, description="use the layer")
    inflation_radius: float = param(0.55, description="inflate up to (m)")
    cost_scaling_factor: float = param(10.0, description="exponential decay rate (1/m)")
    inflate_unknown: bool = param(False, description="inflate into unknown cells")


def layer_defaults(defaults: Mapping[str, Any], prefix: str) -> dict[str, Any]:
    """The entries of flat ``defaults`` directly under ``prefix`` (``obstacle_layer.``)."""
    out = {}
    for key, value in defaults.items():
        if key.startswith(prefix):
            rest = key[len(prefix) :]
            if "." not in rest:
                out[rest] = value
    return out


def declare_layer_params(
    costmap: CostmapROS, cls: type[T], sub: str, defaults: Mapping[str, Any]
) -> T:
    """Declare ``cls``'s fields under ``<costmap>.<sub>.`` with the launch defaults for ``sub``.

    ``sub`` is a layer name (``obstacle_layer``) or a layer's observation source
    (``obstacle_layer.scan``).
    """
    return declare_params(
        costmap.node,
        cls,
        prefix=f"{costmap.name}.{sub}.",
        defaults=layer_defaults(defaults, f"{sub}."),
    )


def layer_type(name: str, declared: str) -> str:
    """The registered type of layer ``name`` whose ``plugin`` parameter is ``declared``.

    Raises:
        CostmapError: Unknown type, or an empty ``plugin`` and nothing to guess from.
    """
    text = declared.rsplit("::", 1)[-1].rsplit("/", 1)[-1]
    if text in COSTMAP_LAYERS:
        return text
    if not declared:
        for key, guess in _GUESSES:
            if key in name:
                return guess
    msg = (
        f"costmap plugin {name!r} has type {declared!r}: expected "
        f"{', '.join(COSTMAP_LAYERS)} (set '{name}.plugin')"
    )
    raise CostmapError(msg)


def make_layer(costmap: CostmapROS, name: str, defaults: Mapping[str, Any]) -> Layer:
    """Declare ``<name>.plugin`` and build the layer through :data:`COSTMAP_LAYERS`.

    Raises:
        CostmapError: Unknown layer type or a factory that does not import.
    """
    declared = str(
        costmap.node.declare_parameter(
            f"{costmap.name}.{name}.plugin", defaults.get(f"{name}.plugin", "")
        ).value
    )
    kind = layer_type(name, declared)
    try:
        factory = resolve_factory(kind, COSTMAP_LAYERS, what="costmap layer")
    except UnknownPluginError as exc:
        raise CostmapError(str(exc)) from exc
    layer: Layer = factory(costmap, name, defaults)
    return layer


def make_static_layer(costmap: CostmapROS, name: str, defaults: Mapping[str, Any]) -> Layer:
    """StaticLayer: the map topic, translated to costs."""
    from visnav.mapping.static_layer import StaticLayer  # noqa: PLC0415 - lazy plugin

    p = declare_layer_params(costmap, StaticLayerParams, name, defaults)
    layer = StaticLayer(
        name,
        lethal_cost_threshold=p.lethal_cost_threshold,
        unknown_cost_value=p.unknown_cost_value,
        trinary_costmap=p.trinary_costmap,
        use_maximum=p.use_maximum,
        first_map_only=p.first_map_only,
        enabled=p.enabled,
    )
    costmap.subscribe_map(layer, p.map_topic)
    return layer


def make_inflation_layer(costmap: CostmapROS, name: str, defaults: Mapping[str, Any]) -> Layer:
    """InflationLayer: costs decaying with the distance to lethal cells."""
    from visnav.mapping.inflation_layer import InflationLayer  # noqa: PLC0415 - lazy plugin

    p = declare_layer_params(costmap, InflationLayerParams, name, defaults)
    return InflationLayer(
        name,
        inflation_radius=p.inflation_radius,
        cost_scaling_factor=p.cost_scaling_factor,
        inflate_unknown=p.inflate_unknown,
        enabled=p.enabled,
    )


def make_obstacle_layer(costmap: CostmapROS, name: str, defaults: Mapping[str, Any]) -> Layer:
    """ObstacleLayer: marking and clearing from LaserScan / PointCloud2 sources."""
    from visnav.mapping.observation import ObservationSource  # noqa: PLC0415 - lazy plugin
    from visnav.mapping.obstacle_layer import ObstacleLayer  # noqa: PLC0415

    p = declare_layer_params(costmap, ObstacleLayerParams, name, defaults)
    sources = []
    for src in p.observation_sources.split():
        sp = declare_layer_params(costmap, ObservationSourceParams, f"{name}.{src}", defaults)
        sources.append(
            ObservationSource(
                src,
                topic=sp.topic,
                data_type=sp.data_type,
                sensor_frame=sp.sensor_frame,
                observation_persistence=sp.observation_persistence,
                expected_update_rate=sp.expected_update_rate,
                min_obstacle_height=sp.min_obstacle_height,
                max_obstacle_height=sp.max_obstacle_height,
                obstacle_range=sp.obstacle_range,
                raytrace_range=sp.raytrace_range,
                inf_is_valid=sp.inf_is_valid,
                clearing=sp.clearing,
                marking=sp.marking,
            )
        )
    layer = ObstacleLayer(
        name,
        sources=sources,
        tf=costmap.tf,
        footprint_clearing_enabled=p.footprint_clearing_enabled,
        max_obstacle_height=p.max_obstacle_height,
        combination_method=p.combination_method,
        enabled=p.enabled,
    )
    costmap.subscribe_observations(layer, sources)
    return layer
