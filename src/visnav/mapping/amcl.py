"""Adaptive Monte Carlo localisation (ROS amcl / nav2_amcl): numpy in and out, no graph.

:class:`Amcl` is amcl's particle filter on a 2D map: particles ``(x, y, yaw)`` start
around an initial pose (or uniformly over free space: ``global_localization``), move
with the ``diff`` odometry model, are weighted by the ``likelihood_field`` (or nav2's
``likelihood_field_prob``) laser model (:mod:`visnav.mapping.amcl_models`) and
resampled with KLD sampling (Fox 2003: as few particles as keep the error under
``pf_err`` with quantile ``pf_z``, between
``min_particles`` and ``max_particles``), with random particles injected when the
short-term average weight falls below the long-term one (``recovery_alpha_fast`` /
``recovery_alpha_slow``, Augmented MCL). The filter runs only after the odometry moved
more than ``update_min_d`` (in x or y) or ``update_min_a``, resamples every
``resample_interval`` updates, and its estimate is the weighted mean of the heaviest
cluster of particles (clusters: connected 0.5 m x 0.5 m x 10 degree histogram bins, amcl's
kd-tree bins).

Where visnav differs from amcl, and why:

* **Convergence is checked, and reported.** amcl publishes ``map -> odom`` from whatever
  its particles say, so a robot started far from where the map says it is drives on a
  wrong pose. Here every update measures the *scan fit* at the estimate: the fraction
  of the used beams whose end point lies within ``scan_fit_distance`` of an obstacle
  (among the beams that fit or end in a known cell: unknown space is no evidence).
  :attr:`Amcl.status` is ``localized`` while the fit is at least ``min_scan_fit`` and the
  heaviest cluster holds at least half the weight; ``not_converged`` when an initial pose
  lies outside the map or the first updates do not fit; ``lost`` after
  ``lost_after_updates`` poor updates in a row. The node publishes ``map -> odom`` only
  while localised, so the navigator stops (its robot pose lookup fails) instead of
  driving on a pose that does not match the map.
* Resampling draws samples independently from the weights (as amcl's ``pf.c``) but
  stops by a vectorised test of the KLD bound over the whole candidate list at once.
* The map's distance field is an exact Euclidean distance transform to the obstacle
  cells' surface, looked up bilinearly (amcl: a brushfire between cell centres, read at
  the end point's cell, which puts every wall half a cell too far); the estimate's
  covariance is that of the heaviest cluster
  (amcl reports the whole set's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from visnav.graph.param_dataclass import param
from visnav.mapping.amcl_models import (
    Beams,
    beam_endpoints,
    likelihood_field_weights,
    sample_diff_motion,
)
from visnav.mapping.errors import MappingError

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from visnav.mapping.likelihood_field import LikelihoodField

__all__ = [
    "Amcl",
    "AmclError",
    "AmclParams",
    "LocalizationStatus",
    "PoseEstimate",
    "kld_sample_limit",
]

BIN_SIZE = (0.5, 0.5, math.radians(10.0))
"""amcl's kd-tree histogram bins: x, y (m) and yaw (rad)."""


class AmclError(MappingError, ValueError):
    """A bad AMCL parameter or input (the message names it and the fix)."""


