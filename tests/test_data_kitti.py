"""The shipped KITTI excerpts: their physics, their simulated noise and their loader."""

import json
import shutil
import zipfile

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.data import (EXCERPTS, SCHEMA_VERSION, KittiExcerpt, kitti_dir, load_excerpt_file,
                                load_kitti, read_manifest, simulate_gnss, simulate_lidar_poses)
from kalman_course.evaluation.trajectory import ate_rmse

EXCERPT_NAMES = ("cruise", "turns", "stop_go")
DOC_INTERPOLATED_SPANS = [(35.85, 37.54), (198.18, 199.83), (202.53, 204.17), (219.12, 220.81),
                          (235.71, 237.40), (278.41, 280.06), (305.05, 306.80), (307.23, 308.92)]


@pytest.fixture(scope="module")
def seq():
    return load_kitti("seq00")


def rms(e):
    return float(np.sqrt(np.mean(np.sum(np.atleast_2d(e) ** 2, axis=1))))


# ---------------------------------------------------------------------------------------
# Files and records
# ---------------------------------------------------------------------------------------

def test_every_excerpt_loads_with_consistent_shapes():
    for name in EXCERPTS:
        ex = load_kitti(name)
        assert isinstance(ex, KittiExcerpt) and ex.name == name
        N, M, K = len(ex.imu), len(ex.gnss), len(ex.truth)
        assert ex.imu.specific_force.shape == ex.imu.angular_rate.shape == (N, 3)
        assert ex.imu.interpolated.shape == (N,) and ex.imu.interpolated.dtype == bool
        assert ex.gnss.position_true.shape == ex.gnss.position_noisy.shape == (M, 3)
        assert ex.truth.rotation.shape == (K, 3, 3) and ex.truth.quaternion.shape == (K, 4)
        for track in (ex.lidar, ex.orb_slam2, ex.sptam):
            assert track.position.shape == (K, 3) and track.rotation.shape == (K, 3, 3)
            np.testing.assert_array_equal(track.t, ex.truth.t)
        for t in (ex.imu.t, ex.gnss.t, ex.truth.t):
            assert ex.tau_range[0] <= t[0] and t[-1] <= ex.tau_range[1]
        np.testing.assert_allclose(ex.gravity, [0.0, 0.0, -9.8092])
        assert ex.lidar.simulated and ex.gnss.simulated_noise
        assert ex.lidar.sigma_position == 0.2 and ex.lidar.sigma_attitude_deg == 0.3 and ex.gnss.sigma == 1.0
        assert so3.is_rotation(ex.truth.rotation, tol=1e-12)
        assert ex.imu.specific_force.dtype == np.float64


def test_excerpts_are_the_documented_slices_of_sequence_00(seq):
    expected = {"cruise": (421.5, 452.0), "turns": (310.0, 370.0), "stop_go": (40.0, 100.0)}
    for name, tau in expected.items():
        ex = load_kitti(name)
        assert ex.tau_range == tau
        keep = (seq.imu.t >= tau[0]) & (seq.imu.t <= tau[1])
        np.testing.assert_array_equal(ex.imu.t, seq.imu.t[keep])
        np.testing.assert_array_equal(ex.imu.angular_rate, seq.imu.angular_rate[keep])
        keep = (seq.truth.t >= tau[0]) & (seq.truth.t <= tau[1])
        np.testing.assert_array_equal(ex.truth.position, seq.truth.position[keep])
        assert not ex.imu.interpolated.any()


def test_records_are_read_only_and_cached():
    ex = load_kitti("cruise")
    assert load_kitti("cruise") is ex
    with pytest.raises(ValueError):
        ex.imu.t[0] = 0.0
    with pytest.raises(AttributeError):
        ex.name = "x"


def test_manifest_lists_every_file_and_the_data_is_small():
    manifest = read_manifest()
    assert manifest["schema_version"] == SCHEMA_VERSION
    assert set(manifest["files"]) == {f"{n}.npz" for n in EXCERPTS}
    total = 0
    for fname, entry in manifest["files"].items():
        path = kitti_dir() / fname
        assert path.stat().st_size == entry["size"]
        total += entry["size"]
    assert total < 3.4e6
    assert (kitti_dir() / "ATTRIBUTION.md").is_file()


