"""README, "Your own data": both examples run as printed, on files simulated in their projects' layouts.

No third-party data ships with the course, so the test writes a pickle laid out like the
Toronto ES-EKF project's (plain namespaces with the same attribute names) and KITTI
odometry pose files (12 numbers per line, as the devkit writes them) from the course's own
simulated trajectory, runs each README block in a folder holding them, and checks what it
prints against the truth the files were made from.
"""

from __future__ import annotations

import contextlib
import io
import pickle
import re
import types
from pathlib import Path

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data.synthetic import imu_trajectory
from kalman_course.evaluation.drift import drift

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks() -> list[str]:
    text = README.read_text(encoding="utf-8")
    section = text.split("## Your own data", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def _run(block: str, folder: Path, monkeypatch) -> tuple[dict, str]:
    monkeypatch.chdir(folder)
    namespace: dict = {"__name__": "readme"}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block, "README.md", "exec"), namespace)
    return namespace, out.getvalue()


def test_the_section_has_the_two_examples():
    blocks = _blocks()
    assert len(blocks) == 2
    assert "pt1_data.pkl" in blocks[0] and "read_kitti_poses" in blocks[1]


def _stamped(t, data):
    return types.SimpleNamespace(t=np.asarray(t), data=np.asarray(data))


def test_toronto_example(tmp_path, monkeypatch):
    rng = np.random.default_rng(11)
    sc = imu_trajectory(seed=11, duration=40.0, rate=200.0)
    gt = types.SimpleNamespace(p=sc.position, v=sc.velocity, r=so3.to_rpy(sc.rotation), _t=sc.t)
    gnss_k = np.arange(0, len(sc.t), 200)[1:]          # 1 Hz, σ 0.1 m
    lidar_k = np.arange(0, len(sc.t), 20)[1:]          # 10 Hz, σ 1 m
    data = {"gt": gt, "imu_f": _stamped(sc.t, sc.imu.specific_force), "imu_w": _stamped(sc.t, sc.imu.angular_rate),
            "gnss": _stamped(sc.t[gnss_k], sc.position[gnss_k] + rng.normal(scale=0.1, size=(len(gnss_k), 3))),
            "lidar": _stamped(sc.t[lidar_k], sc.position[lidar_k] + rng.normal(scale=1.0, size=(len(lidar_k), 3)))}
    (tmp_path / "data").mkdir()
    with open(tmp_path / "data" / "pt1_data.pkl", "wb") as f:
        pickle.dump(data, f)
    namespace, printed = _run(_blocks()[0], tmp_path, monkeypatch)
    res = namespace["res"]
    np.testing.assert_array_equal(res.t, sc.t)         # one row per IMU time, the start's included
    rmse = float(re.search(r"position RMSE ([0-9.]+) m", printed).group(1))
    assert rmse < 0.5                                  # half the lidar's σ (0.28 m measured): GNSS and IMU weigh in
    assert set(res.sources) == {"gnss", "lidar"}


def _kitti_lines(rotation, position) -> str:
    rows = np.concatenate([rotation, position[:, :, None]], axis=2).reshape(-1, 12)
    return "".join(" ".join(f"{v:e}" for v in row) + "\n" for row in rows)


def test_kitti_odometry_example(tmp_path, monkeypatch):
    sc = imu_trajectory(seed=12, duration=80.0, rate=10.0)
    R_true, p_true = sc.rotation, sc.position
    # an estimate that drifts (a yaw rate error and a scale error), expressed in another frame
    yaw = so3.exp(np.outer(np.linspace(0.0, 0.03, len(sc.t)), [0.0, 0.0, 1.0]))
    p_est = np.einsum("kij,kj->ki", yaw, p_true - p_true[0]) * 1.01 + p_true[0]
    R_est = yaw @ R_true
    frame_R, frame_t = so3.exp([0.1, -0.2, 0.7]), np.array([5.0, -3.0, 1.0])
    (tmp_path / "poses").mkdir()
    (tmp_path / "results").mkdir()
    (tmp_path / "sequences" / "09").mkdir(parents=True)
    (tmp_path / "poses" / "09.txt").write_text(_kitti_lines(R_true, p_true))
    (tmp_path / "results" / "09.txt").write_text(_kitti_lines(frame_R @ R_est, p_est @ frame_R.T + frame_t))
    (tmp_path / "sequences" / "09" / "times.txt").write_text("".join(f"{t:e}\n" for t in sc.t))
    namespace, printed = _run(_blocks()[1], tmp_path, monkeypatch)
    ate = float(re.search(r"ATE after SE\(3\) alignment ([0-9.]+) m", printed).group(1))
    assert 0.1 < ate < 5.0                               # the drift is left, the frame change is gone
    # drift is invariant to the frame: the metric of the unaligned estimate is the drift made
    expected = drift(p_est, R_est, p_true, R_true)
    shown = re.search(r"drift ([0-9.]+) %, ([0-9.]+) °/100 m", printed)
    assert float(shown.group(1)) == pytest.approx(expected.translation_percent, abs=0.006)
    assert float(shown.group(2)) == pytest.approx(expected.rotation_deg_per_100m, abs=6e-4)
    assert expected.translation_percent > 0.5
