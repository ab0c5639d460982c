"""Sensing and navigation: what a method knows of the current and of its own position.

Every non-oracle method (the heuristic, BC, the LLM planner's vehicles, a user's policy
through the step API) senses the world through the same models, with the same parameters in
every task and tier (``data/sensors.yaml``; docs/sensing.md): a tier makes the ocean and the
mission harder, never one method's sensors. The oracle is given the truth.

Current. The vehicle carries a forecast of the field (the product's own field through a
forecast-error model drawn once per episode: speed gain, direction error, bias) and measures
the current at its position once per step (ADCP/DVL-class white noise). Its estimate is the
forecast at its position plus a filtered correction: a steady-state Kalman filter on the
forecast error (a random walk), updated with every in-situ sample (:func:`kalman_gain`).

Position. Underwater, dead reckoning from a start fix: per step the error grows by the
DVL-measured ground displacement's heading-bias rotation and scale-factor error (constant per
vehicle and episode) plus white velocity noise; at the surface a GNSS fix replaces it. Depth
(pressure sensor) and altitude (DVL beams) are measured directly.

An *information ablation* gives a non-oracle method one piece of the truth
(:func:`sensing_params` with ``true_current`` or ``true_position``): it shows what drives a
cell. The kernels are in :mod:`oneocean.sensing.kernels`.
"""

from __future__ import annotations

import math
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import NamedTuple


from ..errors import ConfigError
from ..io import read_yaml_mapping

#: Where the sensor table lives (shipped in the wheel).
SENSORS_YAML = Path(str(resources.files("oneocean") / "data" / "sensors.yaml"))

#: Information levels of a method: what it is given instead of its sensors.
#: ``sensors``: the sensor models; ``truth``: the oracle; the three ablations in between
#: (``true_target``: the mission target -- UPL's object, FH's school -- perceived exactly).
INFO_LEVELS = ("sensors", "true_current", "true_position", "true_target", "truth")


class SensingParams(NamedTuple):
    """The sensing and navigation models of one rollout (a kernel argument).

    Built by :func:`sensing_params`; standard deviations are 1 sigma.

    Attributes
    ----------
    true_current : int
        1: the method knows the true current (oracle, ablation).
    true_position : int
        1: the method knows its true position (oracle, ablation).
    true_target : int
        1: the method perceives the mission target exactly (oracle, ablation).
    fc_gain_std : float
        Forecast speed-gain error, relative.
    fc_dir_std : float
        Forecast direction error, rad.
    fc_bias_std : float
        Forecast bias per horizontal component, m s-1.
    meas_std : float
        In-situ current noise per component and sample, m s-1.
    kf_gain : float
        Steady-state Kalman gain of the forecast-error filter.
    start_fix_std : float
        Start fix error per horizontal axis, m.
    heading_bias_std : float
        Dead-reckoning heading bias, rad.
    scale_std : float
        Dead-reckoning velocity scale-factor error, relative.
    vel_noise : float
        DVL velocity noise per axis and step, m s-1.
    gnss_std : float
        GNSS error per horizontal axis, m.
    surface_depth : float
        GNSS is received shallower than this, m.
    fix_every : int
        An acoustic position fix every this many steps (0: none).
    fix_std : float
        Its error per horizontal axis, m.
    fix_gain : float
        Steady-state gain of the navigation filter's fix update.
    fix_seq : int
        1: the aid tracks the team's vehicles in turn (one per ``fix_every`` steps: a vehicle's
        fix every ``n_agents * fix_every`` steps, staggered; opt-in ``navigation.sequential``).
    fix_process_var : float
        The fix filter's process variance per second, m2 s-1 (the sequential gain is computed
        in the kernel from the team size).
    """
    true_current: int        # 1: the method knows the true current (oracle, ablation)
    true_position: int       # 1: the method knows its true position (oracle, ablation)
    true_target: int         # 1: the method perceives the mission target exactly (oracle, ablation)
    fc_gain_std: float       # forecast speed-gain error, relative (1 sigma)
    fc_dir_std: float        # forecast direction error, rad
    fc_bias_std: float       # forecast bias per horizontal component, m s-1
    meas_std: float          # in-situ current noise per component and sample, m s-1
    kf_gain: float           # steady-state Kalman gain of the forecast-error filter
    start_fix_std: float     # start fix error per horizontal axis, m
    heading_bias_std: float  # dead-reckoning heading bias, rad
    scale_std: float         # dead-reckoning velocity scale-factor error, relative
    vel_noise: float         # DVL velocity noise per axis and step, m s-1
    gnss_std: float          # GNSS error per horizontal axis, m
    surface_depth: float     # GNSS is received shallower than this, m
    fix_every: int           # an acoustic position fix every this many steps (0: none)
    fix_std: float           # its error per horizontal axis, m
    fix_gain: float          # steady-state gain of the navigation filter's fix update
    fix_seq: int             # 1: the aid tracks the team's vehicles in turn (one per
                             # fix_every steps: a vehicle's fix every n_agents * fix_every
                             # steps, staggered; opt-in ``navigation.sequential``)
    fix_process_var: float   # the fix filter's process variance per second, m2 s-1 (the
                             # sequential gain is computed in the kernel from the team size)


