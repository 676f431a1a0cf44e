"""Accuracy, consistency and speed of the reference ESKF on KITTI sequence 00.

Run ``python benchmarks/eskf_accuracy.py`` (one to two minutes). It prints Markdown:

1. what is real and what is simulated: the KITTI IMU, the ground truth and the ORB-SLAM2 /
   S-PTAM trajectories are real; the lidar poses are simulated (truth plus white noise of
   exactly the filter's R, the most favourable case) and so is the noise on the GNSS fixes;
   and the noise settings used (the shipped ``kitti_lidar`` / ``kitti_gnss`` configurations);
2. for each excerpt (cruise, turns, stop_go), over eleven lidar-noise draws (the shipped
   draw plus :func:`kalman_course.data.simulate_lidar_poses` with seeds 1–10), the median
   and range (min–max) of position APE (RMSE), attitude APE (RMS angle), 1 s RPE
   (translation and rotation) and mean 6-dof pose NEES against the ground truth, for the raw
   lidar poses (no filter), IMU dead reckoning, the reference ESKF (random-walk bias, exact
   reset), the constant-bias model, the biases frozen at zero, and the reset Jacobian off;
   then the reference's ratios to the raw poses (median, range, and how many draws miss
   each acceptance bar);
3. in a table of their own, ORB-SLAM2 and S-PTAM on the same frames (SE(3)-aligned per
   excerpt): real camera-only estimates without map or IMU, a different problem;
4. the bias estimates in units of their own σ, and the Earth's rotation the filter neglects;
5. a sensitivity table over seven noise settings (the lecture asks for at least five) and,
   as the lecture's bonus, the nominal-state EKF next to the ESKF on the shipped draw;
6. the GNSS variant (1 Hz, σ = 1 m): fused position RMSE at the fixes' times (like the raw
   fixes) and at the 10 Hz truth times, and two 30 s GNSS outages in the turns excerpt: the
   filter's error at the end against the IMU alone from the truth, the state the fixes left
   it in, and the error over ten GNSS noise seeds
   (:mod:`kalman_course.chapters.eskf_outage`);
7. all of sequence 00: ATE (SE(3)-aligned cam0 positions) with lidar and with GNSS, with and
   without the interpolated-IMU flags, and apart from them the SLAM tracks;
8. the run time of the whole sequence with lidar, median of 5.

Every filter starts from the true state at the first IMU sample after the first truth pose.
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np

from kalman_course.chapters import eskf_bias, eskf_outage
from kalman_course.chapters.eskf_sources import REAL_INPUTS, gnss_source, lidar_source
from kalman_course.filters import eskf
from kalman_course.data import load_kitti, simulate_gnss, simulate_lidar_poses
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.nominal_ekf import run_nominal_ekf
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.spread import spread
from kalman_course.evaluation.trajectory import ate_rmse
from kalman_course.tooling.bench import SLAM_CAVEAT, aligned_track, eskf_sequence_time, seq00_ate, seq00_slam_ate

EXCERPTS = ("cruise", "turns", "stop_go")
EXTRA_SEEDS = tuple(range(1, 11))
OUTAGES = ((325.0, 355.0), (335.0, 365.0))   # tau, s: 30 s without GNSS inside the turns excerpt
BARS = {"ape_position": 0.4, "ape_attitude_deg": 0.3, "rpe_position": 0.4, "rpe_attitude_deg": 0.4}
METRICS = ("ape_position", "ape_attitude_deg", "rpe_position", "rpe_attitude_deg", "nees_pose")
LATITUDE_DEG = 49.0   # Karlsruhe, where sequence 00 was driven (the data ship no latitude)
REFERENCE = "ESKF (random-walk bias, exact reset)"
RAW = "raw lidar poses (no filter)"


def _lidar_draws(ex):
    yield ex.lidar
    for seed in EXTRA_SEEDS:
        yield simulate_lidar_poses(ex.truth, seed, ex.lidar.sigma_position, ex.lidar.sigma_attitude_deg)


def _gnss_draws(ex):
    yield ex.gnss
    for seed in EXTRA_SEEDS:
        yield simulate_gnss(ex.gnss, seed, ex.gnss.sigma)


def _fixes(gnss, outage=None):
    """The noisy fixes a filter receives, without those inside ``outage`` (tau0, tau1) s."""
    fixes = gnss.observations()
    if outage is None:
        return fixes
    return fixes.select((fixes.t < outage[0]) | (fixes.t > outage[1]))


def excerpt_rows(name: str, cfg) -> tuple[dict, dict, dict]:
    """Metrics per method and draw, the reference's ratios to the raw poses per draw, and each
    variant's largest position difference from the reference (m), over the lidar draws."""
    ex = load_kitti(name)
    k0, s0 = ex.initial_state()
    frozen_cfg, frozen_P0 = eskf_bias.frozen_bias(cfg)
    variants = {
        REFERENCE: (cfg, None),
        "ESKF, constant bias": (cfg.replace(bias_model="constant"), None),
        "ESKF, biases frozen at zero (no bias states)": (frozen_cfg, frozen_P0),
        "ESKF, reset Jacobian off": (cfg.replace(exact_reset=False), None),
    }
    runs: dict[str, list[dict]] = {k: [] for k in [RAW, *variants]}
    ratios: dict[str, list[float]] = {k: [] for k in BARS}
    diffs = {label: 0.0 for label in variants}
    for lidar in _lidar_draws(ex):
        res0 = None
        for label, (c, P0) in variants.items():
            res = eskf.run(ex.imu, s0, c, ex.gravity, lidar=lidar, start=k0, P0=P0)
            runs[label].append(evaluate(res.t, res.position, res.rotation, ex.truth, res.P))
            res0 = res0 or res
            diffs[label] = max(diffs[label], float(np.abs(res.position - res0.position).max()))
        sel = np.isin(lidar.t, res0.t)
        raw = evaluate(lidar.t[sel], lidar.position[sel], lidar.rotation[sel], ex.truth)
        runs[RAW].append(raw)
        for k in BARS:
            ratios[k].append(runs[REFERENCE][-1][k] / raw[k])
    res0_t = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0).t
    dr = eskf.run(ex.imu, s0, cfg, ex.gravity, start=k0, output_times=res0_t)
    runs["IMU dead reckoning (no observations)"] = [evaluate(dr.t, dr.position, dr.rotation, ex.truth)]
    return runs, ratios, diffs


