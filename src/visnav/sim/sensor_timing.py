"""When sensors fire in sim time, and the seed each sensor's noise uses.

A :class:`SensorClock` decides, once per physics step, whether a sensor with
an ``update_rate`` produces a measurement. It works on integer nanoseconds and
fires at the first step at or after each multiple of the period (``k *
period``), so rates do not drift with the step size: a 30 Hz camera on a 2 ms
physics step fires 30 times per simulated second (Gazebo's sensor timing,
without its accumulated drift). ``update_rate`` 0 fires on every step, as
Gazebo's "as fast as possible".

:func:`sensor_seed` derives a stable per-sensor seed from the run's seed and
the sensor's name, so adding a sensor does not change the noise of the others
and two runs with one seed give identical messages.
"""

from __future__ import annotations

import hashlib
import math

from visnav.sim.errors import SensorTimingError

__all__ = ["SensorClock", "sensor_seed"]

_NS_PER_S = 1_000_000_000


class SensorClock:
    """Fire-or-not decisions for one sensor at ``rate_hz`` in sim time.

    Args:
        rate_hz: measurements per simulated second; 0 means every step.
        start_ns: sim time of the first possible measurement.

    Raises:
        SensorTimingError: a negative or non-finite rate.
    """

    def __init__(self, rate_hz: float, *, start_ns: int = 0) -> None:
        if not math.isfinite(rate_hz) or rate_hz < 0.0:
            msg = f"update_rate is {rate_hz!r}: expected a finite rate >= 0 Hz (0 = every step)"
            raise SensorTimingError(msg)
        self.rate_hz = float(rate_hz)
        self.period_ns = 0 if rate_hz == 0.0 else max(1, round(_NS_PER_S / rate_hz))
        self._next_ns = int(start_ns)

    @property
    def next_ns(self) -> int:
        """Sim time at or after which the next measurement is due."""
        return self._next_ns

    def restart(self, start_ns: int) -> None:
        """Schedule the next measurement at ``start_ns`` (sim time went back)."""
        self._next_ns = int(start_ns)

    def due(self, now_ns: int) -> bool:
        """Return True (and schedule the next one) if a measurement is due at ``now_ns``."""
        if now_ns < self._next_ns:
            return False
        if self.period_ns == 0:
            self._next_ns = now_ns
            return True
        missed = (now_ns - self._next_ns) // self.period_ns
        self._next_ns += (missed + 1) * self.period_ns
        return True


def sensor_seed(run_seed: int, name: str) -> int:
    """Return a stable 63-bit seed for the sensor ``name`` in a run seeded ``run_seed``."""
    digest = hashlib.blake2b(f"{int(run_seed)}:{name}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") >> 1
