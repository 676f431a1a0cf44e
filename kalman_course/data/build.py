"""Rebuild the shipped KITTI sequence 00 excerpts from PyPI packages.

Usage::

    python -m kalman_course.data.build [--out DIR] [--packages DIR]

The command downloads exactly the ``gtsam`` 4.3.0 wheel and the ``evo`` 1.38.1 sdist with
pip into a temporary folder (or takes them from ``--packages DIR``), checks the sha256 of
every source file it reads, converts the streams to one clock and one frame, simulates the
seeded lidar and GNSS noise and writes ``<name>.npz`` for every excerpt plus
``MANIFEST.json``. The output is byte-for-byte identical on every run on a given machine:
the seeds are fixed and the ``.npz`` archives are written with fixed member order,
timestamps and permissions.

Sources (see ``kitti/ATTRIBUTION.md``)
-------------------------------------
- IMU, 100 Hz: ``gtsam/Data/KittiEquivBiasedImu.txt`` in the gtsam 4.3.0 wheel;
- GNSS/INS positions, 1 Hz: ``gtsam/Data/KittiGps_converted.txt`` (same wheel);
- ground-truth poses and their times: ``test/data/KITTI_00_gt.txt`` and
  ``KITTI_00_gt_times.txt`` in the evo 1.38.1 sdist;
- ORB-SLAM2 and S-PTAM estimates: ``test/data/KITTI_00_ORB.txt``, ``KITTI_00_SPTAM.txt``.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from kalman_course.core import so3
from kalman_course.data.kitti import (EXCERPTS, SCHEMA_VERSION, kitti_dir, simulate_gnss,
                                      simulate_lidar_poses)

__all__ = ["main", "build", "write_npz", "excerpt_arrays", "read_sources", "SOURCES"]

GTSAM = ("gtsam", "4.3.0")
EVO = ("evo", "1.38.1")
#: The gtsam wheel that is downloaded (any platform's wheel carries the same data files).
GTSAM_WHEEL_PLATFORM = "manylinux_2_17_x86_64"
GTSAM_WHEEL_PYTHON = "3.11"

#: stream -> (package, version, distribution kind, path inside it, sha256 of the file)
SOURCES = {
    "imu": (*GTSAM, "wheel", "gtsam/Data/KittiEquivBiasedImu.txt",
            "90264418a69979eccd6d84eb69560225dff544bf6affe353ea37bb70d4ecf38a"),
    "imu_metadata": (*GTSAM, "wheel", "gtsam/Data/KittiEquivBiasedImu_metadata.txt",
                     "70f51ea40a05f1097484634d60064f16bc1622abcaa872458e555442afa44580"),
    "gnss": (*GTSAM, "wheel", "gtsam/Data/KittiGps_converted.txt",
             "aa6f2a1332a40e8cbcd071de650f6b62fc58253e8bef83c8efeb51548dc9102c"),
    "truth": (*EVO, "sdist", "test/data/KITTI_00_gt.txt",
              "90791a4113df979b149fa9e1104e960ea59f525a8318a202dbb6aec1a3d88793"),
    "truth_times": (*EVO, "sdist", "test/data/KITTI_00_gt_times.txt",
                    "99a2899466cdc28dd292b4856d214a8b0aab035b91b02bb6afcb4ff363e7d421"),
    "orb_slam2": (*EVO, "sdist", "test/data/KITTI_00_ORB.txt",
                  "13437093039ccd585d03feb327a6f809a5e12a05a3be33d26192025411eded10"),
    "sptam": (*EVO, "sdist", "test/data/KITTI_00_SPTAM.txt",
              "d364788759ed2c281be91b82fba9bb17d5e77811f1fb6953873b35208ccee0cf"),
}

# --- clocks: tau = stamp − offset (seconds since odometry frame 0) --------------------
IMU_CLOCK_OFFSET = 46534.992
GNSS_CLOCK_OFFSET = 46534.939

# --- T_cam_imu = diag(R_rect_00, 1) · T_cam_velo · T_velo_imu, 2011_10_03 calibration -----
R_CAM_IMU_RAW = ((0.00119669, -0.99997658, 0.00673804),
                 (-0.00924124, -0.00674881, -0.99993453),
                 (0.99995649, 0.00113434, -0.00924910))
T_CAM_IMU = (-0.325411, 0.754050, -1.094933)

# --- ground-truth world (cam0 at frame 0) -> nav: p_n = s R_nw p_w + t_nw (Umeyama fit) ------
SCALE_NAV_WORLD = 0.998106
R_NAV_WORLD_RAW = ((0.861258037, -0.047103388, 0.505980103),
                   (-0.506909961, -0.009618985, 0.861945338),
                   (-0.035733531, -0.998843704, -0.032161605))
T_NAV_WORLD = (-4.712124, -9.928876, 0.691833)

#: g_n, m/s², measured on this data (nav z is up and gravity-aligned to about 0.01°).
GRAVITY_NAV = (0.0, 0.0, -9.8092)

#: An IMU sample is flagged as interpolated when all six channels lie within this distance
#: (m/s² or rad/s) of the straight line through its two neighbours.
INTERPOLATION_TOLERANCE = 1e-6
#: Half-width (samples) of the local cubic fit that gives the truth velocity.
VELOCITY_HALF_WINDOW = 4

#: name -> (tau start, tau end) in s; None = the ground truth's whole span.
EXCERPT_RANGES = {"cruise": (421.5, 452.0), "turns": (310.0, 370.0), "stop_go": (40.0, 100.0),
                  "seq00": None}
LIDAR_SIGMA_POSITION = 0.2
LIDAR_SIGMA_ATTITUDE_DEG = 0.3
GNSS_SIGMA = 1.0
#: Fixed seeds of the shipped noise draws, per file.
LIDAR_SEEDS = {"cruise": 3001, "turns": 3002, "stop_go": 3003, "seq00": 3000}
GNSS_SEEDS = {"cruise": 4001, "turns": 4002, "stop_go": 4003, "seq00": 4000}

LICENCE = ("KITTI Vision Benchmark Suite, CC BY-NC-SA 3.0; Geiger, Lenz, Stiller, Urtasun, "
           "'Vision meets Robotics: The KITTI Dataset', IJRR 32(11), 2013. Derived excerpts, "
           "non-commercial course use, same licence.")

_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def _log(msg: str) -> None:
    print(msg, flush=True)


# ---------------------------------------------------------------------------------------
# Fetching
# ---------------------------------------------------------------------------------------

def download_packages(dest: Path, log=_log) -> tuple[Path, Path]:
    """pip-download the gtsam wheel and the evo sdist into ``dest``; return their paths."""
    dest.mkdir(parents=True, exist_ok=True)
    commands = [
        # one fixed wheel, whatever the local interpreter and platform: only its data files
        # are read, and their sha256 is checked
        [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary", ":all:",
         "--platform", GTSAM_WHEEL_PLATFORM, "--python-version", GTSAM_WHEEL_PYTHON,
         "--implementation", "cp", "-d", str(dest), f"{GTSAM[0]}=={GTSAM[1]}"],
        [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:",
         "-d", str(dest), f"{EVO[0]}=={EVO[1]}"],
    ]
    for cmd in commands:
        log("  $ " + " ".join(cmd[2:]))
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeError(f"pip download failed (exit {result.returncode}):\n{result.stderr.strip()}")
    return find_packages(dest)


def find_packages(folder: Path) -> tuple[Path, Path]:
    """Return the gtsam 4.3.0 wheel and the evo 1.38.1 sdist found in ``folder``."""
    wheels = sorted(folder.glob(f"{GTSAM[0]}-{GTSAM[1]}-*.whl"))
    sdists = sorted(folder.glob(f"{EVO[0]}-{EVO[1]}.tar.gz"))
    if not wheels:
        raise FileNotFoundError(f"{folder}: no {GTSAM[0]}-{GTSAM[1]}-*.whl found")
    if not sdists:
        raise FileNotFoundError(f"{folder}: no {EVO[0]}-{EVO[1]}.tar.gz found")
    return wheels[0], sdists[0]


def read_sources(wheel: Path, sdist: Path) -> dict[str, bytes]:
    """Read every source file named in :data:`SOURCES` and check its sha256."""
    raw: dict[str, bytes] = {}
    with zipfile.ZipFile(wheel) as zf, tarfile.open(sdist, "r:gz") as tf:
        for stream, (pkg, version, kind, member, sha) in SOURCES.items():
            if kind == "wheel":
                data = zf.read(member)
            else:
                fh = tf.extractfile(f"{pkg}-{version}/{member}")
                if fh is None:
                    raise ValueError(f"{sdist}: {member} is not a regular file")
                data = fh.read()
            digest = hashlib.sha256(data).hexdigest()
            if digest != sha:
                raise ValueError(f"{member} in {pkg} {version}: sha256 {digest} differs from the "
                                 f"expected {sha}; the package's data changed")
            raw[stream] = data
    return raw


# ---------------------------------------------------------------------------------------
# Conversion
# ---------------------------------------------------------------------------------------

def _table(data: bytes, skip_rows: int, delimiter=None) -> np.ndarray:
    return np.loadtxt(io.StringIO(data.decode("ascii")), skiprows=skip_rows, delimiter=delimiter, ndmin=2)


def interpolated_mask(t: np.ndarray, values: np.ndarray, tol: float = INTERPOLATION_TOLERANCE) -> np.ndarray:
    """Flag samples lying on the straight line (in time) through their two neighbours.

    Parameters
    ----------
    t : numpy.ndarray, shape (N,)
        Sample times, s.
    values : numpy.ndarray, shape (N, C)
        The channels (here f and ω); a sample is flagged when every channel is within
        ``tol`` of the linear interpolation between its neighbours.

    Returns
    -------
    numpy.ndarray of bool, shape (N,)
    """
    alpha = (t[1:-1] - t[:-2]) / (t[2:] - t[:-2])
    line = values[:-2] + (values[2:] - values[:-2]) * alpha[:, None]
    mask = np.zeros(len(t), dtype=bool)
    mask[1:-1] = np.max(np.abs(values[1:-1] - line), axis=1) < tol
    return mask


def local_cubic_velocity(t: np.ndarray, p: np.ndarray, half_window: int = VELOCITY_HALF_WINDOW) -> np.ndarray:
    """Velocity from positions by a least-squares cubic over 2·half_window + 1 samples.

    The window is centred on each sample (shifted inwards at the ends) and the fitted
    cubic is differentiated at the sample's time.

    Parameters
    ----------
    t : numpy.ndarray, shape (K,)
        Times, s.
    p : numpy.ndarray, shape (K, 3)
        Positions, m.

    Returns
    -------
    numpy.ndarray, shape (K, 3)
        Velocities, m/s.
    """
    K = len(t)
    width = 2 * half_window + 1
    first = np.clip(np.arange(K) - half_window, 0, K - width)
    idx = first[:, None] + np.arange(width)[None, :]
    dt = t[idx] - t[:, None]                                      # (K, width)
    A = dt[:, :, None] ** np.arange(4)[None, None, :]            # (K, width, 4)
    AtA = np.einsum("kwi,kwj->kij", A, A)
    Atp = np.einsum("kwi,kwc->kic", A, p[idx])
    coef = np.linalg.solve(AtA, Atp)                              # (K, 4, 3)
    return coef[:, 1, :]


def convert_sequence(raw: dict[str, bytes]) -> dict[str, np.ndarray]:
    """Convert the raw files to whole-sequence arrays on the tau clock and in the nav frame."""
    imu = _table(raw["imu"], skip_rows=2)            # header, then a lone sample before a 1.92 s gap
    gnss = _table(raw["gnss"], skip_rows=1, delimiter=",")
    gt = _table(raw["truth"], 0).reshape(-1, 3, 4)
    gt_t = _table(raw["truth_times"], 0)[:, 0]
    slam = {key: _table(raw[key], 0).reshape(-1, 3, 4) for key in ("orb_slam2", "sptam")}
    if not (len(gt) == len(gt_t) == len(slam["orb_slam2"]) == len(slam["sptam"])):
        raise ValueError("ground truth, its times and the SLAM estimates must have one row per frame")

    R_ci = so3.orthonormalise(np.array(R_CAM_IMU_RAW))
    t_ci = np.array(T_CAM_IMU)
    R_nw = so3.orthonormalise(np.array(R_NAV_WORLD_RAW))
    t_nw = np.array(T_NAV_WORLD)
    s = SCALE_NAV_WORLD

    def imu_poses(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R_wc = so3.orthonormalise(T[:, :, :3])
        p_w = np.einsum("kij,j->ki", R_wc, t_ci) + T[:, :, 3]   # IMU origin in the world frame
        p_n = s * p_w @ R_nw.T + t_nw
        q_ni = so3.matrix_to_quat(R_nw @ R_wc @ R_ci)
        return p_n, q_ni

    out: dict[str, np.ndarray] = {}
    t_imu = imu[:, 0] - IMU_CLOCK_OFFSET
    out["imu/t"] = t_imu
    # float32 halves the largest fields; its rounding (relative 6e-8, i.e. < 1e-6 m/s² and
    # < 3e-8 rad/s here) is four orders of magnitude below the sensors' noise.
    out["imu/specific_force"] = imu[:, 2:5].astype(np.float32)
    out["imu/angular_rate"] = imu[:, 5:8].astype(np.float32)
    out["imu/interpolated"] = interpolated_mask(t_imu, imu[:, 2:8])
    out["gnss/t"] = gnss[:, 0] - GNSS_CLOCK_OFFSET
    out["gnss/position"] = gnss[:, 1:4]
    p, q = imu_poses(gt)
    out["truth/t"] = gt_t
    out["truth/position"] = p
    out["truth/velocity"] = local_cubic_velocity(gt_t, p)
    out["truth/quaternion"] = q
    for key, T in slam.items():
        out[f"{key}/position"], out[f"{key}/quaternion"] = imu_poses(T)
    out["gravity"] = np.array(GRAVITY_NAV)
    out["frames/R_cam_imu"] = R_ci
    out["frames/t_cam_imu"] = t_ci
    out["frames/R_nav_world"] = R_nw
    out["frames/t_nav_world"] = t_nw
    out["frames/scale"] = np.array(s)
    return out


def _provenance() -> dict:
    def src(*streams: str) -> list[dict]:
        return [{"package": SOURCES[k][0], "version": SOURCES[k][1], "distribution": SOURCES[k][2],
                 "file": SOURCES[k][3], "sha256": SOURCES[k][4]} for k in streams]

    return {
        "licence": LICENCE,
        "imu": {"sources": src("imu", "imu_metadata"),
                "transform": f"header and first data row skipped (lone sample before a 1.92 s gap); "
                             f"specific force and angular rate stored as float32; "
                             f"tau = stamp - {IMU_CLOCK_OFFSET}; body frame x forward, y left, z up; "
                             f"interpolated = all 6 channels within {INTERPOLATION_TOLERANCE} of the "
                             f"line through both neighbours",
                "metadata_noise_densities": {"accel": 0.01, "gyro": 1.75e-4, "accel_bias": 1.67e-4,
                                             "gyro_bias": 2.91e-6}},
        "gnss": {"sources": src("gnss"),
                 "transform": f"tau = stamp - {GNSS_CLOCK_OFFSET}; positions as recorded (OXTS INS "
                              f"solution); position_noisy adds simulated N(0, sigma^2) per axis"},
        "truth": {"sources": src("truth", "truth_times"),
                  "transform": "T_w_imu = T_w_cam0 T_cam_imu (rotations orthonormalised); "
                               "p_n = s R_nw p_w + t_nw, R_nb = R_nw R_w_imu; velocity by a local cubic "
                               f"least-squares fit over {2 * VELOCITY_HALF_WINDOW + 1} poses"},
        "lidar": {"sources": src("truth", "truth_times"),
                  "transform": "SIMULATED: truth plus seeded noise, p + sigma_p n_p, R Exp(sigma_theta n_theta)"},
        "orb_slam2": {"sources": src("orb_slam2", "truth_times"),
                      "transform": "camera poses mapped to IMU poses in the nav frame like the truth"},
        "sptam": {"sources": src("sptam", "truth_times"),
                  "transform": "camera poses mapped to IMU poses in the nav frame like the truth"},
    }


def excerpt_arrays(seq: dict[str, np.ndarray], name: str) -> dict[str, np.ndarray]:
    """Cut one excerpt out of the whole-sequence arrays and add its simulated noise."""
    tau = EXCERPT_RANGES[name]
    if tau is None:
        tau = (float(seq["truth/t"][0]), float(seq["truth/t"][-1]))
    out: dict[str, np.ndarray] = {}
    for stream in ("imu", "gnss", "truth"):
        t = seq[f"{stream}/t"]
        keep = (t >= tau[0]) & (t <= tau[1])
        prefixes = (stream,) if stream != "truth" else ("truth", "orb_slam2", "sptam")
        for key, value in seq.items():
            if key.split("/")[0] in prefixes:
                out[key] = value[keep]
    for key in ("gravity", "frames/R_cam_imu", "frames/t_cam_imu", "frames/R_nav_world",
                "frames/t_nav_world", "frames/scale"):
        out[key] = seq[key]

    poses = SimpleNamespace(t=out["truth/t"], position=out["truth/position"],
                            quaternion=out["truth/quaternion"])
    lidar = simulate_lidar_poses(poses, LIDAR_SEEDS[name], LIDAR_SIGMA_POSITION, LIDAR_SIGMA_ATTITUDE_DEG)
    out["lidar/position"] = lidar.position
    out["lidar/quaternion"] = lidar.quaternion

    fixes = SimpleNamespace(t=out["gnss/t"], position_true=out["gnss/position"])   # the recorded solution
    out["gnss/position_noisy"] = simulate_gnss(fixes, GNSS_SEEDS[name], GNSS_SIGMA).position_noisy
    meta = {
        "name": name,
        "schema_version": SCHEMA_VERSION,
        "tau_range": [float(tau[0]), float(tau[1])],
        "lidar": {"simulated": True, "seed": LIDAR_SEEDS[name], "sigma_position": LIDAR_SIGMA_POSITION,
                  "sigma_attitude_deg": LIDAR_SIGMA_ATTITUDE_DEG},
        "gnss": {"simulated_noise": True, "seed": GNSS_SEEDS[name], "sigma": GNSS_SIGMA},
        "provenance": _provenance(),
    }
    out["meta"] = np.array(json.dumps(meta, sort_keys=True))
    return out


# ---------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------

def write_npz(path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` as a compressed ``.npz`` whose bytes depend only on the arrays.

    Members are written in sorted key order with a fixed timestamp (1980-01-01), fixed
    permissions and deflate level 9; every array is stored little-endian and C-ordered.
    ``numpy.load`` reads the result like any ``.npz``.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w") as zf:
        for key in sorted(arrays):
            arr = np.asarray(arrays[key], order="C")
            if arr.dtype.kind in "fiu":
                arr = arr.astype(arr.dtype.newbyteorder("<"), copy=False)
            buf = io.BytesIO()
            np.lib.format.write_array(buf, arr, version=(1, 0), allow_pickle=False)
            info = zipfile.ZipInfo(key + ".npy", date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.create_system = 3
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue(), compresslevel=9)
    tmp.replace(path)


def content_sha256(arrays: dict[str, np.ndarray]) -> str:
    """sha256 over the uncompressed .npy bytes of each member, in key order.

    Unlike the file checksum it does not depend on the zlib version that compressed them.
    """
    h = hashlib.sha256()
    for key in sorted(arrays):
        buf = io.BytesIO()
        np.lib.format.write_array(buf, np.asarray(arrays[key], order="C"), version=(1, 0), allow_pickle=False)
        h.update(key.encode() + b"\0" + buf.getvalue())
    return h.hexdigest()


def build(out_dir, packages_dir=None, log=_log) -> dict:
    """Build every excerpt into ``out_dir`` and write its ``MANIFEST.json``.

    Parameters
    ----------
    out_dir : str or Path
        Output folder (created if needed).
    packages_dir : str or Path, optional
        Folder that already holds the gtsam wheel and the evo sdist; if None they are
        downloaded with pip into a temporary folder that is deleted afterwards.
    log : callable
        Receives one progress line at a time.

    Returns
    -------
    dict
        The manifest that was written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="kalman-course-kitti-") as tmp:
        if packages_dir is None:
            log(f"downloading {GTSAM[0]} {GTSAM[1]} (wheel) and {EVO[0]} {EVO[1]} (sdist) with pip ...")
            wheel, sdist = download_packages(Path(tmp), log)
        else:
            wheel, sdist = find_packages(Path(packages_dir))
        log(f"reading {wheel.name} and {sdist.name} ...")
        raw = read_sources(wheel, sdist)
    log("converting sequence 00 to the tau clock and the navigation frame ...")
    seq = convert_sequence(raw)
    files = {}
    for name in EXCERPTS:
        arrays = excerpt_arrays(seq, name)
        path = out_dir / f"{name}.npz"
        write_npz(path, arrays)
        data = path.read_bytes()
        files[path.name] = {
            "sha256": hashlib.sha256(data).hexdigest(),
            "size": len(data),
            "schema_version": SCHEMA_VERSION,
            "content_sha256": content_sha256(arrays),
            "tau_range": json.loads(str(arrays["meta"]))["tau_range"],
            "counts": {"imu": int(len(arrays["imu/t"])), "gnss": int(len(arrays["gnss/t"])),
                       "truth": int(len(arrays["truth/t"]))},
        }
        log(f"  wrote {path} ({len(data) / 1e6:.2f} MB, {len(arrays['imu/t'])} IMU samples)")
    manifest = {
        "schema_version": SCHEMA_VERSION,
        "description": "KITTI sequence 00 excerpts for kalman-course; rebuild with "
                       "`python -m kalman_course.data.build`",
        "licence": LICENCE,
        "files": files,
    }
    (out_dir / "MANIFEST.json").write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n",
                                           encoding="utf-8")
    log(f"  wrote {out_dir / 'MANIFEST.json'}")
    return manifest


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    parser = argparse.ArgumentParser(prog="python -m kalman_course.data.build",
                                     description="Rebuild the KITTI sequence 00 excerpts from PyPI packages.")
    parser.add_argument("--out", default=None,
                        help=f"output folder (default: the package's data folder, {kitti_dir()})")
    parser.add_argument("--packages", default=None, metavar="DIR",
                        help="use the gtsam wheel and evo sdist already in DIR instead of downloading")
    args = parser.parse_args(argv)
    out = Path(args.out) if args.out else kitti_dir()
    try:
        build(out, packages_dir=args.packages)
    except (RuntimeError, ValueError, FileNotFoundError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print("done")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
