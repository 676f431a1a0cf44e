"""The lidar-ESKF's accuracy over many simulated noise draws, not one (chapter 08).

The lidar poses of the KITTI excerpts are simulated: the true pose plus white noise
(σ 0.2 m, 0.3°) drawn from a seed. One draw gives one ratio "ESKF error / raw pose error";
another draw gives another. :func:`lidar_seed_spread` runs the filter on the same real IMU
and truth with a new lidar draw per seed (:func:`kalman_course.data.simulate_lidar_poses`)
and reports, per seed, the position and attitude APE of the raw poses and of the ESKF and
the ESKF's mean NEES, of the pose and of its position and attitude blocks separately, each
judged against the χ² interval of a run's average (``average_band``);
:class:`SeedSpread` summarises them by median and range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_seed
from kalman_course.data import simulate_lidar_poses
from kalman_course.evaluation.consistency import average_band
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.spread import Spread, spread
from kalman_course.filters import eskf

__all__ = ["SeedRow", "SeedSpread", "lidar_seed_spread", "paired_ratio", "seed_spread_table", "NEES_BLOCKS",
           "POSITION_TARGET", "ATTITUDE_TARGET"]

#: The blocks whose NEES each seed reports: the 6-dof pose and its two 3-dof parts.
NEES_BLOCKS = ("pose", "position", "attitude")
#: The course's own targets for ESKF / raw APE (what the lidar ESKF was built to reach on
#: white simulated poses); design goals, not statistical tests.
POSITION_TARGET, ATTITUDE_TARGET = 0.4, 0.3


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
    nees_position, nees_attitude : float
        Mean NEES of the position and of the attitude block alone (3 dof each, expected 3).
    verdicts : dict of str to str
        ``"pose"``, ``"position"``, ``"attitude"`` -> the verdict of that mean NEES against
        the χ² interval of a run's average over its steps (``average_band``, 95 %).
    """

    seed: int
    raw_position: float
    raw_attitude_deg: float
    eskf_position: float
    eskf_attitude_deg: float
    nees_pose: float
    nees_position: float
    nees_attitude: float
    verdicts: dict

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
    def nees_position(self) -> Spread:
        """Mean position-block NEES (3 dof) over the seeds."""
        return self._spread("nees_position")

    @property
    def nees_attitude(self) -> Spread:
        """Mean attitude-block NEES (3 dof) over the seeds."""
        return self._spread("nees_attitude")

    def inconsistent(self, block: str = "pose") -> int:
        """How many seeds' mean NEES of ``block`` ("pose", "position", "attitude") misses its χ² interval."""
        if block not in NEES_BLOCKS:
            raise ValueError(f"block must be one of {NEES_BLOCKS}, got {block!r}")
        return sum(r.verdicts[block] != "consistent" for r in self.rows)

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
        records = {"pose": (m["nees"], 6), "position": (m["nees_position"], 3), "attitude": (m["nees_attitude"], 3)}
        verdicts = {block: average_band(values[None, :], dof).verdict for block, (values, dof) in records.items()}
        rows.append(SeedRow(seed, raw["ape_position"], raw["ape_attitude_deg"], m["ape_position"],
                            m["ape_attitude_deg"], m["nees_pose"], float(np.mean(m["nees_position"])),
                            float(np.mean(m["nees_attitude"])), verdicts))
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


def seed_spread_table(spreads, position_target: float = POSITION_TARGET,
                      attitude_target: float = ATTITUDE_TARGET) -> str:
    """A fixed-width table of the spreads: accuracy against the course's targets, NEES against χ².

    Parameters
    ----------
    spreads : iterable of SeedSpread
    position_target, attitude_target : float
        The course's targets for the ESKF / raw ratio of position and attitude APE (design
        goals; the table counts the seeds above them).

    Returns
    -------
    str
        One row per excerpt: median (range) of each figure, how many seeds miss each
        target, and for the pose, position and attitude NEES how many seeds' averages lie
        outside their 95 % χ² interval (``average_band``).
    """
    head = (f"{'excerpt':8s} {'seeds':>5s}  {'position ESKF/raw':>22s} {'> ' + str(position_target):>5s}  "
            f"{'attitude ESKF/raw':>22s} {'> ' + str(attitude_target):>5s}")
    sub = f"{'':8s} {'':5s}  {'median (min–max)':>22s} {'':5s}  {'median (min–max)':>22s} {'':5s}"
    for block, dof in zip(NEES_BLOCKS, (6, 3, 3)):
        head += f"  {f'{block} NEES ({dof})':>22s} {'out':>4s}"
        sub += f"  {'median (min–max)':>22s} {'':4s}"
    lines = [head, sub]
    for s in spreads:
        line = (f"{s.excerpt:8s} {len(s.rows):5d}  {s.position_ratio.text('.3f'):>22s} "
                f"{s.position_ratio.count_above(position_target):5d}  {s.attitude_ratio.text('.3f'):>22s} "
                f"{s.attitude_ratio.count_above(attitude_target):5d}")
        for block in NEES_BLOCKS:
            line += f"  {getattr(s, 'nees_' + block).text('.2f'):>22s} {s.inconsistent(block):4d}"
        lines.append(line)
    return "\n".join(lines)