def slam_rows(name: str) -> dict:
    """Metrics of the real SLAM tracks, SE(3)-aligned per excerpt, on the lidar frames."""
    ex = load_kitti(name)
    k0, s0 = ex.initial_state()
    res_t = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0).t
    sel = np.isin(ex.truth.t, res_t)
    rows = {}
    for track in (ex.orb_slam2, ex.sptam):
        p, R = aligned_track(track, ex.truth)
        rows[track.name] = evaluate(ex.truth.t[sel], p[sel], R[sel], ex.truth)
    return rows


def gnss_rows(name: str, cfg) -> tuple[float, float, float]:
    """Mean over the GNSS draws of the fused RMSE at the fixes' times, at the truth times, and of
    the raw fixes' RMSE (at their own times), m."""
    ex = load_kitti(name)
    k0, s0 = ex.initial_state()
    at_fixes, at_truth, raw = [], [], []
    for gnss in _gnss_draws(ex):
        fixes = gnss.observations()
        inside = fixes.select((fixes.t >= ex.truth.t[0]) & (fixes.t <= ex.truth.t[-1]))
        times = np.union1d(ex.truth.t, inside.t)
        res = eskf.run(ex.imu, s0, cfg, ex.gravity, gnss=fixes, start=k0, output_times=times,
                       clip_output_times=True)
        r_truth = res.at(ex.truth.t)
        at_truth.append(ate_rmse(r_truth.position, ex.truth.position[np.isin(ex.truth.t, r_truth.t)], align="none"))
        r_fix = res.at(inside.t)
        used = np.isin(inside.t, r_fix.t)
        truth_at_fix = ex.truth.interpolate(inside.t).position
        at_fixes.append(ate_rmse(r_fix.position, truth_at_fix[used], align="none"))
        raw.append(ate_rmse(inside.position, truth_at_fix, align="none"))
    return float(np.mean(at_fixes)), float(np.mean(at_truth)), float(np.mean(raw))