def test_provenance_names_package_version_and_file_of_every_stream(seq):
    prov = seq.provenance
    assert "CC BY-NC-SA 3.0" in prov["licence"] and "Geiger" in prov["licence"]
    for stream in ("imu", "gnss", "truth", "lidar", "orb_slam2", "sptam"):
        for src in prov[stream]["sources"]:
            assert src["package"] in ("gtsam", "evo")
            assert src["version"] in ("4.3.0", "1.38.1")
            assert src["file"] and len(src["sha256"]) == 64
    assert "SIMULATED" in prov["lidar"]["transform"]


# ---------------------------------------------------------------------------------------
# Physics: the streams agree with each other
# ---------------------------------------------------------------------------------------

def test_gnss_agrees_with_ground_truth_imu_positions_within_1_cm(seq):
    inside = (seq.gnss.t >= seq.truth.t[0]) & (seq.gnss.t <= seq.truth.t[-1])
    err = seq.truth.interpolate(seq.gnss.t[inside]).position - seq.gnss.position_true[inside]
    assert rms(err) <= 0.01
    for name in EXCERPT_NAMES:
        ex = load_kitti(name)
        assert rms(ex.truth.interpolate(ex.gnss.t).position - ex.gnss.position_true) <= 0.01


def test_gnss_clock_offset_is_at_its_minimum(seq):
    inside = (seq.gnss.t >= seq.truth.t[0] + 0.1) & (seq.gnss.t <= seq.truth.t[-1] - 0.1)
    t = seq.gnss.t[inside]
    errs = {dt: rms(seq.truth.interpolate(t + dt).position - seq.gnss.position_true[inside])
            for dt in (-0.02, -0.01, 0.0, 0.01, 0.02)}
    assert min(errs, key=errs.get) == 0.0
    assert errs[0.01] > 5 * errs[0.0]


def _gyro_vs_truth(seq, offset):
    """Mean gyro over each truth interval (IMU clock shifted by offset) and the truth's rate."""
    t_imu = seq.imu.t + offset
    w = seq.imu.angular_rate
    cum = np.vstack([np.zeros(3), np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t_imu)[:, None], axis=0)])
    tg = seq.truth.t
    C = np.stack([np.interp(tg, t_imu, cum[:, i]) for i in range(3)], axis=1)
    mean_gyro = np.diff(C, axis=0) / np.diff(tg)[:, None]
    R = seq.truth.rotation
    rate = so3.log(np.swapaxes(R[:-1], 1, 2) @ R[1:]) / np.diff(tg)[:, None]
    # keep intervals well inside the IMU coverage and away from interpolated samples
    bad_t = seq.imu.t[seq.imu.interpolated]
    lo = np.searchsorted(bad_t, tg[:-1] - 0.3)
    hi = np.searchsorted(bad_t, tg[1:] + 0.3)
    near_bad = hi > lo
    ok = (tg[:-1] > seq.imu.t[0] + 0.3) & (tg[1:] < seq.imu.t[-1] - 0.3) & ~near_bad
    return mean_gyro[ok], rate[ok]


def test_gyro_agrees_with_ground_truth_rate_at_the_minimising_time_offset(seq):
    offsets = np.arange(-0.02, 0.0201, 0.002)
    errs = [rms(np.subtract(*_gyro_vs_truth(seq, off))) for off in offsets]
    best = offsets[int(np.argmin(errs))]
    assert abs(best) <= 0.005
    assert min(errs) <= 0.01
    assert errs[0] > min(errs) and errs[-1] > min(errs)   # a real minimum inside the scan


def test_gyro_and_ground_truth_frames_agree_kabsch(seq):
    gyro, rate = _gyro_vs_truth(seq, 0.0)
    # rotation A minimising |gyro − A rate|: a check of the camera–IMU extrinsic
    U, _, Vt = np.linalg.svd(gyro.T @ rate)
    A = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    assert np.degrees(so3.angle(A)) < 0.2