_KEYS = {
    ("current", "forecast"): ("speed_gain_std", "direction_std_deg", "bias_std_ms",
                              "reference_lead_h", "analysis_fraction"),
    ("current", "in_situ"): ("noise_std_ms",),
    ("current", "filter"): ("process_std_ms",),
    ("navigation",): ("start_fix_std_m", "heading_bias_std_deg", "scale_factor_std",
                      "velocity_noise_ms", "gnss_std_m", "surface_depth_m",
                      "fix_filter_process_std_m"),
}


@lru_cache(maxsize=None)
def _load(path: str) -> dict:
    f = Path(path)
    doc = read_yaml_mapping(f, "sensor table")
    for where, keys in _KEYS.items():
        node = doc
        for part in where:
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, dict):
            raise ConfigError(f"{f}: missing section '{'.'.join(where)}'")
        for key in keys:
            v = node.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise ConfigError(f"{f}: '{'.'.join(where + (key,))}' must be a number >= 0, "
                                  f"got {v!r}")
        extra = sorted(set(node) - set(keys) - ({"aids"} if where == ("navigation",) else set()))
        if extra:
            raise ConfigError(f"{f}: unknown key '{'.'.join(where + (extra[0],))}'")
    perc = doc.get("perception", {})
    if not isinstance(perc, dict):
        raise ConfigError(f"{f}: 'perception' must be a mapping of perception models")
    for name, model in perc.items():
        if not isinstance(model, dict):
            raise ConfigError(f"{f}: 'perception.{name}' must be a mapping of parameters")
        for key, v in model.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise ConfigError(f"{f}: 'perception.{name}.{key}' must be a number >= 0, "
                                  f"got {v!r}")
    aids = doc["navigation"].get("aids", {})
    for name, aid in (aids.items() if isinstance(aids, dict) else [("aids", aids)]):
        v = aid.get("std_m") if isinstance(aid, dict) else None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
            raise ConfigError(f"{f}: 'navigation.aids.{name}.std_m' must be a number >= 0, "
                              f"got {v!r}")
    return doc


def sensor_table(path: str | Path | None = None) -> dict:
    """The validated sensor table.

    Parameters
    ----------
    path : path-like, optional
        Sensor table file; default: :data:`SENSORS_YAML` (``data/sensors.yaml``).

    Returns
    -------
    dict
        The parsed table (cached per path; do not modify).

    Raises
    ------
    ConfigError
        If a section or key is missing, unknown, or not a number >= 0.
    """
    return _load(str(path or SENSORS_YAML))


