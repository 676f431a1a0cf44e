"""The lidar-ESKF's accuracy over many simulated noise draws, not one (chapter 08).

The lidar poses of the KITTI excerpts are simulated: the true pose plus white noise
(σ 0.2 m, 0.3°) drawn from a seed. One draw gives one ratio "ESKF error / raw pose error";
another draw gives another. :func:`lidar_seed_spread` runs the filter on the same real IMU
and truth with a new lidar draw per seed (:func:`kalman_course.data.simulate_lidar_poses`)
and reports, per seed, the position and attitude APE of the raw poses and of the ESKF and
the ESKF's mean pose NEES; :class:`SeedSpread` summarises them by median and range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_seed
from kalman_course.data import simulate_lidar_poses
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.spread import Spread, spread
from kalman_course.filters import eskf

__all__ = ["SeedRow", "SeedSpread", "lidar_seed_spread", "paired_ratio", "seed_spread_table"]


@dataclass(frozen=True)
class SeedRow:
    """One lidar noise draw: errors of the raw poses and of the ESKF against the truth.

    Attributes
    ----------
    seed : int
        Seed of the simulated lidar noise.
    raw_position, eskf_position : float
        Position APE (RMSE of |p − p_true|), m.
    raw_attitude_deg, eskf_attitude_deg : float
        Attitude APE (RMS rotation angle), degrees.
    nees_pose : float
        The ESKF's mean 6-dof pose NEES (expected value 6 when consistent).
    """

    seed: int
    raw_position: float
    raw_attitude_deg: float
    eskf_position: float
    eskf_attitude_deg: float
    nees_pose: float

    @property
    def position_ratio(self) -> float:
        """ESKF position APE / raw pose position APE."""
        return self.eskf_position / self.raw_position

    @property
    def attitude_ratio(self) -> float:
        """ESKF attitude APE / raw pose attitude APE."""
        return self.eskf_attitude_deg / self.raw_attitude_deg


@dataclass(frozen=True)
class SeedSpread:
    """The rows of one excerpt over several lidar noise seeds, and their spreads.

    Attributes
    ----------
    excerpt : str
        Name of the KITTI excerpt.
    rows : tuple of SeedRow
        One per seed, in the order the seeds were given.
    """

    excerpt: str
    rows: tuple

    def _spread(self, attr: str) -> Spread:
        return spread([getattr(r, attr) for r in self.rows], attr)

    @property
    def position_ratio(self) -> Spread:
        """ESKF / raw position APE over the seeds."""
        return self._spread("position_ratio")

    @property
    def attitude_ratio(self) -> Spread:
        """ESKF / raw attitude APE over the seeds."""
        return self._spread("attitude_ratio")

    @property
    def nees_pose(self) -> Spread:
        """Mean pose NEES over the seeds."""
        return self._spread("nees_pose")

    @property
    def eskf_position(self) -> Spread:
        """ESKF position APE over the seeds, m."""
        return self._spread("eskf_position")


def lidar_seed_spread(ex, config, seeds, *, P0=None, name: str | None = None) -> SeedSpread:
    """Run the lidar-ESKF on one excerpt with a new simulated lidar draw per seed.

    Each draw is ``simulate_lidar_poses(ex.truth, seed, σ_p, σ_θ)`` with the excerpt's own
    σ (white noise, the shipped draw's size); the IMU and the truth are the excerpt's real
    data, and the filter starts from the true state (``ex.initial_state()``).

    Parameters
    ----------
    ex : KittiExcerpt
        For example ``load_kitti("turns")``.
    config : EskfConfig or str
        The filter's settings.
    seeds : iterable of int
        Seeds of the lidar noise, at least one.
    P0 : array_like (15, 15), optional
        Initial covariance (default: the configuration's prior), e.g. with zero bias blocks
        for a filter whose biases stay frozen at zero.
    name : str, optional
        The excerpt's name for the result (default ``ex.name`` if it has one).

    Returns
    -------
    SeedSpread

    Raises
    ------
    ValueError
        If ``seeds`` is empty or holds a bad seed.
    """
    seeds = [as_seed(s) for s in seeds]
    if not seeds:
        raise ValueError("seeds must hold at least one seed")
    k0, s0 = ex.initial_state()
    rows = []
    for seed in seeds:
        lidar = simulate_lidar_poses(ex.truth, seed, ex.lidar.sigma_position, ex.lidar.sigma_attitude_deg)
        res = eskf.run(ex.imu, s0, config, ex.gravity, lidar=lidar, start=k0, P0=P0)
        m = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
        used = np.isin(lidar.t, res.t)
        raw = evaluate(lidar.t[used], lidar.position[used], lidar.rotation[used], ex.truth)
        rows.append(SeedRow(seed, raw["ape_position"], raw["ape_attitude_deg"], m["ape_position"],
                            m["ape_attitude_deg"], m["nees_pose"]))
    return SeedSpread(name or getattr(ex, "name", "excerpt"), tuple(rows))


def paired_ratio(numerator, denominator, attr: str = "eskf_position") -> Spread:
    """One figure of two filters compared draw by draw: its ratio on each shared seed, pooled.

    Parameters
    ----------
    numerator, denominator : iterable of SeedSpread
        The same excerpts, in the same order, each run on the same seeds (for example a
        variant and the reference filter).
    attr : str
        A :class:`SeedRow` figure, e.g. ``"eskf_position"`` or ``"nees_pose"``.

    Returns
    -------
    Spread
        Of ``numerator / denominator`` over every (excerpt, seed) pair.

    Raises
    ------
    ValueError
        If the excerpts or seeds do not pair up, or ``attr`` is no figure of a row.
    """
    if attr not in SeedRow.__dataclass_fields__ and not isinstance(getattr(SeedRow, attr, None), property):
        raise ValueError(f"attr must name a figure of SeedRow (e.g. 'eskf_position', 'nees_pose'), got {attr!r}")
    ratios = []
    num, den = list(numerator), list(denominator)
    if len(num) != len(den) or not num:
        raise ValueError(f"numerator and denominator must hold the same excerpts, got {len(num)} and {len(den)}")
    for a, b in zip(num, den):
        if a.excerpt != b.excerpt or [r.seed for r in a.rows] != [r.seed for r in b.rows]:
            raise ValueError(f"runs do not pair up: {a.excerpt} seeds {[r.seed for r in a.rows]} vs "
                             f"{b.excerpt} seeds {[r.seed for r in b.rows]}")
        ratios += [getattr(ra, attr) / getattr(rb, attr) for ra, rb in zip(a.rows, b.rows)]
    return spread(ratios, attr)


def seed_spread_table(spreads, position_bar: float = 0.4, attitude_bar: float = 0.3,
                      nees_band: tuple = (3.0, 12.0)) -> str:
    """A fixed-width table of the spreads against the design's acceptance bars.

    Parameters
    ----------
    spreads : iterable of SeedSpread
    position_bar, attitude_bar : float
        Largest acceptable ESKF / raw ratio of position and attitude APE.
    nees_band : (float, float)
        Acceptable range of the mean pose NEES.

    Returns
    -------
    str
        One row per excerpt: median (range) of each figure and how many seeds miss each bar.
    """
    lines = [f"{'excerpt':8s} {'seeds':>5s}  {'position ESKF/raw':>22s} {'> ' + str(position_bar):>5s}  "
             f"{'attitude ESKF/raw':>22s} {'> ' + str(attitude_bar):>5s}  {'pose NEES':>22s} {'out':>4s}",
             f"{'':8s} {'':5s}  {'median (min–max)':>22s} {'':5s}  {'median (min–max)':>22s} {'':5s}  "
             f"{'median (min–max)':>22s} {'':4s}"]
    for s in spreads:
        nees = np.asarray(s.nees_pose.values)
        out = int(np.sum((nees < nees_band[0]) | (nees > nees_band[1])))
        lines.append(f"{s.excerpt:8s} {len(s.rows):5d}  {s.position_ratio.text('.3f'):>22s} "
                     f"{s.position_ratio.count_above(position_bar):5d}  {s.attitude_ratio.text('.3f'):>22s} "
                     f"{s.attitude_ratio.count_above(attitude_bar):5d}  {s.nees_pose.text('.2f'):>22s} {out:4d}")
    return "\n".join(lines)