def test_interpolated_samples_are_flagged_and_lie_on_straight_lines(seq):
    flags = seq.imu.interpolated
    assert flags.sum() == 1257
    idx = np.flatnonzero(flags)
    starts = idx[np.r_[True, np.diff(idx) > 1]]
    ends = idx[np.r_[np.diff(idx) > 1, True]]
    assert len(starts) == len(DOC_INTERPOLATED_SPANS)
    for s, e, (a, b) in zip(starts, ends, DOC_INTERPOLATED_SPANS):
        assert a <= seq.imu.t[s] <= a + 0.1 and b - 0.1 <= seq.imu.t[e] <= b
    t = seq.imu.t
    x = np.hstack([seq.imu.specific_force, seq.imu.angular_rate])
    alpha = (t[idx] - t[idx - 1]) / (t[idx + 1] - t[idx - 1])
    line = x[idx - 1] + (x[idx + 1] - x[idx - 1]) * alpha[:, None]
    assert np.abs(x[idx] - line).max() < 1e-5          # float32 storage rounds at ~1e-6


def test_imu_timing_matches_the_documented_facts(seq):
    dt = np.diff(seq.imu.t)
    assert abs(dt.mean() - 0.0099991) < 2e-6
    assert 0.0025 < dt.min() < 0.0027 and 0.0199 < dt.max() < 0.0201
    assert abs(seq.imu.t[np.argmax(dt)] - 52.18) < 0.01


def test_specific_force_and_gravity_are_consistent(seq):
    """Time average of R f + g equals Δv/T on each excerpt, and |g| ≈ 9.809 overall."""
    for name in EXCERPT_NAMES:
        ex = load_kitti(name)
        t0, t1 = ex.truth.t[1], ex.truth.t[-2]
        sel = (ex.imu.t >= t0) & (ex.imu.t <= t1)
        t = ex.imu.t[sel]
        R = ex.truth.interpolate(t).rotation
        a = np.einsum("kij,kj->ki", R, ex.imu.specific_force[sel]) + ex.gravity
        mean_a = np.sum(0.5 * (a[1:] + a[:-1]) * np.diff(t)[:, None], axis=0) / (t[-1] - t[0])
        v = ex.truth.interpolate(np.array([t[0], t[-1]])).velocity
        assert np.linalg.norm(mean_a - (v[1] - v[0]) / (t[-1] - t[0])) < 0.01
    # gravity estimated over the pieces of sequence 00 free of interpolated samples
    edges = [seq.imu.t[0] + 1.0]
    idx = np.flatnonzero(seq.imu.interpolated)
    cuts = np.flatnonzero(np.diff(idx) > 1)
    for s, e in zip(idx[np.r_[0, cuts + 1]], idx[np.r_[cuts, -1]]):
        edges += [seq.imu.t[s] - 0.5, seq.imu.t[e] + 0.5]
    edges.append(seq.truth.t[-1] - 1.0)
    num, total = np.zeros(3), 0.0
    for a_, b_ in zip(edges[::2], edges[1::2]):
        if b_ - a_ < 1.0:
            continue
        sel = (seq.imu.t >= a_) & (seq.imu.t <= b_)
        t = seq.imu.t[sel]
        fn = np.einsum("kij,kj->ki", seq.truth.interpolate(t).rotation, seq.imu.specific_force[sel])
        v = seq.truth.interpolate(np.array([t[0], t[-1]])).velocity
        num += v[1] - v[0] - np.sum(0.5 * (fn[1:] + fn[:-1]) * np.diff(t)[:, None], axis=0)
        total += t[-1] - t[0]
    g = num / total
    assert abs(np.linalg.norm(g) - 9.809) < 0.003
    assert np.degrees(np.arctan2(np.hypot(g[0], g[1]), -g[2])) < 0.05


def test_the_short_stop_is_a_stop():
    ex = load_kitti("stop_go")
    speed = np.linalg.norm(ex.truth.velocity, axis=1)
    still = ex.truth.t[speed < 0.05]
    assert len(still) >= 3 and 56.3 <= still.min() and still.max() <= 57.5
    sel = (ex.imu.t >= still.min()) & (ex.imu.t <= still.max())
    assert abs(np.linalg.norm(ex.imu.specific_force[sel], axis=1).mean() - 9.8092) < 0.02
    assert np.abs(ex.imu.angular_rate[sel].mean(axis=0)).max() < 0.01


def test_slam_estimates_reproduce_the_published_ate(seq):
    f = seq.frames
    cam_truth = f.cam0_position(seq.truth.position, seq.truth.rotation)
    for track, expected in ((seq.orb_slam2, 1.30), (seq.sptam, 3.74)):
        ate = ate_rmse(f.cam0_position(track.position, track.rotation), cam_truth) / f.scale
        assert abs(ate - expected) < 0.01, (track.name, ate)