def perception(name: str, path: str | Path | None = None) -> dict:
    """The parameters of perception model ``name`` (``sensors.yaml`` ``perception.<name>``).

    How every non-oracle method perceives a mission target (the oracle, and the
    ``true_target`` ablation, perceive it exactly: ``SensingParams.true_target``).

    Parameters
    ----------
    name : str
        Perception model name.
    path : path-like, optional
        Sensor table file; default: :data:`SENSORS_YAML`.

    Returns
    -------
    dict
        A copy of the model's parameters.

    Raises
    ------
    ConfigError
        If the table has no such model.
    """
    models = sensor_table(path).get("perception", {})
    if name not in models:
        raise ConfigError(f"{path or SENSORS_YAML}: missing perception model "
                          f"'perception.{name}'")
    return dict(models[name])


def perception_values(model: dict, name: str, keys) -> list[float]:
    """The values of ``keys`` of a perception model, in order.

    Parameters
    ----------
    model : dict
        The model's mapping (:func:`perception`).
    name : str
        The model's name, for error messages.
    keys : iterable of str
        Parameter names.

    Returns
    -------
    list of float
        The values of ``keys``.

    Raises
    ------
    ConfigError
        If a key is missing (one line naming it).
    """
    for key in keys:
        if key not in model:
            raise ConfigError(f"sensors.yaml: missing 'perception.{name}.{key}'")
    return [float(model[key]) for key in keys]


def kalman_gain(process_std: float, meas_std: float, dt: float) -> float:
    """Steady-state gain of a scalar Kalman filter tracking a random walk.

    The prior variance ``M`` solves ``M^2 = q M + q r`` (``q``, ``r`` the step's process and
    measurement variances), gain ``M / (M + r)``.

    Parameters
    ----------
    process_std : float
        Random-walk standard deviation per sqrt(s), in the tracked quantity's unit per
        sqrt(s) (e.g. m s-1 for a current, m for a position, per sqrt(s)).
    meas_std : float
        Standard deviation of the white measurements (same unit as the tracked quantity).
    dt : float
        Time between updates, s.

    Returns
    -------
    float
        The gain, 0..1; 1 when the measurement is exact, 0 without process noise.
    """
    from .kernels import steady_gain

    return steady_gain.py_func(float(process_std) ** 2 * float(dt), float(meas_std) ** 2)


def nav_aid(table: dict, where: str = "task table") -> tuple | None:
    """A task table's acoustic navigation aid.

    Read from the table's optional ``navigation: {aid: <name in sensors.yaml navigation.aids>,
    period_s: <s>}``. With the optional ``sequential: true`` (opt-in; the aid must declare
    ``sequential`` in ``sensors.yaml``) the aid tracks the team's vehicles in turn,
    ``period_s`` being one target's slot of the interrogation sequence.

    Parameters
    ----------
    table : dict
        The task table.
    where : str, default "task table"
        Name of the table, for error messages.

    Returns
    -------
    tuple or None
        ``(aid, period_s)``, or ``(aid, period_s, sequential)`` when ``sequential`` is given
        (``period_s`` in s); None without ``navigation``.

    Raises
    ------
    ConfigError
        If ``navigation`` is malformed, names an unknown aid, has a period <= 0, or asks a
        sequential fix of an aid that cannot track several targets.
    """
    nav = table.get("navigation")
    if nav is None:
        return None
    aids = sensor_table()["navigation"].get("aids", {})
    if (not isinstance(nav, dict) or not {"aid", "period_s"} <= set(nav)
            or not set(nav) <= {"aid", "period_s", "sequential"}):
        raise ConfigError(f"{where}: 'navigation' must be {{aid: NAME, period_s: S}} "
                          f"(optionally sequential: true), got {nav!r}")
    if nav["aid"] not in aids:
        raise ConfigError(f"{where}: navigation.aid {nav['aid']!r} is not a sensor aid; "
                          f"known: {', '.join(sorted(aids))}")
    p = nav["period_s"]
    if isinstance(p, bool) or not isinstance(p, (int, float)) or not p > 0:
        raise ConfigError(f"{where}: navigation.period_s must be a number > 0, got {p!r}")
    if "sequential" not in nav:
        return str(nav["aid"]), float(p)
    seq = nav["sequential"]
    if not isinstance(seq, bool):
        raise ConfigError(f"{where}: navigation.sequential must be true or false, got {seq!r}")
    if seq and not aids[nav["aid"]].get("sequential"):
        raise ConfigError(f"{where}: navigation.sequential: aid {nav['aid']!r} does not track "
                          "several targets in turn (sensors.yaml navigation.aids)")
    return str(nav["aid"]), float(p), seq


