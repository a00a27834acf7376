"""Procedural, seeded texture images for visnav worlds.

MuJoCo's own builtin textures (``checker``, ``gradient``, ``flat``) have no seed:
their ``random`` marks come from a fixed generator. Visual SLAM needs surfaces
that differ from one another, so visnav generates its ``noise`` textures here,
with numpy, from an explicit seed, and hands MuJoCo the pixels.

The ``noise`` texture is blocky multi-octave value noise: random cells of
``scale`` pixels, plus finer octaves at half and a quarter of that size,
blended and mapped onto the segment between two colours (with a little random
per-cell hue jitter). The sharp cell borders give corner detectors (ORB, FAST)
something to find at every viewing distance.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = ["noise_image"]


def _octave(
    rng: np.random.Generator, height: int, width: int, cell: int
) -> npt.NDArray[np.float64]:
    """One octave: i.i.d. uniform values on a grid of ``cell``-pixel squares."""
    cell = max(1, cell)
    ny = -(-height // cell)
    nx = -(-width // cell)
    values = rng.random((ny, nx))
    return np.repeat(np.repeat(values, cell, axis=0), cell, axis=1)[:height, :width]


def noise_image(
    width: int,
    height: int,
    *,
    seed: int,
    rgb1: tuple[float, float, float],
    rgb2: tuple[float, float, float],
    scale: int = 16,
    octaves: int = 3,
    jitter: float = 0.15,
) -> npt.NDArray[np.uint8]:
    """Blocky value noise between two colours, deterministic for a seed.

    Args:
        width: Image width in pixels (> 0).
        height: Image height in pixels (> 0).
        seed: Seed of the numpy generator; equal seeds give equal images.
        rgb1: First colour, components in [0, 1].
        rgb2: Second colour, components in [0, 1].
        scale: Size of the coarsest cells in pixels.
        octaves: Number of octaves (each halves the cell size).
        jitter: Amplitude of the independent per-channel noise of the finest
            octave, which keeps neighbouring cells distinguishable in colour.

    Returns:
        ``(height, width, 3)`` uint8 RGB image.
    """
    rng = np.random.default_rng(seed)
    total = np.zeros((height, width))
    weight = 0.0
    amplitude = 1.0
    for octave in range(max(1, octaves)):
        total += amplitude * _octave(rng, height, width, scale >> octave)
        weight += amplitude
        amplitude *= 0.5
    mix = total / weight
    # Stretch the blend (a sum of uniforms crowds the middle) so both colours appear.
    mix = np.clip((mix - mix.mean()) * 2.2 + 0.5, 0.0, 1.0)
    c1 = np.asarray(rgb1, dtype=np.float64)
    c2 = np.asarray(rgb2, dtype=np.float64)
    image = c1 + mix[..., None] * (c2 - c1)
    fine = max(1, scale >> max(0, octaves - 1))
    for channel in range(3):
        image[..., channel] += jitter * (_octave(rng, height, width, fine) - 0.5)
    return np.asarray(np.clip(image * 255.0 + 0.5, 0, 255), dtype=np.uint8)