def test_truth_interpolation(seq):
    tr = load_kitti("turns").truth
    at = tr.interpolate(tr.t[:5])
    np.testing.assert_allclose(at.position, tr.position[:5], atol=1e-12)
    np.testing.assert_allclose(at.rotation, tr.rotation[:5], atol=1e-12)
    mid = tr.state_at(0.5 * (tr.t[10] + tr.t[11]))
    assert np.linalg.norm(mid.position - 0.5 * (tr.position[10] + tr.position[11])) < 0.05
    with pytest.raises(ValueError, match="t must lie inside the truth's time span"):
        tr.interpolate([tr.t[0] - 1.0])


def test_initial_state_is_the_truth_at_the_first_usable_imu_sample():
    ex = load_kitti("cruise")
    k0, state = ex.initial_state()
    assert ex.imu.t[k0] >= ex.truth.t[0] and (k0 == 0 or ex.imu.t[k0 - 1] < ex.truth.t[0])
    assert np.linalg.norm(state.position - ex.truth.position[0]) < 0.2


# ---------------------------------------------------------------------------------------
# Simulated observation noise
# ---------------------------------------------------------------------------------------

def test_simulated_lidar_noise_has_the_stated_standard_deviations(seq):
    dp = seq.lidar.position - seq.truth.position
    dtheta = so3.log(np.swapaxes(seq.truth.rotation, 1, 2) @ seq.lidar.rotation)   # R_obs = R_gt Exp(n)
    K = len(dp)
    tol = 4.0 / np.sqrt(2 * K)               # 4 standard errors of a sample standard deviation
    np.testing.assert_allclose(dp.std(axis=0), 0.2, rtol=tol)
    np.testing.assert_allclose(np.degrees(dtheta.std(axis=0)), 0.3, rtol=tol)
    assert np.abs(dp.mean(axis=0)).max() < 4 * 0.2 / np.sqrt(K)
    assert np.abs(np.corrcoef(np.hstack([dp, dtheta]).T) - np.eye(6)).max() < 4 / np.sqrt(K)


def test_simulated_gnss_noise_has_the_stated_standard_deviation(seq):
    d = seq.gnss.position_noisy - seq.gnss.position_true
    np.testing.assert_allclose(d.std(axis=0), 1.0, rtol=4.0 / np.sqrt(2 * len(d)))


def test_shipped_noise_is_reproduced_by_the_exposed_generators():
    for name in EXCERPTS:
        ex = load_kitti(name)
        lidar = simulate_lidar_poses(ex.truth, ex.lidar.seed)
        np.testing.assert_allclose(lidar.position, ex.lidar.position, atol=1e-12)
        np.testing.assert_allclose(lidar.rotation, ex.lidar.rotation, atol=1e-12)
        gnss = simulate_gnss(ex.gnss, ex.gnss.seed)
        np.testing.assert_allclose(gnss.position_noisy, ex.gnss.position_noisy, atol=1e-12)
    other = simulate_lidar_poses(ex.truth, ex.lidar.seed + 1)
    assert np.abs(other.position - ex.lidar.position).max() > 0.1


# ---------------------------------------------------------------------------------------
# What a filter receives
# ---------------------------------------------------------------------------------------

def test_gnss_observations_are_the_noisy_fixes():
    for name in EXCERPTS:
        gnss = load_kitti(name).gnss
        obs = gnss.observations()
        assert type(obs) is PositionObservations
        np.testing.assert_array_equal(obs.t, gnss.t)
        np.testing.assert_array_equal(obs.position, gnss.position_noisy)
        # the noise is really there: the fixes are not the recorded solution
        assert np.abs(obs.position - gnss.position_true).max() > 1.0


def test_gnss_data_has_no_position_a_filter_could_read_by_mistake():
    gnss = load_kitti("cruise").gnss
    assert not isinstance(gnss, PositionObservations)
    with pytest.raises(AttributeError):
        gnss.position