def sensitivity_settings(cfg):
    """The reference and six other noise settings (the lecture asks for at least five)."""
    d = cfg.process_density
    lid = cfg.lidar_std
    return [
        ("reference (accel 0.03, gyro 1e-3)", cfg),
        ("metadata densities (accel 0.01, gyro 1.75e-4)", cfg.replace(process__accel_noise=0.01, process__gyro_noise=1.75e-4)),
        ("gyro density × 10", cfg.replace(process__gyro_noise=10 * d[1])),
        ("accel density × 10", cfg.replace(process__accel_noise=10 * d[0])),
        ("both densities ÷ 3", cfg.replace(process__accel_noise=d[0] / 3, process__gyro_noise=d[1] / 3)),
        ("lidar R × 4 (σ doubled)", cfg.replace(observation__lidar_position=2 * lid[0], observation__lidar_attitude=2 * lid[3])),
        ("lidar R ÷ 4 (σ halved)", cfg.replace(observation__lidar_position=lid[0] / 2, observation__lidar_attitude=lid[3] / 2)),
    ]


def _cell(values, spec: str) -> str:
    """``median (min–max)`` of a list of numbers, or the one number."""
    if len(values) == 1:
        return "–" if np.isnan(values[0]) else format(values[0], spec)
    if np.isnan(values).any():
        return "–"
    return spread(values).text(spec)


def print_excerpt(name: str, cfg) -> bool:
    runs, ratios, diffs = excerpt_rows(name, cfg)
    ex = load_kitti(name)
    n = 1 + len(EXTRA_SEEDS)
    print(f"## {name}: lidar poses at 10 Hz, {n} simulated draws\n")
    print(f"Inputs: {REAL_INPUTS}; {lidar_source(ex.lidar, cfg)} plus seeds {EXTRA_SEEDS[0]}–{EXTRA_SEEDS[-1]} of the "
          f"same noise. Each cell: median (min–max) over the draws.\n")
    print("| method | position APE (m) | attitude APE (°) | RPE 1 s (m) | RPE 1 s (°) | pose NEES |")
    print("|---|---|---|---|---|---|")
    for label, ms in runs.items():
        cells = [_cell([m[k] for m in ms], ".2f" if k == "nees_pose" else ".3f") for k in METRICS]
        print(f"| {label} | " + " | ".join(cells) + " |")
    nees = np.array([m["nees_pose"] for m in runs[REFERENCE]])
    passed = all(statistics.median(ratios[k]) <= BARS[k] for k in BARS) and 3.0 <= float(np.median(nees)) <= 12.0
    print("\nreference / raw, median (min–max) over the draws [draws missing the bar]: "
          + ", ".join(f"{k} {spread(ratios[k]).text('.3f')} (≤ {BARS[k]}) [{spread(ratios[k]).count_above(BARS[k])}]"
                      for k in BARS)
          + f"; NEES {spread(nees).text('.2f')} (the course's target 3–12, not a χ² test) [{int(np.sum((nees < 3) | (nees > 12)))}]: "
          + ("PASS on the medians" if passed else "FAIL on the medians"))
    print("largest position difference from the reference: "
          + ", ".join(f"{k.split(', ')[-1]} {v * 1e3:.3f} mm" for k, v in list(diffs.items())[1:]) + "\n")
    return passed


def print_bias(cfg) -> None:
    print("## Bias estimates in units of their own σ (shipped lidar draws)\n")
    print("| run | max \\|b̂_a\\|/σ | max \\|b̂_ω\\|/σ | σ(b_ω) at the end (°/h) | b̂_ω,z (°/h) |")
    print("|---|---|---|---|---|")
    to_deg_h = eskf_bias.RAD_PER_S_TO_DEG_PER_H
    for name in (*EXCERPTS, "seq00"):
        ex = load_kitti(name)
        k0, s0 = ex.initial_state()
        r = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0)
        in_a, in_w = eskf_bias.bias_in_sigmas(r)
        print(f"| {name} | {np.abs(in_a).max():.2f} | {np.abs(in_w).max():.2f} | "
              f"{r.std()[-1, 12:15].max() * to_deg_h:.1f} | {r.gyro_bias[-1, 2] * to_deg_h:+.1f} |")
    total, north, up = eskf_bias.earth_rate(LATITUDE_DEG).deg_per_hour()
    print(f"\nThe filter neglects the Earth's rotation: {total:.2f} °/h, at {LATITUDE_DEG}° N {north:.2f} °/h about "
          f"north and {up:.2f} °/h about up, below the gyro-bias σ an excerpt reaches; the up component, fixed along "
          "the body z axis of a level car, is indistinguishable from a z gyro bias to this filter.\n")


