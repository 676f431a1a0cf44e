"""The KITTI odometry pose-file reader and writer (kalman_course.data.kitti_odometry).

Every file is written here, into tmp_path: no third-party data is shipped or read.
"""

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data.kitti_odometry import (FRAME_PERIOD, KittiPoses, read_kitti_poses,
                                               write_kitti_poses)


@pytest.fixture
def trajectory():
    rng = np.random.default_rng(21)
    K = 30
    rotation = so3.from_rpy(rng.uniform(-0.1, 0.1, K), rng.uniform(-0.1, 0.1, K), np.linspace(0.0, 3.0, K))
    position = np.cumsum(rng.normal(0.0, 1.0, (K, 3)), axis=0)
    return rotation, position


def devkit_text(rotation, position, fmt="{:e}"):
    """Lines as the devkit prints them: [R | t] row-major, %e (7 significant digits)."""
    rows = np.concatenate([rotation, position[:, :, None]], axis=2).reshape(-1, 12)
    return "".join(" ".join(fmt.format(v) for v in row) + "\n" for row in rows)


def test_a_devkit_file_is_read(tmp_path, trajectory):
    rotation, position = trajectory
    path = tmp_path / "00.txt"
    path.write_text(devkit_text(rotation, position))
    poses = read_kitti_poses(path)
    assert isinstance(poses, KittiPoses) and len(poses) == 30
    np.testing.assert_allclose(poses.rotation, rotation, atol=1e-6)
    np.testing.assert_allclose(poses.position, position, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(poses.t, FRAME_PERIOD * np.arange(30))
    assert poses.time_source == "frame index × 0.1 s" and poses.source == str(path)
    assert not poses.position.flags.writeable


def test_the_first_pose_of_a_devkit_file_is_the_identity(tmp_path):
    # the devkit's first line, as poses/00.txt prints it
    path = tmp_path / "00.txt"
    path.write_text("1.000000e+00 9.043680e-12 2.326809e-11 5.551115e-17 9.043683e-12 1.000000e+00 "
                    "2.392370e-10 3.330669e-16 2.326810e-11 2.392370e-10 9.999999e-01 -4.440892e-16\n")
    poses = read_kitti_poses(path)
    np.testing.assert_allclose(poses.rotation[0], np.eye(3), atol=1e-6)


def test_write_then_read_gives_the_same_numbers(tmp_path, trajectory):
    rotation, position = trajectory
    path = write_kitti_poses(tmp_path / "est.txt", rotation, position)
    poses = read_kitti_poses(path)
    np.testing.assert_array_equal(poses.rotation, rotation)
    np.testing.assert_array_equal(poses.position, position)
    assert all(len(line.split()) == 12 for line in path.read_text().splitlines())


def test_write_refuses_to_overwrite(tmp_path, trajectory):
    rotation, position = trajectory
    path = write_kitti_poses(tmp_path / "est.txt", rotation, position)
    with pytest.raises(FileExistsError, match="exists already; pass overwrite=True"):
        write_kitti_poses(path, rotation[:3], position[:3])
    assert len(read_kitti_poses(path)) == 30                       # untouched
    write_kitti_poses(path, rotation[:3], position[:3], overwrite=True)
    assert len(read_kitti_poses(path)) == 3


def test_write_names_bad_input(tmp_path, trajectory):
    rotation, position = trajectory
    bad = rotation.copy()
    bad[4] = -bad[4]
    with pytest.raises(ValueError, match=r"^rotation\[4\] is a reflection"):
        write_kitti_poses(tmp_path / "a.txt", bad, position)
    with pytest.raises(ValueError, match=r"position must have shape \(30, 3\)"):
        write_kitti_poses(tmp_path / "a.txt", rotation, position[:5])
    with pytest.raises(ValueError, match="overwrite must be True or False"):
        write_kitti_poses(tmp_path / "a.txt", rotation, position, overwrite=1)
    with pytest.raises(ValueError, match="is a directory"):
        write_kitti_poses(tmp_path, rotation, position)
    assert not (tmp_path / "a.txt").exists()


def test_times_from_a_file_or_an_array(tmp_path, trajectory):
    rotation, position = trajectory
    path = write_kitti_poses(tmp_path / "00.txt", rotation, position)
    times = 0.1036 * np.arange(30)
    times_path = tmp_path / "times.txt"
    times_path.write_text("".join(f"{v:e}\n" for v in times))
    from_file = read_kitti_poses(path, times_path)
    np.testing.assert_allclose(from_file.t, times, rtol=1e-6)
    assert from_file.time_source == str(times_path)
    from_array = read_kitti_poses(path, times)
    np.testing.assert_array_equal(from_array.t, times)
    assert from_array.time_source == "times array"


@pytest.mark.parametrize("text, message", [
    ("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n",
     r"line 2: expected 12 numbers \(the 3 × 4 matrix \[R \| t\], row by row\), got 11 \(is the file truncated\?\)"),
    ("1 0 0 0 0 1 0 0 0 0 1 0 7\n1 0 0 0 0 1 0 0 0 0 1 0\n", r"line 1: expected 12 numbers.*got 13$"),
    ("1 0 0 0 0 1 0 0 0 0 1 0\n\n1 0 0 0 0 1 0 0 0 0 1 0\n", r"line 2: expected 12 numbers.*got 0$"),
    ("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 x 0 1 0 0 0 0 1 0\n", r"line 2: 'x' is not a number"),
    ("1 0 0 0 0 1 0 0 0 0 1 nan\n", r"line 1: 'nan' is not finite"),
    ("1 0 0 0 0 1 0 0 0 0 -1 0\n", r"line 1: the rotation block R is a reflection, not a rotation \(det = -1"),
    ("1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 2 0 0 0 0 2 0\n",
     r"line 2: the rotation block R is not a rotation matrix \(\|RᵀR − I\| = 3, tolerance 1e-06\)$"),
    ("1 0 0 0 0.1 1 0 0 0 0 1 0\n", r"line 1: the rotation block R is not a rotation matrix"),
    ("", "the file is empty"),
    ("\n\n", "the file is empty"),
])
def test_a_bad_pose_file_is_named_with_its_line(tmp_path, text, message):
    path = tmp_path / "poses.txt"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        read_kitti_poses(path)
    assert str(info.value).startswith(str(path))


def test_trailing_blank_lines_are_fine(tmp_path):
    path = tmp_path / "poses.txt"
    path.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n\n  \n")
    assert len(read_kitti_poses(path)) == 2


def test_missing_file_directory_and_binary(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothere.txt: no such file"):
        read_kitti_poses(tmp_path / "nothere.txt")
    with pytest.raises(ValueError, match="is a directory, expected a KITTI pose file"):
        read_kitti_poses(tmp_path)
    binary = tmp_path / "poses.bin"
    binary.write_bytes(b"1 0 0 0 0 1 0 0 0 0 1 0\n\xff\xfe\x00")
    with pytest.raises(ValueError, match=r"poses.bin, line 2: not UTF-8 text"):
        read_kitti_poses(binary)
    with pytest.raises(ValueError, match="path must be a file path"):
        read_kitti_poses(3)
    with pytest.raises(ValueError, match="orthonormalise must be True or False"):
        read_kitti_poses(binary, orthonormalise="yes")


def test_few_digits_need_orthonormalise(tmp_path, trajectory):
    rotation, position = trajectory
    path = tmp_path / "coarse.txt"
    path.write_text(devkit_text(rotation, position, fmt="{:.3e}"))       # 4 significant digits
    with pytest.raises(ValueError, match=r"line 1: the rotation block R is not a rotation matrix.*"
                                         r"read it with orthonormalise=True"):
        read_kitti_poses(path)
    poses = read_kitti_poses(path, orthonormalise=True)
    assert so3.is_rotation(poses.rotation, tol=1e-12)
    np.testing.assert_allclose(poses.rotation, rotation, atol=1e-3)
    # but a block no printing explains is still refused, and so is a reflection
    far = tmp_path / "far.txt"
    far.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n1 0.1 0 0 0 1 0 0 0 0 1 0\n")
    with pytest.raises(ValueError, match=r"far.txt, line 2: .*more than PRINTED_ROTATION_TOL"):
        read_kitti_poses(far, orthonormalise=True)
    mirror = tmp_path / "mirror.txt"
    mirror.write_text("1 0 0 0 0 1 0 0 0 0 -1 0\n")
    with pytest.raises(ValueError, match=r"mirror.txt, line 1: the rotation block R is a reflection"):
        read_kitti_poses(mirror, orthonormalise=True)


@pytest.mark.parametrize("times_text, message", [
    ("0\n0.1\n", r"times.txt: 2 times, but .*poses.txt has 3 poses"),
    ("0\n0.1\n0.1\n", r"times.txt, line 3: times must strictly increase, got 0.1 s after 0.1 s"),
    ("0\n0.1\nabc\n", r"times.txt, line 3: 'abc' is not a number"),
    ("0\n0.1 0.2\n0.3\n", r"times.txt, line 2: expected 1 number \(one time, s\), got 2"),
])
def test_a_bad_times_file_is_named(tmp_path, times_text, message):
    path = tmp_path / "poses.txt"
    path.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 3)
    (tmp_path / "times.txt").write_text(times_text)
    with pytest.raises(ValueError, match=message):
        read_kitti_poses(path, tmp_path / "times.txt")


def test_bad_times_arrays_are_named(tmp_path):
    path = tmp_path / "poses.txt"
    path.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 3)
    with pytest.raises(ValueError, match="times must have one time per pose: 2 times, but"):
        read_kitti_poses(path, [0.0, 0.1])
    with pytest.raises(ValueError, match=r"times\[2\]: times must strictly increase"):
        read_kitti_poses(path, [0.0, 0.2, 0.1])
    with pytest.raises(ValueError, match=r"times\[1\] is NaN"):
        read_kitti_poses(path, [0.0, np.nan, 0.1])
    with pytest.raises(FileNotFoundError, match="times.txt: no such file"):
        read_kitti_poses(path, tmp_path / "times.txt")


def test_the_record_validates_direct_construction():
    with pytest.raises(ValueError, match=r"rotation\[0\] is a reflection"):
        KittiPoses([0.0], np.zeros((1, 3)), -np.eye(3)[None])
