"""Configuration of the error-state Kalman filter: a YAML file, loaded and validated.

Every number in the file is a mapping with its value, its unit, its kind and a sentence
saying what it means, so that nobody has to guess whether ``0.03`` is a per-sample
standard deviation or a continuous noise density::

    process:
      accel_noise:
        value: 0.03
        unit: m/s^2/sqrt(Hz)
        kind: density
        meaning: accelerometer white noise n_a, continuous density

Kinds
-----
``std``
    a standard deviation of one quantity (prior uncertainty, one observation's noise).
``density``
    the square root of the power spectral density of a continuous white noise. Over a
    step of T seconds it adds ``density² · T`` of variance to the integrated quantity;
    the equivalent per-sample standard deviation of the reading is ``density / √T``.
``per_sample_std``
    the standard deviation of one IMU reading at the file's ``imu_rate_hz``; converted to
    a density as ``std / √imu_rate_hz``.

The filter (:mod:`kalman_course.filters.eskf`) only ever sees SI values (m, m/s, rad, densities);
:func:`load_config` converts degrees and per-sample numbers once, here.

Shipped files (``kalman_course/filters/eskf_configs/``): ``kitti_lidar.yaml`` (10 Hz lidar
map-matching poses) and ``kitti_gnss.yaml`` (1 Hz GNSS positions). Load them by name::

    from kalman_course.filters.eskf_config import load_config
    cfg = load_config("kitti_lidar")
    print(cfg.describe())
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from kalman_course.core.validation import as_flag

__all__ = ["NoiseSetting", "EskfConfig", "load_config", "config_from_dict", "config_dir",
           "BIAS_MODELS", "SECTIONS"]

#: Bias models: a random walk (δḃ = n_b) or the lecture's constant bias (δḃ = 0).
BIAS_MODELS = ("random_walk", "constant")

_DEG = math.pi / 180.0

# section -> entry -> (allowed kinds, {unit: factor to SI}, SI unit shown, required)
_STD = ("std",)
_WHITE = ("density", "per_sample_std")
_RW = ("density",)
SECTIONS: dict[str, dict[str, tuple]] = {
    "prior": {
        "position": (_STD, {"m": 1.0}, "m", True),
        "velocity": (_STD, {"m/s": 1.0}, "m/s", True),
        "attitude": (_STD, {"rad": 1.0, "deg": _DEG}, "rad", True),
        "accel_bias": (_STD, {"m/s^2": 1.0}, "m/s^2", True),
        "gyro_bias": (_STD, {"rad/s": 1.0, "deg/s": _DEG}, "rad/s", True),
    },
    "process": {
        "accel_noise": (_WHITE, {"m/s^2/sqrt(Hz)": 1.0, "m/s^2": None}, "m/s^2/sqrt(Hz)", True),
        "gyro_noise": (_WHITE, {"rad/s/sqrt(Hz)": 1.0, "rad/s": None, "deg/s/sqrt(Hz)": _DEG},
                       "rad/s/sqrt(Hz)", True),
        "accel_bias_noise": (_RW, {"m/s^3/sqrt(Hz)": 1.0}, "m/s^3/sqrt(Hz)", True),
        "gyro_bias_noise": (_RW, {"rad/s^2/sqrt(Hz)": 1.0}, "rad/s^2/sqrt(Hz)", True),
    },
    "interpolated_imu": {
        "accel_noise": (_WHITE, {"m/s^2/sqrt(Hz)": 1.0, "m/s^2": None}, "m/s^2/sqrt(Hz)", False),
        "gyro_noise": (_WHITE, {"rad/s/sqrt(Hz)": 1.0, "rad/s": None, "deg/s/sqrt(Hz)": _DEG},
                       "rad/s/sqrt(Hz)", False),
    },
    "observation": {
        "lidar_position": (_STD, {"m": 1.0}, "m", True),
        "lidar_attitude": (_STD, {"rad": 1.0, "deg": _DEG}, "rad", True),
        "gnss_position": (_STD, {"m": 1.0}, "m", True),
    },
}


@dataclass(frozen=True)
class NoiseSetting:
    """One number of the configuration, as written in the file.

    Attributes
    ----------
    value : float
        The number as written.
    unit : str
        Its unit as written (for example ``deg`` or ``m/s^2/sqrt(Hz)``).
    kind : str
        ``std``, ``density`` or ``per_sample_std`` (see the module docstring).
    meaning : str
        What the number is, in one sentence.
    si : float
        The value the filter uses: a standard deviation in m, m/s, rad, m/s², rad/s, or a
        density in SI units per √Hz.
    """

    value: float
    unit: str
    kind: str
    meaning: str
    si: float


@dataclass(frozen=True)
class EskfConfig:
    """A validated ESKF configuration in SI units.

    Attributes
    ----------
    name : str
        Where it came from (file stem or "dict").
    bias_model : str
        ``"random_walk"`` (δḃ = n_b; B has four noise columns) or ``"constant"`` (δḃ = 0;
        B has two noise columns and the biases keep only their prior uncertainty).
    exact_reset : bool
        After injection apply P ← G P Gᵀ with the exact reset Jacobian G (True), or leave
        P as it is, as the lecture does (False).
    imu_rate_hz : float
        Nominal IMU rate, Hz; only used to convert ``per_sample_std`` entries.
    settings : dict
        ``{"section.entry": NoiseSetting}`` for every number in the file.
    """

    name: str
    bias_model: str
    exact_reset: bool
    imu_rate_hz: float
    settings: dict = field(repr=False)

    # ---- SI accessors ---------------------------------------------------------------
    def si(self, key: str) -> float:
        """SI value of ``"section.entry"``; inside ``interpolated_imu`` falls back to ``process``."""
        if key in self.settings:
            return self.settings[key].si
        section, entry = key.split(".", 1)
        if section == "interpolated_imu":
            return self.settings[f"process.{entry}"].si
        raise KeyError(f"no setting {key!r}; known: {', '.join(sorted(self.settings))}")

    @property
    def prior_std(self) -> np.ndarray:
        """Standard deviations of δx = [δp, δv, δθ, δb_a, δb_ω] at the start, shape (15,)."""
        names = ("position", "velocity", "attitude", "accel_bias", "gyro_bias")
        return np.repeat([self.si(f"prior.{n}") for n in names], 3)

    @property
    def process_density(self) -> np.ndarray:
        """Densities (σ_a, σ_ω, σ_ba, σ_bω) of w = [n_a, n_ω, n_ba, n_bω], shape (4,)."""
        return np.array([self.si("process.accel_noise"), self.si("process.gyro_noise"),
                         self.si("process.accel_bias_noise"), self.si("process.gyro_bias_noise")])

    @property
    def interpolated_density(self) -> np.ndarray:
        """Densities used on IMU steps flagged as interpolated or bridging a gap, shape (4,).

        :func:`kalman_course.filters.eskf.run` uses them on steps touching an interpolated
        sample (``imu.interpolated``) and on gaps in the IMU clock (a step longer than
        ``gap_factor`` median steps).
        """
        return np.array([self.si("interpolated_imu.accel_noise"), self.si("interpolated_imu.gyro_noise"),
                         self.si("process.accel_bias_noise"), self.si("process.gyro_bias_noise")])

    @property
    def lidar_std(self) -> np.ndarray:
        """Standard deviations of the pose residual [δp̄ (m) ×3, δθ̄ (rad) ×3], shape (6,)."""
        return np.repeat([self.si("observation.lidar_position"), self.si("observation.lidar_attitude")], 3)

    @property
    def gnss_std(self) -> float:
        """Standard deviation of one GNSS position component, m."""
        return self.si("observation.gnss_position")

    def replace(self, **changes) -> "EskfConfig":
        """A copy with fields or SI values changed.

        Field names (``bias_model``, ``exact_reset``) are replaced as given; any other
        keyword is ``section__entry`` (for example ``process__gyro_noise=1e-3``) and sets
        that setting's SI value.
        """
        fields = {f.name for f in dataclasses.fields(self)}
        direct = {k: v for k, v in changes.items() if k in fields}
        settings = dict(self.settings)
        for key, value in changes.items():
            if key in fields:
                continue
            if "__" not in key:
                raise ValueError(f"unknown configuration change {key!r}: use a field name "
                                 f"({', '.join(sorted(fields))}) or section__entry")
            section, entry = key.split("__", 1)
            if section not in SECTIONS or entry not in SECTIONS[section]:
                raise ValueError(f"unknown setting {section}.{entry}")
            v = _positive(value, f"{section}.{entry}", allow_zero=True)
            si_unit = SECTIONS[section][entry][2]
            kind = SECTIONS[section][entry][0][0]
            settings[f"{section}.{entry}"] = NoiseSetting(v, si_unit, kind, "set in code", v)
        if "bias_model" in direct and direct["bias_model"] not in BIAS_MODELS:
            raise ValueError(f"bias_model must be one of {BIAS_MODELS}, got {direct['bias_model']!r}")
        if "exact_reset" in direct:
            direct["exact_reset"] = as_flag(direct["exact_reset"], "exact_reset")
        return dataclasses.replace(self, settings=settings, **direct)

    def describe(self) -> str:
        """The settings as a Markdown table (value, unit, kind, SI value, meaning)."""
        lines = [f"ESKF configuration `{self.name}`: bias model {self.bias_model}, "
                 f"exact reset {'on' if self.exact_reset else 'off'}", "",
                 "| setting | value | unit | kind | meaning |", "|---|---|---|---|---|"]
        for key, s in self.settings.items():
            lines.append(f"| {key} | {s.value:.4g} | {s.unit} | {s.kind} | {s.meaning} |")
        return "\n".join(lines)


def config_dir() -> Path:
    """Folder of the shipped configuration files."""
    return Path(__file__).resolve().parent / "eskf_configs"


def _positive(value, where: str, allow_zero: bool = False) -> float:
    """``value`` as a finite float > 0 (≥ 0 with ``allow_zero``: a noise of 0 means known exactly)."""
    if isinstance(value, bool):
        raise ValueError(f"{where}: value must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: value must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        kind = "non-negative (0 = known exactly)" if allow_zero else "positive"
        raise ValueError(f"{where}: value must be a {kind} finite number, got {value!r}")
    return v


def config_from_dict(data, name: str = "dict") -> EskfConfig:
    """Validate a configuration given as a mapping (the parsed YAML) and convert it to SI.

    Raises
    ------
    ValueError
        Naming the section and entry: a missing or unknown key, a non-positive value, a
        unit or kind that does not fit the entry, a missing ``meaning``.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string (where the configuration came from), got {name!r}")
    where = f"config {name}"
    if not isinstance(data, dict):
        raise ValueError(f"{where}: must be a mapping at the top level, got {type(data).__name__}")
    known_top = {"bias_model", "exact_reset", "imu_rate_hz", "description", *SECTIONS}
    unknown = sorted(str(k) for k in set(data) - known_top)        # a key may be a number in YAML
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known_top))}")
    bias_model = data.get("bias_model", "random_walk")
    if bias_model not in BIAS_MODELS:
        raise ValueError(f"{where}: bias_model must be one of {BIAS_MODELS}, got {bias_model!r}")
    exact_reset = data.get("exact_reset", True)
    if not isinstance(exact_reset, bool):
        raise ValueError(f"{where}: exact_reset must be true or false, got {exact_reset!r}")
    rate = _positive(data.get("imu_rate_hz", 100.0), f"{where}: imu_rate_hz")

    settings: dict[str, NoiseSetting] = {}
    for section, entries in SECTIONS.items():
        block = data.get(section, {})
        if block is None:
            block = {}
        if not isinstance(block, dict):
            raise ValueError(f"{where}: section {section!r} must be a mapping")
        extra = sorted(str(k) for k in set(block) - set(entries))
        if extra:
            raise ValueError(f"{where}: unknown entry {section}.{extra[0]}; known: {', '.join(entries)}")
        for entry, (kinds, units, _si_unit, required) in entries.items():
            key = f"{section}.{entry}"
            if entry not in block:
                if required:
                    raise ValueError(f"{where}: missing {key}")
                continue
            item = block[entry]
            if not isinstance(item, dict):
                raise ValueError(f"{where}: {key} must be a mapping with value, unit, kind and meaning, "
                                 f"got {item!r}")
            missing = [k for k in ("value", "unit", "kind", "meaning") if k not in item]
            if missing:
                raise ValueError(f"{where}: {key} is missing {', '.join(missing)}")
            value = _positive(item["value"], f"{where}: {key}", allow_zero=True)
            kind, unit, meaning = item["kind"], item["unit"], item["meaning"]
            for field_name, text in (("kind", kind), ("unit", unit)):
                if not isinstance(text, str):
                    raise ValueError(f"{where}: {key} has {field_name} {text!r}, which is not a string")
            if kind not in kinds:
                raise ValueError(f"{where}: {key} has kind {kind!r}; allowed: {', '.join(kinds)}")
            if not isinstance(meaning, str) or not meaning.strip():
                raise ValueError(f"{where}: {key} needs a non-empty meaning")
            if unit not in units:
                raise ValueError(f"{where}: {key} has unit {unit!r}; allowed: {', '.join(units)}")
            if kind == "per_sample_std":
                if units[unit] is not None:
                    raise ValueError(f"{where}: {key} is a per-sample std, so its unit must be the "
                                     f"reading's unit ({[u for u, f in units.items() if f is None][0]}), "
                                     f"got {unit!r}")
                si = value / math.sqrt(rate)
            else:
                if units[unit] is None:
                    raise ValueError(f"{where}: {key} is a {kind} but {unit!r} is a per-sample unit; "
                                     f"use kind per_sample_std or a /sqrt(Hz) unit")
                si = value * units[unit]
            settings[key] = NoiseSetting(value, unit, kind, meaning.strip(), si)
    return EskfConfig(name, bias_model, exact_reset, rate, settings)