def print_outages(cfg_g) -> None:
    ex = load_kitti("turns")
    print(f"Inputs: {REAL_INPUTS}; {gnss_source(ex.gnss, cfg_g)} (and seeds {EXTRA_SEEDS[0]}–{EXTRA_SEEDS[-1]} "
          "for the spread). The filter starts at the true state.\n")
    print("| 30 s outage in turns (tau, s) | fixes before it | filter's horizontal error at the end (m) "
          "| IMU alone from the truth at the filter's start / at the outage start (m) "
          "| filter at the outage start: tilt, heading (°), velocity error (m/s) "
          "| filter's error at the end over the seeds, median (min–max) (m) |")
    print("|---|---|---|---|---|---|")
    studies = []
    for outage in OUTAGES:
        s = eskf_outage.outage_study(ex, cfg_g, outage)
        over = eskf_outage.outage_seed_errors(ex, cfg_g, outage, EXTRA_SEEDS)
        studies.append(s)
        print(f"| {outage[0]:.0f}–{outage[1]:.0f} | {s.t_start - ex.truth.t[0]:.0f} s | {s.filter_error:.1f} | "
              f"{s.imu_from_run_start:.1f} / {s.imu_from_outage_start:.1f} | {s.tilt_deg:.2f}, {s.heading_deg:+.2f}, "
              f"{s.velocity_error:.2f} | {over['filter_error'].text('.1f')} |")
    s = studies[0]
    print(f"\nThe filter starts at the true state, so its errors when the fixes stop were made by its own updates "
          f"with the noisy 1 Hz fixes: at {s.t_start:.1f} s its tilt is {s.tilt_deg:.2f}° off where the IMU alone "
          f"from the truth has drifted {s.imu_tilt_deg:.2f}°, and its gyro-bias estimate is "
          + "(" + ", ".join(f"{v:+.0f}" for v in s.gyro_bias_deg_h) + ") °/h. The IMU alone from the truth at the outage "
          "start, with one part of the filter's state there, ends the outage "
          + ", ".join(f"{k.replace('rotation', 'attitude').replace('_', ' ')} {v:.1f} m" for k, v in s.swapped.items())
          + " off. 1 Hz position fixes observe attitude and gyro bias weakly; starting from the truth hides the "
          "initialisation problem. The filter's σ grows with the error (it stays consistent).\n")


