"""Accuracy, consistency and speed of the reference ESKF on KITTI sequence 00.

Run ``python benchmarks/eskf_accuracy.py`` (about half a minute). It prints Markdown:

1. the noise settings used (the shipped ``kitti_lidar`` / ``kitti_gnss`` configurations);
2. for each excerpt (cruise, turns, stop_go), means over five lidar-noise seeds (the
   shipped draw plus :func:`kalman_course.data.simulate_lidar_poses` with four more seeds):
   position APE (RMSE), attitude APE (RMS angle), 1 s RPE (translation and rotation) and
   mean 6-dof pose NEES against the ground truth, for the raw lidar poses (no filter),
   IMU dead reckoning, the reference ESKF (random-walk bias, exact reset), the constant-bias
   model, the reset Jacobian off, and ORB-SLAM2 / S-PTAM on the same frames (SE(3)-aligned
   per excerpt); then the ratios to the raw lidar poses against the acceptance bars;
3. the GNSS variant (1 Hz, σ = 1 m): fused position RMSE (at the 10 Hz truth times) vs the
   raw fixes, and 30 s GNSS outages in the turns excerpt (peak error over the seeds);
4. all of sequence 00: ATE (SE(3)-aligned cam0 positions, as for the SLAM anchors) with
   lidar and with GNSS, with and without the interpolated-IMU flags;
5. the run time of the whole sequence with lidar, median of 5;

and a sensitivity table over seven noise settings (the lecture asks for at least five) and,
as the lecture's bonus, the nominal-state EKF next to the ESKF on the shipped draw.

Every filter starts from the true state at the first IMU sample after the first truth pose.
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np

from kalman_course.filters import eskf
from kalman_course.data import load_kitti, simulate_gnss, simulate_lidar_poses
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.nominal_ekf import run_nominal_ekf
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.trajectory import ate_rmse
from kalman_course.tooling.bench import aligned_track, eskf_sequence_time, seq00_ate

EXCERPTS = ("cruise", "turns", "stop_go")
EXTRA_SEEDS = (101, 202, 303, 404)
OUTAGES = ((325.0, 355.0), (335.0, 365.0))   # tau, s: 30 s without GNSS inside the turns excerpt
BARS = {"ape_position": 0.4, "ape_attitude_deg": 0.3, "rpe_position": 0.4, "rpe_attitude_deg": 0.4}
METRICS = ("ape_position", "ape_attitude_deg", "rpe_position", "rpe_attitude_deg", "nees_pose")


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


def excerpt_rows(name: str, cfg) -> tuple[dict, dict]:
    """Mean metrics per method over the seeds, the reference's mean ratios to the raw poses, and
    each variant's largest position difference from the reference (m)."""
    ex = load_kitti(name)
    k0, s0 = ex.initial_state()
    variants = {
        "ESKF (random-walk bias, exact reset)": cfg,
        "ESKF, constant bias": cfg.replace(bias_model="constant"),
        "ESKF, reset Jacobian off": cfg.replace(exact_reset=False),
    }
    sums: dict[str, list[dict]] = {k: [] for k in ["raw lidar poses (no filter)", *variants]}
    ratios = []
    diffs = {label: 0.0 for label in variants}
    for lidar in _lidar_draws(ex):
        res0 = None
        for label, c in variants.items():
            res = eskf.run(ex.imu, s0, c, ex.gravity, lidar=lidar, start=k0)
            m = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
            sums[label].append(m)
            res0 = res0 or res
            diffs[label] = max(diffs[label], float(np.abs(res.position - res0.position).max()))
        sel = np.isin(lidar.t, res0.t)
        raw = evaluate(lidar.t[sel], lidar.position[sel], lidar.rotation[sel], ex.truth)
        sums["raw lidar poses (no filter)"].append(raw)
        ref = sums["ESKF (random-walk bias, exact reset)"][-1]
        ratios.append({k: ref[k] / raw[k] for k in BARS})
    # deterministic methods on the same frames
    res0_t = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0).t
    dr = eskf.run(ex.imu, s0, cfg, ex.gravity, start=k0, output_times=res0_t)
    sums["IMU dead reckoning"] = [evaluate(dr.t, dr.position, dr.rotation, ex.truth)]
    sel = np.isin(ex.truth.t, res0_t)
    for track in (ex.orb_slam2, ex.sptam):
        p, R = aligned_track(track, ex.truth)
        sums[f"{track.name} (SE(3)-aligned)"] = [evaluate(ex.truth.t[sel], p[sel], R[sel], ex.truth)]
    means = {label: {k: float(np.mean([m[k] for m in ms])) for k in METRICS} for label, ms in sums.items()}
    return means, {k: float(np.mean([r[k] for r in ratios])) for k in BARS}, diffs


