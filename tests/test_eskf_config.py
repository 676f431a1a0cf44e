"""ESKF configuration files: shipped files load, every number has unit and meaning, errors are clear."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from kalman_course.core.observations import PositionObservations
from kalman_course.data import load_kitti
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import config_dir, config_from_dict, load_config
from kalman_course.filters.eskf_streams import ObservationStream


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
    (lambda d: d["prior"]["position"].__setitem__("value", -1.0), r"non-negative \(0 = known exactly\)"),
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


def test_zero_means_known_exactly_a_bias_free_filter_needs_no_tiny_numbers():
    # the Toronto project's filter has no bias states: biases known to be zero, and constant
    raw = copy.deepcopy(_raw())
    for entry in ("accel_bias", "gyro_bias"):
        raw["prior"][entry]["value"] = 0
    raw["bias_model"] = "constant"
    cfg = config_from_dict(raw)
    assert (cfg.prior_std[9:] == 0.0).all()
    assert cfg.replace(process__accel_bias_noise=0.0).process_density[2] == 0.0
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    res = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0, t_end=ex.imu.t[k0] + 5.0)
    assert res.updated.all() and len(res.t) > 40
    assert (res.accel_bias == 0.0).all() and (res.gyro_bias == 0.0).all()
    assert (res.P[:, 9:, :] == 0.0).all() and (res.P[:, :, 9:] == 0.0).all()
    with pytest.raises(ValueError, match=r"imu_rate_hz: value must be a positive finite number, got 0"):
        config_from_dict(dict(raw, imu_rate_hz=0))


def test_a_zero_noise_sensor_the_filter_is_already_certain_of_is_named():
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    fix = PositionObservations([ex.imu.t[k0 + 1]], [s0.position])
    with pytest.raises(ValueError, match=r"^surveyed\[0\] at t = [0-9.]+ s: the innovation covariance S = G P̌ Gᵀ \+ R "
                                         r"is singular"):
        eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=ex.imu.t[k0 + 3], P0=np.zeros((15, 15)),
                 streams=[ObservationStream(fix, 0.0, name="surveyed")])
