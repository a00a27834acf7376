"""Sensor error model specs a robot description carries (wheel encoders, RGB-D depth).

The elements are read from the ``<gazebo>`` plugins (Gazebo itself ignores them, so the
same description still loads in Gazebo); the models that apply them at run time are in
:mod:`visnav.sim.noise_models`, which explains them with their sources.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import xml.etree.ElementTree as ET

    from numpy.typing import NDArray

    from visnav.description._sdf_reader import SdfReader

__all__ = [
    "WHEEL_NOISE_TAGS",
    "DepthNoise",
    "WheelOdometryNoise",
    "parse_depth_noise",
    "parse_wheel_noise",
]

WHEEL_NOISE_TAGS = (
    "wheel_radius_error",
    "wheel_separation_error",
    "wheel_slip",
    "encoder_resolution",
)
"""Diff-drive plugin elements read by :func:`parse_wheel_noise`."""

_DEPTH_NOISE_TAGS = ("type", "baseline", "focal_length", "disparity_stddev", "disparity_step")


@dataclass(frozen=True, kw_only=True)
class WheelOdometryNoise:
    """Error model of wheel-encoder odometry (all zero: Gazebo's exact encoders).

    Attributes:
        wheel_radius_error: Relative standard deviation of each wheel's effective
            radius against the nominal ``wheel_diameter / 2``; one draw per wheel and
            run (Borenstein's ``E_d`` comes from the two draws' ratio).
        wheel_separation_error: Relative standard deviation of the effective wheel
            separation (Borenstein's ``E_b``); one draw per run.
        wheel_slip: Slip of each wheel in m per square root of the metre it rolls:
            the rim travel of an update gets gaussian noise of variance
            ``wheel_slip^2 * |travel|``, so it does not depend on the update rate.
        encoder_resolution: Encoder ticks per wheel revolution (0: exact angles).
    """

    wheel_radius_error: float = 0.0
    wheel_separation_error: float = 0.0
    wheel_slip: float = 0.0
    encoder_resolution: int = 0

    @property
    def active(self) -> bool:
        """True if the model changes the odometry at all."""
        return bool(
            self.wheel_radius_error
            or self.wheel_separation_error
            or self.wheel_slip
            or self.encoder_resolution
        )


@dataclass(frozen=True, kw_only=True)
class DepthNoise:
    """Disparity noise of a structured-light or stereo RGB-D sensor (module docstring).

    Attributes:
        baseline: Projector-camera (or stereo) baseline ``b`` in m.
        focal_length: Focal length ``f`` of the depth sensor in pixels.
        disparity_stddev: Gaussian disparity noise ``sigma_d`` in pixels.
        disparity_step: Disparity quantisation step in pixels (0: none).
    """

    baseline: float = 0.075
    focal_length: float = 580.0
    disparity_stddev: float = 0.0
    disparity_step: float = 0.0

    @property
    def active(self) -> bool:
        """True if the model changes depth at all."""
        return self.disparity_stddev > 0.0 or self.disparity_step > 0.0

    def sigma(self, z: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
        """Standard deviation of the depth error at range ``z`` (m), quantisation included.

        ``z^2 / (f b) * sqrt(sigma_d^2 + step^2 / 12)``: first-order propagation of the
        disparity noise plus the uniform rounding error of the disparity.
        """
        spread = math.sqrt(self.disparity_stddev**2 + self.disparity_step**2 / 12.0)
        return np.square(z) / (self.focal_length * self.baseline) * spread


def parse_wheel_noise(reader: SdfReader, plugin: ET.Element, *, owner: str) -> WheelOdometryNoise:
    """Read :data:`WHEEL_NOISE_TAGS` from a diff-drive ``<plugin>`` (absent: no noise)."""
    resolution = reader.number(plugin, "encoder_resolution", 0.0, owner=owner, minimum=0.0)
    if resolution != int(resolution):
        found = plugin.find("encoder_resolution")
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}<encoder_resolution> = {resolution:g} is not a whole number of ticks",
            "write the encoder's ticks per wheel revolution, e.g. 4096 (0 = exact)",
        )
    return WheelOdometryNoise(
        wheel_radius_error=reader.number(
            plugin, "wheel_radius_error", 0.0, owner=owner, minimum=0.0
        ),
        wheel_separation_error=reader.number(
            plugin, "wheel_separation_error", 0.0, owner=owner, minimum=0.0
        ),
        wheel_slip=reader.number(plugin, "wheel_slip", 0.0, owner=owner, minimum=0.0),
        encoder_resolution=int(resolution),
    )


def parse_depth_noise(reader: SdfReader, plugin: ET.Element, *, owner: str) -> DepthNoise:
    """Read ``<depth_noise>`` from a depth camera's plugin (absent: no depth noise)."""
    element = plugin.find("depth_noise")
    if element is None:
        return DepthNoise()
    kind = (reader.text(element, "type") or "disparity").lower()
    if kind == "none":
        return DepthNoise()
    if kind != "disparity":
        raise reader.error(
            element,
            f"{owner}<depth_noise><type> {kind!r} is not a depth noise model",
            "write <type>disparity</type> (or none)",
        )
    reader.unknown(element, _DEPTH_NOISE_TAGS, owner=owner, what="<depth_noise>")
    return DepthNoise(
        baseline=reader.number(element, "baseline", 0.075, owner=owner, minimum=0.0, strict=True),
        focal_length=reader.number(
            element, "focal_length", 580.0, owner=owner, minimum=0.0, strict=True
        ),
        disparity_stddev=reader.number(element, "disparity_stddev", 0.0, owner=owner, minimum=0.0),
        disparity_step=reader.number(element, "disparity_step", 0.0, owner=owner, minimum=0.0),
    )