def test_lidar_is_a_validated_pose_record():
    lidar = load_kitti("cruise").lidar
    assert isinstance(lidar, PoseObservations)
    assert len(lidar) == len(lidar.t) and lidar.quaternion.shape == (len(lidar), 4)
    np.testing.assert_allclose(so3.quat_to_matrix(lidar.quaternion), lidar.rotation, atol=1e-15)
    for arr in (lidar.t, lidar.position, lidar.rotation, lidar.quaternion):
        assert not arr.flags.writeable
    sub = lidar.select(slice(0, 10))
    assert type(sub) is type(lidar) and sub.seed == lidar.seed
    np.testing.assert_array_equal(sub.quaternion, lidar.quaternion[:10])


def test_lidar_record_rejects_a_nan_pose():
    truth = load_kitti("cruise").truth
    position = truth.position.copy()
    position[17, 2] = np.nan
    bad = type("Poses", (), {"t": truth.t, "position": position, "rotation": truth.rotation})
    with pytest.raises(ValueError, match=r"^truth\.position\[17\] is NaN$"):
        simulate_lidar_poses(bad, seed=0)


def test_simulate_gnss_takes_the_noise_free_position_of_any_record():
    gnss = load_kitti("cruise").gnss
    plain = type("Fixes", (), {"t": gnss.t, "position": gnss.position_true})
    np.testing.assert_array_equal(simulate_gnss(plain, 3).position_noisy,
                                  simulate_gnss(gnss, 3).position_noisy)
    with pytest.raises(ValueError, match="gnss must have t .* and position"):
        simulate_gnss(type("NoPosition", (), {"t": gnss.t}), 3)


def test_lidar_generator_applies_noise_on_the_right():
    truth = load_kitti("cruise").truth
    sim = simulate_lidar_poses(truth, seed=5, sigma_position=0.0, sigma_attitude_deg=10.0)
    rng = np.random.default_rng(5)
    rng.standard_normal((len(truth), 3))                        # position draw comes first
    n = np.deg2rad(10.0) * rng.standard_normal((len(truth), 3))
    np.testing.assert_allclose(sim.rotation, truth.rotation @ so3.exp(n), atol=1e-12)
    np.testing.assert_array_equal(sim.position, truth.position)


@pytest.mark.parametrize("kwargs,msg", [
    (dict(seed=-1), "seed must be a non-negative integer"),
    (dict(seed=1.5), "seed must be a non-negative integer"),
    (dict(seed=1, sigma_position=-0.1), "sigma_position must be a finite non-negative number"),
    (dict(seed=1, sigma_attitude_deg="a"), "sigma_attitude_deg must be a finite non-negative number"),
])
def test_generators_reject_bad_arguments(kwargs, msg):
    with pytest.raises(ValueError, match=msg):
        simulate_lidar_poses(load_kitti("cruise").truth, **kwargs)


# ---------------------------------------------------------------------------------------
# Loader failures
# ---------------------------------------------------------------------------------------

@pytest.fixture
def copy(tmp_path):
    """A private copy of cruise.npz and the manifest."""
    src = kitti_dir()
    shutil.copy(src / "cruise.npz", tmp_path / "cruise.npz")
    shutil.copy(src / "MANIFEST.json", tmp_path / "MANIFEST.json")
    return tmp_path


def _rewrite(path, change):
    """Rewrite the npz at ``path`` with its arrays passed through ``change(dict)``."""
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    change(arrays)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for key, arr in arrays.items():
            with zf.open(key + ".npy", "w") as fh:
                np.lib.format.write_array(fh, arr)


def test_unknown_name_lists_the_valid_ones():
    with pytest.raises(ValueError, match="unknown KITTI excerpt 'highway'; valid names: cruise, turns, stop_go, seq00"):
        load_kitti("highway")


def test_missing_file(copy):
    with pytest.raises(FileNotFoundError, match=r"nothere\.npz: KITTI excerpt file not found"):
        load_excerpt_file(copy / "nothere.npz")


def test_truncated_file(copy):
    path = copy / "cruise.npz"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=r"cruise\.npz: file is truncated or modified \(\d+ bytes, the manifest says \d+\)"):
        load_excerpt_file(path, manifest=copy / "MANIFEST.json")
    with pytest.raises(ValueError, match=r"cruise\.npz: file is truncated or corrupt"):
        load_excerpt_file(path)


def test_corrupt_file_fails_its_checksum(copy):
    path = copy / "cruise.npz"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"cruise\.npz: checksum mismatch \(sha256 [0-9a-f]{64}, the manifest says"):
        load_excerpt_file(path, manifest=copy / "MANIFEST.json")
    with pytest.raises(ValueError, match=r"cruise\.npz: file is truncated or corrupt"):
        load_excerpt_file(path)