@dataclass(frozen=True)
class AmclParams:
    """nav2_amcl's parameters (names and defaults) plus visnav's convergence check."""

    min_particles: int = param(500, description="fewest particles", range=(1, 1_000_000))
    max_particles: int = param(2000, description="most particles", range=(1, 1_000_000))
    pf_err: float = param(0.05, description="KLD error bound (ROS 1 kld_err)", range=(1e-6, 1.0))
    pf_z: float = param(0.99, description="KLD quantile (ROS 1 kld_z)", range=(0.0, 10.0))
    alpha1: float = param(0.2, description="rotation noise from rotation", range=(0.0, 100.0))
    alpha2: float = param(0.2, description="rotation noise from translation", range=(0.0, 100.0))
    alpha3: float = param(0.2, description="translation noise from translation", range=(0.0, 100.0))
    alpha4: float = param(0.2, description="translation noise from rotation", range=(0.0, 100.0))
    robot_model_type: str = param(
        "nav2_amcl::DifferentialMotionModel", description="odometry model (differential only)"
    )
    laser_model_type: str = param("likelihood_field", description="laser model")
    z_hit: float = param(0.5, description="weight of the hit term", range=(0.0, 1.0))
    z_rand: float = param(0.5, description="weight of the random term", range=(0.0, 1.0))
    sigma_hit: float = param(0.2, description="hit term std dev (m)", range=(1e-4, 10.0))
    laser_likelihood_max_dist: float = param(
        2.0, description="distance field cap (m)", range=(1e-3, 100.0)
    )
    laser_max_range: float = param(100.0, description="max range used (m; <= 0: the scan's)")
    laser_min_range: float = param(-1.0, description="min range used (m; <= 0: the scan's)")
    max_beams: int = param(60, description="beams used per scan", range=(2, 100_000))
    update_min_d: float = param(0.25, description="translation before an update (m)")
    update_min_a: float = param(0.2, description="rotation before an update (rad)")
    resample_interval: int = param(1, description="updates between resamplings", range=(1, 1000))
    recovery_alpha_slow: float = param(0.0, description="slow weight average rate (0 off)")
    recovery_alpha_fast: float = param(0.0, description="fast weight average rate (0 off)")
    initial_cov_xx: float = param(0.25, description="initial pose variance x (m^2)")
    initial_cov_yy: float = param(0.25, description="initial pose variance y (m^2)")
    initial_cov_aa: float = param(
        (math.pi / 12.0) ** 2, description="initial pose variance yaw (rad^2)"
    )
    seed: int = param(0, description="random seed of the filter")
    min_scan_fit: float = param(
        0.5, description="visnav: beam fraction that must fit to be localised", range=(0.0, 1.0)
    )
    scan_fit_distance: float = param(
        0.2, description="visnav: a beam fits within this of an obstacle (m)", range=(0.0, 10.0)
    )
    min_fit_beams: int = param(
        8, description="visnav: fewer valid beams leave the status as it is", range=(1, 100_000)
    )
    lost_after_updates: int = param(
        5, description="visnav: poor updates in a row before lost", range=(1, 1000)
    )

    def __post_init__(self) -> None:
        """Refuse combinations a single parameter's range cannot express."""
        if self.min_particles > self.max_particles:
            msg = (
                f"amcl: min_particles {self.min_particles} > max_particles "
                f"{self.max_particles}; expected min_particles <= max_particles (500, 2000)"
            )
            raise AmclError(msg)
        if self.robot_model_type.rsplit("::", 1)[-1].lower() not in (
            "differentialmotionmodel",
            "differential",
            "diff",
            "diff-corrected",
        ):
            msg = (
                f"amcl: robot_model_type {self.robot_model_type!r} is not available; "
                "expected nav2_amcl::DifferentialMotionModel (visnav has no omni model)"
            )
            raise AmclError(msg)
        if self.laser_model_type not in ("likelihood_field", "likelihood_field_prob"):
            msg = (
                f"amcl: laser_model_type {self.laser_model_type!r} is not available; "
                "expected likelihood_field or likelihood_field_prob (visnav has no beam model)"
            )
            raise AmclError(msg)

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        """``(alpha1, alpha2, alpha3, alpha4)``."""
        return (self.alpha1, self.alpha2, self.alpha3, self.alpha4)


@dataclass(frozen=True)
class PoseEstimate:
    """The filter's pose: the heaviest cluster's mean and covariance.

    Attributes:
        x: Position x in the map (m).
        y: Position y in the map (m).
        yaw: Heading (rad).
        cov: ``(3, 3)`` covariance of ``x, y, yaw``.
        weight: Share of the total weight in the cluster.
        clusters: Number of clusters.
    """

    x: float
    y: float
    yaw: float
    cov: NDArray[np.float64]
    weight: float
    clusters: int


@dataclass
class LocalizationStatus:
    """Whether the filter is localised, and why not.

    Attributes:
        state: ``waiting`` (no initial pose), ``initial`` (not checked yet),
            ``localized``, ``not_converged`` or ``lost``.
        text: One line for logs and ``~/status``.
        scan_fit: Fraction of beams that fit at the last check (None before one).
        bad_updates: Poor updates in a row.
    """

    state: str = "waiting"
    text: str = "waiting for an initial pose (initial_pose / initialpose / global localisation)"
    scan_fit: float | None = None
    bad_updates: int = 0

    @property
    def localized(self) -> bool:
        """Whether ``map -> odom`` may be published."""
        return self.state == "localized"


