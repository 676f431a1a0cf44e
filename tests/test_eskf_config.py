"""ESKF configuration files: shipped files load, every number has unit and meaning, errors are clear."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from kalman_course.filters.eskf_config import config_dir, config_from_dict, load_config


def _raw(name="kitti_lidar"):
    return yaml.safe_load((config_dir() / f"{name}.yaml").read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", ["kitti_lidar", "kitti_gnss"])
def test_shipped_configs_load_with_every_number_documented(name):
    cfg = load_config(name)
    assert cfg.bias_model == "random_walk" and cfg.exact_reset
    for key, s in cfg.settings.items():
        assert s.unit and s.meaning and s.kind in ("std", "density", "per_sample_std"), key
    assert cfg.prior_std.shape == (15,)
    assert cfg.prior_std[6] == pytest.approx(math.radians(0.5))
    assert cfg.lidar_std[3] == pytest.approx(math.radians(0.3))
    np.testing.assert_allclose(cfg.process_density, [0.03, 1e-3, 1.67e-4, 2.91e-6])
    assert cfg.interpolated_density[1] > 10 * cfg.process_density[1]
    table = cfg.describe()
    assert "process.gyro_noise" in table and "rad/s/sqrt(Hz)" in table


def test_per_sample_std_is_converted_to_a_density():
    raw = _raw()
    raw["process"]["accel_noise"] = {"value": 0.3, "unit": "m/s^2", "kind": "per_sample_std",
                                     "meaning": "std of one accelerometer reading at 100 Hz"}
    cfg = config_from_dict(raw)
    assert cfg.si("process.accel_noise") == pytest.approx(0.03)


def test_interpolated_section_is_optional():
    raw = _raw()
    del raw["interpolated_imu"]
    cfg = config_from_dict(raw)
    np.testing.assert_array_equal(cfg.interpolated_density, cfg.process_density)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["process"]["gyro_noise"].pop("meaning"), "missing meaning"),
    (lambda d: d["process"]["gyro_noise"].__setitem__("unit", "rad/s^2"), "unit"),
    (lambda d: d["process"]["gyro_noise"].__setitem__("kind", "std"), "kind"),
    (lambda d: d["prior"]["position"].__setitem__("value", -1.0), "positive"),
    (lambda d: d["prior"]["position"].__setitem__("value", "abc"), "number"),
    (lambda d: d["process"]["accel_noise"].__setitem__("unit", "m/s^2"), "per-sample unit"),
    (lambda d: d["observation"].pop("lidar_position"), "missing observation.lidar_position"),
    (lambda d: d["observation"].__setitem__("radar", {}), "unknown entry observation.radar"),
    (lambda d: d.__setitem__("bias_model", "gauss_markov"), "bias_model"),
    (lambda d: d.__setitem__("exact_reset", "yes"), "exact_reset"),
    (lambda d: d.__setitem__("tuning", 1), "unknown key"),
])
def test_invalid_configs_say_what_is_wrong(mutate, message):
    raw = copy.deepcopy(_raw())
    mutate(raw)
    with pytest.raises(ValueError, match=message):
        config_from_dict(raw)


def test_missing_file_lists_the_shipped_ones(tmp_path):
    with pytest.raises(FileNotFoundError, match="kitti_lidar"):
        load_config("no_such_config")
    bad = tmp_path / "bad.yaml"
    bad.write_text("prior: [1, 2\n", encoding="utf-8")
    with pytest.raises(ValueError, match="not valid YAML"):
        load_config(bad)


def test_replace_changes_fields_and_si_values():
    cfg = load_config()
    c2 = cfg.replace(bias_model="constant", exact_reset=False, process__gyro_noise=2e-3)
    assert c2.bias_model == "constant" and not c2.exact_reset
    assert c2.process_density[1] == 2e-3 and cfg.process_density[1] == 1e-3
    with pytest.raises(ValueError, match="unknown setting"):
        cfg.replace(process__radar=1.0)
    with pytest.raises(ValueError, match="bias_model"):
        cfg.replace(bias_model="none")
    for text in ("false", "no", 0):                      # a YAML-looking string is not a bool
        with pytest.raises(ValueError, match="exact_reset must be True or False"):
            cfg.replace(exact_reset=text)