def test_file_not_in_manifest(copy):
    shutil.copy(copy / "cruise.npz", copy / "mine.npz")
    with pytest.raises(ValueError, match=r"mine\.npz: not listed in the manifest"):
        load_excerpt_file(copy / "mine.npz", manifest=copy / "MANIFEST.json")


def test_missing_field(copy):
    path = copy / "cruise.npz"
    _rewrite(path, lambda a: a.pop("truth/velocity"))
    with pytest.raises(ValueError, match=r"cruise\.npz: missing field 'truth/velocity'"):
        load_excerpt_file(path)
    with pytest.raises(ValueError, match=r"cruise\.npz: file is truncated or modified"):
        load_excerpt_file(path, manifest=copy / "MANIFEST.json")


def test_wrong_shape(copy):
    path = copy / "cruise.npz"
    _rewrite(path, lambda a: a.update({"imu/specific_force": a["imu/specific_force"][:, :2]}))
    with pytest.raises(ValueError, match=r"cruise\.npz: field 'imu/specific_force' has shape \(3050, 2\), "
                                         r"expected \(N, 3\)"):
        load_excerpt_file(path)


def test_inconsistent_lengths(copy):
    path = copy / "cruise.npz"
    _rewrite(path, lambda a: a.update({"lidar/position": a["lidar/position"][:-1]}))
    with pytest.raises(ValueError, match=r"field 'lidar/position' has shape \(293, 3\), expected \(K, 3\); "
                                         r"K = 294 from 'truth/t'"):
        load_excerpt_file(path)


@pytest.mark.parametrize("key, factor", [("imu/t", 1e3), ("gnss/t", 1e-3), ("truth/t", 1e6)])
def test_times_in_another_unit_are_refused(copy, key, factor):
    path = copy / "cruise.npz"
    _rewrite(path, lambda a: a.update({key: a[key] * factor}))
    with pytest.raises(ValueError, match=rf"cruise\.npz: field '{key}' has a median step of .* \(times in milli"):
        load_excerpt_file(path)


@pytest.mark.parametrize("section, key, value", [("gnss", "sigma", -1.0), ("lidar", "sigma_position", "0.2"),
                                                 ("lidar", "sigma_attitude_deg", None)])
def test_a_negative_or_missing_sigma_in_the_metadata_is_refused(copy, section, key, value):
    path = copy / "cruise.npz"

    def change(a):
        meta = json.loads(str(a["meta"]))
        meta[section][key] = value
        a["meta"] = np.array(json.dumps(meta))

    _rewrite(path, change)
    with pytest.raises(ValueError, match=rf"cruise\.npz: metadata {section}\.{key} must be a number ≥ 0"):
        load_excerpt_file(path)


def test_wrong_schema_version(copy):
    path = copy / "cruise.npz"

    def bump(a):
        meta = json.loads(str(a["meta"]))
        meta["schema_version"] = 99
        a["meta"] = np.array(json.dumps(meta))

    _rewrite(path, bump)
    with pytest.raises(ValueError, match=r"cruise\.npz: schema version 99, this loader reads version 1"):
        load_excerpt_file(path)


def test_bad_values(copy):
    path = copy / "cruise.npz"

    def nan(a):
        q = a["truth/quaternion"].copy()
        q[3, 0] = np.nan
        a["truth/quaternion"] = q

    _rewrite(path, nan)
    with pytest.raises(ValueError, match=r"field 'truth/quaternion' contains NaN or inf"):
        load_excerpt_file(path)


def test_missing_or_broken_manifest(copy):
    with pytest.raises(FileNotFoundError, match="manifest not found"):
        load_excerpt_file(copy / "cruise.npz", manifest=copy / "nope.json")
    (copy / "MANIFEST.json").write_text("{not json")
    with pytest.raises(ValueError, match="manifest is not valid JSON"):
        load_excerpt_file(copy / "cruise.npz", manifest=copy / "MANIFEST.json")


def test_a_valid_copy_loads(copy):
    ex = load_excerpt_file(copy / "cruise.npz", manifest=copy / "MANIFEST.json")
    assert ex.name == "cruise" and len(ex.imu) == 3050