def load_config(source="kitti_lidar") -> EskfConfig:
    """Load and validate a configuration.

    Parameters
    ----------
    source : str or path-like or dict
        A shipped configuration's name (``"kitti_lidar"``, ``"kitti_gnss"``), a path to a
        YAML file, or an already parsed mapping.

    Raises
    ------
    FileNotFoundError
        If there is no such file (the message lists the shipped configurations).
    ValueError
        If ``source`` is not a name, path or mapping; the path is a directory; the file is
        not UTF-8 text or not valid YAML; or the configuration does not validate
        (:func:`config_from_dict`). The message names the file.
    """
    if isinstance(source, dict):
        return config_from_dict(source)
    if not isinstance(source, (str, os.PathLike)) or not str(os.fspath(source)):
        raise ValueError(f"source must be a configuration name, a path to a YAML file or a mapping, "
                         f"got {type(source).__name__}: {source!r:.60}")
    path = Path(source)
    if not path.suffix and not path.exists():
        path = config_dir() / f"{source}.yaml"
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not a configuration file (.yaml)")
    if not path.is_file():
        shipped = ", ".join(sorted(p.stem for p in config_dir().glob("*.yaml")))
        raise FileNotFoundError(f"{path}: no such configuration file (shipped: {shipped})")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file (byte {exc.start} cannot be decoded): "
                         f"is it a configuration file?") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from None
    return config_from_dict(data, name=path.stem)