def kld_sample_limit(bins: NDArray[np.int64], params: AmclParams) -> NDArray[np.int64]:
    """amcl's ``pf_resample_limit`` for each count of occupied histogram bins ``k``."""
    k = bins.astype(np.float64)
    km1 = np.maximum(k - 1.0, 1.0)
    b = 2.0 / (9.0 * km1)
    x = 1.0 - b + np.sqrt(b) * params.pf_z
    n = np.ceil(km1 / (2.0 * params.pf_err) * x * x * x)
    n = np.where(k <= 1, params.max_particles, n)
    return np.clip(n, params.min_particles, params.max_particles).astype(np.int64)


def _bin_keys(poses: NDArray[np.float64]) -> NDArray[np.int64]:
    keys: NDArray[np.int64] = np.floor(poses / np.asarray(BIN_SIZE)).astype(np.int64)
    return keys


@dataclass
class _Odom:
    last: tuple[float, float, float] | None = None
    force: bool = True
    updates: int = 0
    w_slow: float = 0.0
    w_fast: float = 0.0


class Amcl:
    """amcl's particle filter (module docstring).

    Args:
        field: The map's likelihood field (its ``max_dist`` is ``laser_likelihood_max_dist``).
        params: The parameters (nav2_amcl's defaults).
    """

    def __init__(self, field: LikelihoodField, params: AmclParams | None = None) -> None:
        self.params = params or AmclParams()
        self.field = field
        self.rng = np.random.default_rng(self.params.seed)
        self.poses: NDArray[np.float64] = np.zeros((0, 3))
        self.weights: NDArray[np.float64] = np.zeros(0)
        self.status = LocalizationStatus()
        self.estimate: PoseEstimate | None = None
        self._odom = _Odom()

    # ------------------------------------------------------------------ initialisation
    def set_initial_pose(
        self, x: float, y: float, yaw: float, cov: tuple[float, float, float] | None = None
    ) -> None:
        """Spread ``max_particles`` around a pose (amcl's ``initialpose``).

        Args:
            x: Position x in the map (m).
            y: Position y in the map (m).
            yaw: Heading (rad).
            cov: Variances ``(xx, yy, aa)``; default ``initial_cov_*``.
        """
        p = self.params
        xx, yy, aa = (
            cov if cov is not None else (p.initial_cov_xx, p.initial_cov_yy, p.initial_cov_aa)
        )
        n = p.max_particles
        noise = self.rng.standard_normal((n, 3)) * np.sqrt(np.maximum([xx, yy, aa], 0.0))
        self.poses = np.array([x, y, yaw]) + noise
        self.poses[:, 2] = np.remainder(self.poses[:, 2] + math.pi, 2 * math.pi) - math.pi
        self.weights = np.full(n, 1.0 / n)
        self._reset_filter()
        self._summarise()
        if not bool(self.field.inside(np.array([x, y]))):
            x0, y0, x1, y1 = self.field.bounds()
            self.status = LocalizationStatus(
                "not_converged",
                f"cannot localise: the initial pose ({x:.2f}, {y:.2f}) is outside the map "
                f"(x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f}); the robot will not be given "
                "map -> odom. Fix: start the robot inside the saved map, or publish a pose "
                "on initialpose",
            )
        else:
            self.status = LocalizationStatus(
                "initial", f"initial pose ({x:.2f}, {y:.2f}, {yaw:.2f}) not checked yet"
            )

    def global_localization(self) -> None:
        """Spread ``max_particles`` uniformly over free space (amcl's ``global_localization``)."""
        n = self.params.max_particles
        self.poses = self.field.sample_free(n, self.rng)
        self.weights = np.full(n, 1.0 / n)
        self._reset_filter()
        self._summarise()
        self.status = LocalizationStatus("initial", "global localisation: not converged yet")

    def force_update(self) -> None:
        """Run the next :meth:`update` without motion (amcl's ``request_nomotion_update``)."""
        self._odom.force = True

    def set_map(self, field: LikelihoodField) -> None:
        """Use a new map; the particles stay (amcl re-initialises on a new map)."""
        self.field = field
        self._odom.force = True

    def _reset_filter(self) -> None:
        self._odom.force = True
        self._odom.w_slow = self._odom.w_fast = 0.0

    @property
    def initialized(self) -> bool:
        """Whether there are particles."""
        return bool(self.poses.shape[0] > 0)

    # ------------------------------------------------------------------ update
    def needs_update(self, odom: tuple[float, float, float]) -> bool:
        """Whether the odometry moved enough since the last update (or one is forced)."""
        last = self._odom.last
        if not self.initialized:
            return False
        if self._odom.force or last is None:
            return True
        p = self.params
        return (
            abs(odom[0] - last[0]) > p.update_min_d
            or abs(odom[1] - last[1]) > p.update_min_d
            or abs(math.remainder(odom[2] - last[2], 2 * math.pi)) > p.update_min_a
        )

    def update(
        self,
        odom: tuple[float, float, float],
        beams: Beams,
        laser: tuple[float, float, float],
    ) -> bool:
        """One filter step if :meth:`needs_update`: motion, weighting, resampling, estimate.

        Args:
            odom: The base's odometry pose ``(x, y, yaw)`` at the scan's time.
            beams: The scan's beams (:func:`~visnav.mapping.amcl_models.select_beams`).
            laser: The laser's pose in the base frame.

        Returns:
            Whether the filter ran.
        """
        if not self.needs_update(odom):
            return False
        st = self._odom
        if st.last is not None:
            sample_diff_motion(self.poses, st.last, odom, self.params.alphas, self.rng)
        st.last = odom
        st.force = False
        self._weigh(beams, laser)
        st.updates += 1
        if st.updates % self.params.resample_interval == 0:
            self._resample()
        self._summarise()
        self._check(beams, laser)
        return True

    def map_to_odom(self) -> tuple[float, float, float] | None:
        """``map -> odom`` as ``(x, y, yaw)`` from the estimate and the odometry at the last update.

        ``map_pose = map_to_odom ⊕ odom_pose``: between updates, the odometry carries the
        estimate forward (as amcl's published transform does).
        """
        e, o = self.estimate, self._odom.last
        if e is None or o is None:
            return None
        yaw = math.remainder(e.yaw - o[2], 2 * math.pi)
        c, s = math.cos(yaw), math.sin(yaw)
        return (e.x - (c * o[0] - s * o[1]), e.y - (s * o[0] + c * o[1]), yaw)

    def _weigh(self, beams: Beams, laser: tuple[float, float, float]) -> None:
        p = self.params
        product = p.laser_model_type == "likelihood_field_prob"
        factor = likelihood_field_weights(
            self.field, self.poses, beams, laser, z_hit=p.z_hit, z_rand=p.z_rand,
            sigma_hit=p.sigma_hit, product=product,
        )  # fmt: skip
        top = float(factor.max()) if product else 0.0
        if product:  # log-likelihoods: scale by the best so that exp() cannot underflow all
            factor = np.exp(factor - top)
        w = self.weights * factor
        total = float(w.sum())
        if not (total > 0.0 and math.isfinite(total)):
            self.weights = np.full(self.poses.shape[0], 1.0 / self.poses.shape[0])
            return
        self.weights = w / total
        w_avg = total / self.poses.shape[0]
        if product:  # the average likelihood per beam (a product over beams has no scale)
            w_avg = math.exp((top + math.log(total)) / max(1, beams.ranges.shape[0]))
        st = self._odom
        st.w_slow = (
            w_avg if st.w_slow == 0.0 else st.w_slow + p.recovery_alpha_slow * (w_avg - st.w_slow)
        )
        st.w_fast = (
            w_avg if st.w_fast == 0.0 else st.w_fast + p.recovery_alpha_fast * (w_avg - st.w_fast)
        )

    def _resample(self) -> None:
        p = self.params
        st = self._odom
        w_diff = 0.0
        if st.w_slow > 0.0 and p.recovery_alpha_slow > 0.0 and p.recovery_alpha_fast > 0.0:
            w_diff = max(0.0, 1.0 - st.w_fast / st.w_slow)
        m = p.max_particles
        cdf = np.cumsum(self.weights)
        cdf /= cdf[-1]
        index = np.minimum(np.searchsorted(cdf, self.rng.random(m), side="right"), len(cdf) - 1)
        candidates = self.poses[index]
        if w_diff > 0.0:
            fresh = self.rng.random(m) < w_diff
            if fresh.any() and self.field.free_count > 0:
                candidates[fresh] = self.field.sample_free(int(fresh.sum()), self.rng)
            st.w_slow = st.w_fast = 0.0
        keys = _bin_keys(candidates)
        _, first = np.unique(keys, axis=0, return_index=True)
        new_bin = np.zeros(m, dtype=np.int64)
        new_bin[first] = 1
        bins = np.cumsum(new_bin)
        limit = kld_sample_limit(bins, p)
        counts = np.arange(1, m + 1)
        over = np.nonzero(counts > limit)[0]
        n = int(over[0]) + 1 if over.size else m
        n = max(n, min(p.min_particles, m))
        self.poses = np.ascontiguousarray(candidates[:n])
        self.weights = np.full(n, 1.0 / n)

    # ------------------------------------------------------------------ estimate
    def _summarise(self) -> None:
        """Cluster the particles and keep the heaviest cluster's mean as the estimate."""
        keys = _bin_keys(self.poses)
        lo = keys.min(axis=0)
        shape = tuple(int(s) for s in keys.max(axis=0) - lo + 1)
        occupied = np.zeros(shape, dtype=bool)
        local = keys - lo
        occupied[local[:, 0], local[:, 1], local[:, 2]] = True
        labels, count = ndimage.label(occupied, structure=np.ones((3, 3, 3), dtype=bool))
        label = labels[local[:, 0], local[:, 1], local[:, 2]]
        totals = np.bincount(label, weights=self.weights, minlength=count + 1)
        best = int(np.argmax(totals))
        sel = label == best
        w = self.weights[sel]
        ws = float(w.sum())
        pts = self.poses[sel]
        mx, my = float(w @ pts[:, 0]) / ws, float(w @ pts[:, 1]) / ws
        c, s = float(w @ np.cos(pts[:, 2])) / ws, float(w @ np.sin(pts[:, 2])) / ws
        yaw = math.atan2(s, c)
        dx, dy = pts[:, 0] - mx, pts[:, 1] - my
        cov = np.zeros((3, 3))
        cov[0, 0] = float(w @ (dx * dx)) / ws
        cov[1, 1] = float(w @ (dy * dy)) / ws
        cov[0, 1] = cov[1, 0] = float(w @ (dx * dy)) / ws
        cov[2, 2] = -2.0 * math.log(max(math.hypot(c, s), 1e-12))
        total = float(self.weights.sum())
        self.estimate = PoseEstimate(mx, my, yaw, cov, ws / total if total > 0 else 0.0, count)

    def scan_fit(self, beams: Beams, laser: tuple[float, float, float]) -> float | None:
        """Fraction of the evaluable beams within ``scan_fit_distance`` of an obstacle.

        A beam is evaluable when it fits or its end point lies in a known cell: a beam
        ending in unknown space (a part of the floor the saved map never saw) is no
        evidence either way. None with fewer than ``min_fit_beams`` evaluable beams.
        """
        if self.estimate is None:
            return None
        e = self.estimate
        ends = beam_endpoints(np.array([[e.x, e.y, e.yaw]]), beams, laser)[0]
        fits = self.field.distance_at(ends) <= self.params.scan_fit_distance
        evaluable = fits | self.field.is_known(ends)
        count = int(evaluable.sum())
        if count < self.params.min_fit_beams:
            return None
        return float(fits.sum()) / count

    def _check(self, beams: Beams, laser: tuple[float, float, float]) -> None:
        st = self.status
        if st.state == "not_converged" and st.scan_fit is None and "outside the map" in st.text:
            return  # an initial pose off the map stays refused until a new one comes
        fit = self.scan_fit(beams, laser)
        p = self.params
        e = self.estimate
        if e is None:
            return
        if fit is None:
            if st.state == "initial":  # nothing to check the pose with: trust it as amcl does
                self.status = LocalizationStatus(
                    "localized", f"initial pose trusted (only {beams.ranges.shape[0]} beams)"
                )
            return
        good = fit >= p.min_scan_fit and e.weight >= 0.5
        where = f"({e.x:.2f}, {e.y:.2f}, {e.yaw:.2f})"
        if good:
            self.status = LocalizationStatus("localized", f"localized at {where}", fit, 0)
            return
        bad = st.bad_updates + 1
        why = (
            f"{fit:.0%} of {beams.ranges.shape[0]} beams fit the map within "
            f"{p.scan_fit_distance:g} m at {where} (min_scan_fit {p.min_scan_fit:g}), the "
            f"best cluster holds {e.weight:.0%} of the weight"
        )
        if st.state in ("initial", "not_converged"):
            self.status = LocalizationStatus(
                "not_converged",
                f"cannot localise: {why}. Fix: check that the map belongs to this world and "
                "the start pose, or publish a pose on initialpose",
                fit,
                bad,
            )
        elif bad >= p.lost_after_updates:
            self.status = LocalizationStatus(
                "lost", f"lost after {bad} poor updates: {why}", fit, bad
            )
        else:
            self.status = LocalizationStatus(st.state, st.text, fit, bad)
