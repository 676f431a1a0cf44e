"""KITTI odometry pose files: read and write the devkit's ``poses/NN.txt`` format.

The format (KITTI odometry development kit, ``readme.txt``): one line per frame, 12
numbers separated by spaces, the 3 × 4 matrix [R | t] row by row,

    r00 r01 r02 t0 r10 r11 r12 t1 r20 r21 r22 t2

the pose of the left grey camera (camera 0) at frame i in the frame of camera 0 at frame
0: ``R`` maps camera-i coordinates into camera-0-at-frame-0 coordinates and ``t`` is
camera i's position there, m. Camera axes: x right, y down, z forward, so the vertical is
the y axis (see :func:`kalman_course.evaluation.trajectory.align_poses`,
``vertical_axis=1``). The same format holds an odometry estimate (the devkit's results).

The frame times are in the sequence's ``times.txt`` (one number per line, seconds since
the first frame). Without it :func:`read_kitti_poses` uses frame index × 0.1 s (the
cameras run at about 10 Hz; the real interval varies by a few ms) and says so in the
record's ``time_source``.

The reader checks what it reads and names the file and line of the first problem: a
line without exactly 12 numbers (a truncated last line), a token that is not a number, a
NaN or inf, a rotation block that is not a rotation. The files print about 7 significant
digits, so a rotation block is off SO(3) by up to about 1e-6; the project's tolerance
:data:`~kalman_course.core.validation.ROTATION_TOL` admits that. A file printed with fewer
digits can be read with ``orthonormalise=True``, which projects every block within
:data:`PRINTED_ROTATION_TOL` onto the nearest rotation (and still refuses anything
further off, and every reflection).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kalman_course.core import so3
from kalman_course.core.observations import PoseObservations
from kalman_course.core.validation import ROTATION_TOL, as_flag, as_matrix, as_rows

__all__ = ["KittiPoses", "read_kitti_poses", "write_kitti_poses", "FRAME_PERIOD", "PRINTED_ROTATION_TOL"]

#: Frame interval assumed without a times.txt, s (KITTI's cameras run at about 10 Hz).
FRAME_PERIOD = 0.1

#: With ``orthonormalise=True``, the largest max |RᵀR − I| of a rotation block that is
#: projected onto SO(3) (a matrix printed with 3 to 4 significant digits); beyond it the
#: block is refused, since no number of digits explains it.
PRINTED_ROTATION_TOL = 1e-3

#: Numbers per line: the 3 × 4 matrix [R | t], row-major.
_NUMBERS_PER_LINE = 12


@dataclass(frozen=True, eq=False, repr=False)
class KittiPoses:
    """The poses of a KITTI odometry pose file, one per frame.

    Parameters
    ----------
    t : array_like, shape (K,)
        Frame times, s; strictly increasing.
    position : array_like, shape (K, 3)
        Camera-0 position at each frame in the camera-0 frame of frame 0, m.
    rotation : array_like, shape (K, 3, 3)
        Camera-0 attitude at each frame (camera i → camera 0 at frame 0).
    source : str
        The file the poses were read from.
    time_source : str
        Where ``t`` came from: a times.txt path, ``"times array"`` or
        ``"frame index × 0.1 s"``.

    Attributes
    ----------
    t, position, rotation : numpy.ndarray
        Read-only float64 copies, validated as a
        :class:`~kalman_course.core.observations.PoseObservations` is.
    source, time_source : str

    Raises
    ------
    ValueError
        If the fields do not make a valid pose record (see ``PoseObservations``).
    """

    t: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    source: str = ""
    time_source: str = ""

    def __post_init__(self) -> None:
        # the rules of an observation record: times increasing, finite values, rotations
        record = PoseObservations(self.t, self.position, self.rotation)
        for name in ("t", "position", "rotation"):
            object.__setattr__(self, name, getattr(record, name))

    def __len__(self) -> int:
        """Number of frames K."""
        return int(self.t.shape[0])

    def __repr__(self) -> str:
        return (f"KittiPoses(K={len(self)}, t=[{self.t[0]:g} … {self.t[-1]:g}] s, "
                f"source={self.source!r}, time_source={self.time_source!r})")


def _lines(path: Path, what: str) -> list[str]:
    """The text lines of ``path``; FileNotFoundError or ValueError naming it if it cannot be read."""
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file ({what})")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected {what}")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        line = path.read_bytes()[:exc.start].count(b"\n") + 1
        raise ValueError(f"{path}, line {line}: not UTF-8 text (byte {exc.start}); expected {what}") from None
    lines = text.splitlines()
    while lines and not lines[-1].strip():               # trailing blank lines
        lines.pop()
    if not lines:
        raise ValueError(f"{path}: the file is empty, expected {what}")
    return lines


def _numbers(path: Path, number: int, line: str, count: int, last: bool) -> list[float]:
    """The ``count`` finite numbers of line ``number`` of ``path``, or a ValueError naming it."""
    tokens = line.split()
    if len(tokens) != count:
        hint = " (is the file truncated?)" if last and 0 < len(tokens) < count else ""
        what = "the 3 × 4 matrix [R | t], row by row" if count == _NUMBERS_PER_LINE else "one time, s"
        raise ValueError(f"{path}, line {number}: expected {count} number{'s' * (count > 1)} ({what}), "
                         f"got {len(tokens)}{hint}")
    values = []
    for token in tokens:
        try:
            value = float(token)
        except ValueError:
            raise ValueError(f"{path}, line {number}: {token[:30]!r} is not a number") from None
        if not math.isfinite(value):
            raise ValueError(f"{path}, line {number}: {token!r} is not finite")
        values.append(value)
    return values


def _rotation_blocks(path: Path, rotation: np.ndarray, orthonormalise: bool) -> np.ndarray:
    """The rotation blocks (K, 3, 3), checked (or projected); ValueError naming the line of a bad one."""
    tol = PRINTED_ROTATION_TOL if orthonormalise else ROTATION_TOL
    error = np.abs(np.swapaxes(rotation, -1, -2) @ rotation - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(rotation)
    bad = (error > tol) | (det <= 0.0)
    if bad.any():
        k = int(np.argmax(bad))
        label = f"{path}, line {k + 1}: the rotation block R"
        if not orthonormalise:
            try:
                so3.as_rotations(rotation[k], label)          # the project's rule and message
            except ValueError as exc:
                hint = ""
                if error[k] <= PRINTED_ROTATION_TOL and det[k] > 0.0:
                    hint = ("; if the file was printed with few digits, read it with orthonormalise=True "
                            "to project each block onto the nearest rotation")
                raise ValueError(f"{exc}{hint}") from None
        if det[k] <= 0.0:
            raise ValueError(f"{label} is a reflection, not a rotation (det = {det[k]:.3g}, expected +1)")
        raise ValueError(f"{label} is not a rotation matrix (|RᵀR − I| = {error[k]:.3g}, more than "
                         f"PRINTED_ROTATION_TOL = {tol:g}, the most orthonormalise=True projects)")
    return so3.orthonormalise(rotation) if orthonormalise else rotation


def _times(times, K: int, path: Path) -> tuple[np.ndarray, str]:
    """(t (K,), where it came from): from a times.txt path, an array, or frame index × FRAME_PERIOD."""
    if times is None:
        return np.arange(K) * FRAME_PERIOD, f"frame index × {FRAME_PERIOD:g} s"
    if isinstance(times, (str, os.PathLike)):
        times_path = Path(times)
        lines = _lines(times_path, "a KITTI times.txt file: one time per line, s")
        t = np.array([_numbers(times_path, n, line, 1, n == len(lines))[0]
                      for n, line in enumerate(lines, 1)])
        if t.shape[0] != K:
            raise ValueError(f"{times_path}: {t.shape[0]} times, but {path} has {K} poses (one time per pose)")
        source, label = str(times_path), lambda k: f"{times_path}, line {k + 1}"
    else:
        t = as_rows(times, "times", (), count="K")
        if t.shape[0] != K:
            raise ValueError(f"times must have one time per pose: {t.shape[0]} times, but {path} has {K} poses")
        source, label = "times array", lambda k: f"times[{k}]"
    step = np.diff(t)
    if (step <= 0.0).any():
        k = int(np.argmax(step <= 0.0)) + 1
        raise ValueError(f"{label(k)}: times must strictly increase, got {t[k]:g} s after {t[k - 1]:g} s")
    return t, source


def read_kitti_poses(path, times=None, *, orthonormalise: bool = False) -> KittiPoses:
    """Read a KITTI odometry pose file (``poses/NN.txt`` or an estimate in that format).

    Parameters
    ----------
    path : str or os.PathLike
        The pose file: one line per frame, 12 numbers, the 3 × 4 matrix [R | t] row-major
        (camera 0 at frame i in the camera-0 frame of frame 0).
    times : str, os.PathLike or array_like, shape (K,), optional
        The sequence's ``times.txt`` (one time per line, s) or the times themselves; they
        must strictly increase and number one per pose. None: frame index × ``FRAME_PERIOD``
        (0.1 s), which the record's ``time_source`` says.
    orthonormalise : bool, keyword-only
        False (default): each rotation block must be a rotation to within ``ROTATION_TOL``
        (1e-6, which the devkit's 7 printed digits meet). True: blocks within
        ``PRINTED_ROTATION_TOL`` (1e-3) are projected onto the nearest rotation
        (:func:`kalman_course.core.so3.orthonormalise`); anything further off is refused.

    Returns
    -------
    KittiPoses
        ``t`` (K,) s, ``position`` (K, 3) m, ``rotation`` (K, 3, 3), ``source`` and
        ``time_source``.

    Raises
    ------
    FileNotFoundError
        If ``path`` (or a ``times`` path) does not exist.
    ValueError
        Naming the file and line: the path is a directory, the file is not UTF-8 text or is
        empty, a line does not hold exactly 12 numbers (a truncated last line says so), a
        token is not a number or not finite, a rotation block is not a rotation (scaled,
        sheared, a reflection; the tolerance is named), or the times do not increase or do
        not number one per pose.

    Examples
    --------
    >>> poses = read_kitti_poses("dataset/poses/00.txt", "dataset/sequences/00/times.txt")  # doctest: +SKIP
    >>> poses.position.shape, poses.time_source                                              # doctest: +SKIP
    ((4541, 3), 'dataset/sequences/00/times.txt')
    """
    orthonormalise = as_flag(orthonormalise, "orthonormalise")
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file path (str or pathlib.Path), got {type(path).__name__}")
    path = Path(path)
    lines = _lines(path, "a KITTI pose file: 12 numbers per line")
    values = [_numbers(path, n, line, _NUMBERS_PER_LINE, n == len(lines)) for n, line in enumerate(lines, 1)]
    matrices = np.array(values).reshape(-1, 3, 4)
    rotation = _rotation_blocks(path, matrices[:, :, :3], orthonormalise)
    t, time_source = _times(times, len(lines), path)
    return KittiPoses(t=t, position=matrices[:, :, 3], rotation=rotation, source=str(path),
                      time_source=time_source)


def write_kitti_poses(path, rotation, position, *, overwrite: bool = False) -> Path:
    """Write poses as a KITTI odometry pose file, one line of 12 numbers per pose.

    Each line is the 3 × 4 matrix [R_k | p_k] row-major, in scientific notation with 17
    significant digits, so that :func:`read_kitti_poses` gives back the same numbers.

    Parameters
    ----------
    path : str or os.PathLike
        File to write; its folder must exist.
    rotation : array_like, shape (K, 3, 3)
        Attitudes R_k; each a rotation matrix (max |RᵀR − I| ≤ ROTATION_TOL, det +1).
    position : array_like, shape (K, 3)
        Positions p_k, m.
    overwrite : bool, keyword-only
        Replace an existing file; False (default) refuses to.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    FileExistsError
        If ``path`` exists and ``overwrite`` is False.
    ValueError
        If ``rotation`` or ``position`` has the wrong shape or is not finite, a matrix of
        ``rotation`` is not a rotation (named by its index), or ``overwrite`` is not a bool.
    """
    overwrite = as_flag(overwrite, "overwrite")
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file path (str or pathlib.Path), got {type(path).__name__}")
    R = as_rows(rotation, "rotation", (3, 3), count="K")
    if R.shape[0] == 0:
        raise ValueError("rotation must hold at least one pose, got shape (0, 3, 3)")
    R = so3.as_rotations(R, "rotation")
    p = as_matrix(position, "position", (R.shape[0], 3))
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected a file name to write the poses to")
    matrices = np.concatenate([R, p[:, :, None]], axis=2).reshape(-1, _NUMBERS_PER_LINE)
    text = "".join(" ".join(f"{v:.16e}" for v in row) + "\n" for row in matrices.tolist())
    try:
        with open(path, "w" if overwrite else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise FileExistsError(f"{path}: exists already; pass overwrite=True to replace it") from None
    return path