def gnss_rows(name: str, cfg, outage=None) -> tuple[float, float, float, float]:
    """Mean fused RMSE at the truth times, mean raw-fix RMSE, and in the outage the peak error
    over the seeds with the filter's own position σ (sqrt of trace of the δp block) there."""
    ex = load_kitti(name)
    k0, s0 = ex.initial_state()
    fused, raw, peak, sigma = [], [], 0.0, 0.0
    for gnss in _gnss_draws(ex):
        fixes = _fixes(gnss, outage)
        res = eskf.run(ex.imu, s0, cfg, ex.gravity, gnss=fixes, start=k0, output_times=ex.truth.t).at(ex.truth.t)
        truth_position = ex.truth.position[np.isin(ex.truth.t, res.t)]
        err = np.linalg.norm(res.position - truth_position, axis=1)
        fused.append(ate_rmse(res.position, truth_position, align="none"))
        all_fixes = gnss.observations()
        inside = all_fixes.select((all_fixes.t >= ex.truth.t[0]) & (all_fixes.t <= ex.truth.t[-1]))
        raw.append(ate_rmse(inside.position, ex.truth.interpolate(inside.t).position, align="none"))
        if outage is not None:
            w = np.nonzero((res.t >= outage[0]) & (res.t <= outage[1] + 1.0))[0]
            i = w[np.argmax(err[w])]
            if err[i] > peak:
                peak, sigma = float(err[i]), float(np.sqrt(np.trace(res.P[i][:3, :3])))
    return float(np.mean(fused)), float(np.mean(raw)), peak, sigma


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


def main() -> int:
    t_start = time.perf_counter()
    cfg = load_config("kitti_lidar")
    cfg_g = load_config("kitti_gnss")
    print("# ESKF on KITTI sequence 00: accuracy, consistency, speed\n")
    print(cfg.describe())
    print(f"\nGNSS runs use `{cfg_g.name}` (same numbers; GNSS σ = {cfg_g.gnss_std:.1f} m). "
          f"Seeds: the shipped draw plus {', '.join(map(str, EXTRA_SEEDS))}.\n")

    ok = True
    for name in EXCERPTS:
        means, ratios, diffs = excerpt_rows(name, cfg)
        print(f"## {name}: lidar poses at 10 Hz (σ 0.2 m, 0.3°), mean over {1 + len(EXTRA_SEEDS)} seeds\n")
        print("| method | position APE (m) | attitude APE (°) | RPE 1 s (m) | RPE 1 s (°) | pose NEES |")
        print("|---|---|---|---|---|---|")
        for label, m in means.items():
            nees = "–" if np.isnan(m["nees_pose"]) else f"{m['nees_pose']:.2f}"
            print(f"| {label} | {m['ape_position']:.3f} | {m['ape_attitude_deg']:.3f} | "
                  f"{m['rpe_position']:.3f} | {m['rpe_attitude_deg']:.3f} | {nees} |")
        nees = means["ESKF (random-walk bias, exact reset)"]["nees_pose"]
        passed = all(ratios[k] <= BARS[k] for k in BARS) and 3.0 <= nees <= 12.0
        ok &= passed
        print("\nreference / raw: " + ", ".join(f"{k} {ratios[k]:.3f} (≤ {BARS[k]})" for k in BARS)
              + f"; NEES {nees:.2f} (3–12): {'PASS' if passed else 'FAIL'}")
        print("largest position difference from the reference: "
              + ", ".join(f"{k.split(', ')[-1]} {v * 1e3:.3f} mm" for k, v in list(diffs.items())[1:]) + "\n")

    print("## Sensitivity to the noise settings (shipped lidar draw, mean over the three excerpts)\n")
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

    print("## Bonus: nominal-state EKF (state p, v, q, b_a, b_ω) vs the ESKF, shipped lidar draw\n")
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

    print("## GNSS variant (1 Hz, σ = 1 m), mean over 5 seeds\n")
    print("| excerpt | fused position RMSE (m) | raw GNSS RMSE (m) | ratio (≤ 0.7) |")
    print("|---|---|---|---|")
    for name in EXCERPTS:
        fused, raw, _, _ = gnss_rows(name, cfg_g)
        ok &= fused <= 0.7 * raw
        print(f"| {name} | {fused:.3f} | {raw:.3f} | {fused / raw:.3f} |")
    print()
    print("| 30 s outage in turns (tau, s) | GNSS fixes before it | peak position error over the seeds (m) "
          "| filter's own σ there (m) | RMSE over the excerpt (m) |")
    print("|---|---|---|---|---|")
    for outage in OUTAGES:
        fused, raw, peak, sigma = gnss_rows("turns", cfg_g, outage=outage)
        print(f"| {outage[0]:.0f}–{outage[1]:.0f} | {outage[0] - 310.0:.0f} s | {peak:.2f} | {sigma:.2f} | {fused:.3f} |")
    print("\nWithout fixes the filter dead-reckons from an attitude that GNSS alone observes only "
          "slowly (through how position errors grow): after 15 s of fixes about 1° of heading and "
          "0.4° of tilt error remain, and 0.4° of tilt alone is 0.07 m/s² of false acceleration. "
          "Ten seconds more of fixes before the outage cut the peak by more than half. The filter's σ "
          "grows with the error (it stays consistent).\n")

    print("## Whole sequence 00 (ATE, SE(3)-aligned cam0 positions)\n")
    print("| estimate | ATE (m) |")
    print("|---|---|")
    rows = seq00_ate(cfg, cfg_g)
    for label, value in rows:
        print(f"| {label} | {value:.3f} |")
    ok &= rows[0][1] <= 0.2 and rows[2][1] <= 1.5

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