def lead_factor(lead_h: float | None, forecast: dict) -> float:
    """Scale of the forecast-error standard deviations at a forecast lead time.

    ``a + (1 - a) * lead_h / reference_lead_h``, ``a`` the analysis fraction.

    Parameters
    ----------
    lead_h : float or None
        Lead time, h; None: the reference lead (factor 1).
    forecast : dict
        The sensor table's ``current.forecast`` section (``analysis_fraction``,
        ``reference_lead_h`` in h).

    Returns
    -------
    float
        The factor, dimensionless.

    Raises
    ------
    ConfigError
        If ``lead_h < 0``.
    """
    if lead_h is None:
        return 1.0
    lead = float(lead_h)
    if not lead >= 0.0:
        raise ConfigError(f"forecast_lead_h must be >= 0, got {lead_h!r}")
    a = float(forecast["analysis_fraction"])
    return a + (1.0 - a) * lead / float(forecast["reference_lead_h"])


def sensing_params(info: str, dt: float, aid: tuple[str, float] | None = None,
                   lead_h: float | None = None,
                   path: str | Path | None = None) -> SensingParams:
    """The :class:`SensingParams` of a method.

    Parameters
    ----------
    info : str
        Information level, one of :data:`INFO_LEVELS`.
    dt : float
        Step, s.
    aid : tuple, optional
        The task's navigation aid (:func:`nav_aid`); None: no acoustic fixes.
    lead_h : float, optional
        The forecast's lead time, h (a tier's ``forecast_lead_h``); None: the reference lead.
    path : path-like, optional
        Sensor table file; default: :data:`SENSORS_YAML`.

    Returns
    -------
    SensingParams
        The rollout's sensing and navigation parameters.

    Raises
    ------
    ConfigError
        If ``info`` is unknown, ``lead_h < 0``, or the sensor table is invalid.
    """
    if info not in INFO_LEVELS:
        raise ConfigError(f"sensing: unknown information level {info!r}; valid: "
                          f"{', '.join(INFO_LEVELS)}")
    t = sensor_table(path)
    nav = t["navigation"]
    fix_every, fix_std, fix_gain, fix_seq = 0, 0.0, 0.0, 0
    if aid is not None:
        fix_every = max(1, int(round(float(aid[1]) / float(dt))))
        fix_std = float(nav["aids"][aid[0]]["std_m"])
        fix_gain = kalman_gain(nav["fix_filter_process_std_m"], fix_std, fix_every * float(dt))
        fix_seq = int(len(aid) > 2 and bool(aid[2]))
    fc, ins, flt = (t["current"][k] for k in ("forecast", "in_situ", "filter"))
    f = lead_factor(lead_h, fc)
    return SensingParams(
        int(info in ("true_current", "truth")), int(info in ("true_position", "truth")),
        int(info in ("true_target", "truth")),
        f * float(fc["speed_gain_std"]), f * math.radians(float(fc["direction_std_deg"])),
        f * float(fc["bias_std_ms"]), float(ins["noise_std_ms"]),
        kalman_gain(flt["process_std_ms"], ins["noise_std_ms"], dt),
        float(nav["start_fix_std_m"]), math.radians(float(nav["heading_bias_std_deg"])),
        float(nav["scale_factor_std"]), float(nav["velocity_noise_ms"]),
        float(nav["gnss_std_m"]), float(nav["surface_depth_m"]), fix_every, fix_std, fix_gain,
        fix_seq, float(nav["fix_filter_process_std_m"]) ** 2)