def main() -> int:
    t_start = time.perf_counter()
    cfg = load_config("kitti_lidar")
    cfg_g = load_config("kitti_gnss")
    print("# ESKF on KITTI sequence 00: accuracy, consistency, speed\n")
    print("**What is real and what is simulated.** Real: the KITTI IMU (100 Hz), the ground truth and the ORB-SLAM2 / "
          "S-PTAM trajectories. Simulated: the lidar map-matching poses (the truth plus white noise, σ 0.2 m / 0.3°, "
          "exactly the R the filter assumes: the most favourable case) and the noise on the GNSS fixes (the recorded "
          "INS positions plus white noise, σ 1 m). Every filter starts from the true state.\n")
    print(cfg.describe())
    print(f"\nGNSS runs use `{cfg_g.name}` (same numbers; GNSS σ = {cfg_g.gnss_std:.1f} m). "
          f"Seeds: the shipped draw plus {EXTRA_SEEDS[0]}–{EXTRA_SEEDS[-1]}.\n")

    ok = True
    for name in EXCERPTS:
        ok &= print_excerpt(name, cfg)

    print(f"## Real visual SLAM on the same frames: a different problem\n")
    print(f"ORB-SLAM2 and S-PTAM are {SLAM_CAVEAT}. Listed apart; not comparable with the tables above.\n")
    print("| excerpt | estimate | position APE (m) | attitude APE (°) | RPE 1 s (m) | RPE 1 s (°) |")
    print("|---|---|---|---|---|---|")
    for name in EXCERPTS:
        for label, m in slam_rows(name).items():
            print(f"| {name} | {label} (SE(3)-aligned) | {m['ape_position']:.3f} | {m['ape_attitude_deg']:.3f} | "
                  f"{m['rpe_position']:.3f} | {m['rpe_attitude_deg']:.3f} |")
    print()

    print_bias(cfg)

    print("## Sensitivity to the noise settings (shipped simulated lidar draw, mean over the three excerpts)\n")
    print("| setting | position APE (m) | attitude APE (°) | RPE 1 s (m) | pose NEES |")
    print("|---|---|---|---|---|")
    for label, c in sensitivity_settings(cfg):
        rows = []
        for name in EXCERPTS:
            ex = load_kitti(name)
            k0, s0 = ex.initial_state()
            r = eskf.run(ex.imu, s0, c, ex.gravity, lidar=ex.lidar, start=k0)
            rows.append(evaluate(r.t, r.position, r.rotation, ex.truth, r.P))
        m = {k: float(np.mean([x[k] for x in rows])) for k in METRICS}
        print(f"| {label} | {m['ape_position']:.3f} | {m['ape_attitude_deg']:.3f} | {m['rpe_position']:.3f} | "
              f"{m['nees_pose']:.2f} |")
    print()

    print("## Bonus: nominal-state EKF (state p, v, q, b_a, b_ω) vs the ESKF, shipped simulated lidar draw\n")
    print("| excerpt | ESKF position APE (m) | nominal EKF position APE (m) | ESKF NEES | nominal EKF NEES | max position difference (mm) |")
    print("|---|---|---|---|---|---|")
    for name in EXCERPTS:
        ex = load_kitti(name)
        k0, s0 = ex.initial_state()
        e = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0)
        r = run_nominal_ekf(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0)
        me = evaluate(e.t, e.position, e.rotation, ex.truth, e.P)
        mr = evaluate(r.t, r.position, r.rotation, ex.truth, r.P_pose)
        print(f"| {name} | {me['ape_position']:.4f} | {mr['ape_position']:.4f} | {me['nees_pose']:.2f} | "
              f"{mr['nees_pose']:.2f} | {np.abs(r.position - e.position).max() * 1e3:.3f} |")
    print()

    print(f"## GNSS variant (1 Hz, real INS positions + simulated noise σ = 1 m), mean over {1 + len(EXTRA_SEEDS)} draws\n")
    print("| excerpt | fused RMSE at the fixes' times (m) | raw GNSS RMSE (m) | ratio (≤ 0.7) | fused RMSE at the 10 Hz truth times (m) |")
    print("|---|---|---|---|---|")
    for name in EXCERPTS:
        at_fixes, at_truth, raw = gnss_rows(name, cfg_g)
        ok &= at_fixes <= 0.7 * raw
        print(f"| {name} | {at_fixes:.3f} | {raw:.3f} | {at_fixes / raw:.3f} | {at_truth:.3f} |")
    print()
    print_outages(cfg_g)

    print("## Whole sequence 00 (ATE, SE(3)-aligned cam0 positions)\n")
    print("| estimate | ATE (m) |")
    print("|---|---|")
    rows = seq00_ate(cfg, cfg_g)
    for label, value in rows:
        print(f"| {label} | {value:.3f} |")
    ok &= rows[0][1] <= 0.2 and rows[2][1] <= 1.5
    print(f"\nReal visual SLAM over the whole sequence ({SLAM_CAVEAT}):\n")
    print("| estimate | ATE (m) |")
    print("|---|---|")
    for label, value in seq00_slam_ate():
        print(f"| {label} | {value:.3f} |")

    wall, cpu = eskf_sequence_time(cfg)
    med, med_cpu = statistics.median(wall), statistics.median(cpu)
    ok &= med <= 1.5
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\nSpeed: whole sequence 00 with lidar ({len(load_kitti('seq00').imu)} IMU samples, "
          f"10 Hz updates): median {med:.3f} s wall-clock of 5 runs (≤ 1.5 s): "
          + ", ".join(f"{t:.3f}" for t in wall)
          + f"; median CPU time {med_cpu:.3f} s; 1-minute load average {load:.2f} on {os.cpu_count()} cores"
          + (" (the machine is busy: wall-clock times are inflated)" if load > 1.0 else ""))
    print(f"\nAll acceptance bars: {'PASS' if ok else 'FAIL'}  ({time.perf_counter() - t_start:.1f} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
