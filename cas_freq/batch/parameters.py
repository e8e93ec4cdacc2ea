"""Arrays of loop parameters from a base config and per-sample changes of dotted config keys.

A sweep or a Monte Carlo run changes a few dotted config keys (``position_loop.Kp``,
``motor.Km``, ``current_loop.delay``, ...) across many samples; everything else stays at the
base config's value. :func:`variant_parameters` turns the base and the changed arrays into one
:class:`~cas_freq.simulation.parameters.LoopParameters` (n samples), validating every sample
like the config schema does (the error names the key, the value and the sample).

Derived quantities follow the changed ones, as they would if each sample were a config file:

- the derivative filter constant ``Tf`` is ``Kd / (10 Kp)`` per sample unless the base config
  sets ``position_loop.Tf`` or ``position_loop.Tf`` is itself varied;
- the viscous friction ``mu_v``: when the base config gives the no-load point
  (``motor.no_load``), ``mu_v = Km I0 / n0`` is derived per sample from the sample's ``Km``,
  ``no_load.speed`` and ``no_load.current`` (a tolerance on Km moves mu_v with it, as the
  report's formula does); when the base config gives ``motor.mu_v`` (e.g. the fitted variant)
  it stays fixed unless ``motor.mu_v`` is varied.
"""

import numpy as np

from cas_freq.config.units import to_si
from cas_freq.exceptions import ConfigError
from cas_freq.simulation.parameters import LoopParameters

#: Dotted config key -> (SI unit, lower bound, strict bound) as in the config schema.
KEYS = {
    "motor.R": ("ohm", 0.0, True),
    "motor.L": ("H", 0.0, True),
    "motor.Km": ("N*m/A", 0.0, True),
    "motor.Ke": ("V*s/rad", 0.0, True),
    "motor.J": ("kg*m^2", 0.0, True),
    "motor.mu_v": ("N*m*s/rad", 0.0, False),
    "motor.no_load.speed": ("rad/s", 0.0, True),
    "motor.no_load.current": ("A", 0.0, False),
    "gear.ratio": ("dimensionless", 0.0, True),
    "current_loop.Kp": ("V/A", 0.0, False),
    "current_loop.Ki": ("V/(A*s)", 0.0, False),
    "current_loop.v_max": ("V", 0.0, True),
    "current_loop.delay": ("s", 0.0, False),
    "position_loop.Kp": ("A/rad", 0.0, False),
    "position_loop.Ki": ("A/(rad*s)", 0.0, False),
    "position_loop.Kd": ("A*s/rad", 0.0, False),
    "position_loop.Tf": ("s", 0.0, True),
    "position_loop.ff_v": ("A*s/rad", None, False),
    "position_loop.ff_a": ("A*s^2/rad", None, False),
    "position_loop.i_max": ("A", 0.0, True),
    "position_loop.delay": ("s", 0.0, False),
}

#: Dotted key -> field of LoopParameters (keys that map one to one).
FIELDS = {
    "motor.R": "R", "motor.L": "L", "motor.Km": "Km", "motor.Ke": "Ke", "motor.J": "J",
    "gear.ratio": "ratio", "current_loop.Kp": "ci_Kp", "current_loop.Ki": "ci_Ki",
    "current_loop.v_max": "v_max", "current_loop.delay": "tau_c",
    "position_loop.Kp": "cp_Kp", "position_loop.Ki": "cp_Ki", "position_loop.Kd": "cp_Kd",
    "position_loop.ff_v": "ff_v", "position_loop.ff_a": "ff_a",
    "position_loop.i_max": "i_max", "position_loop.delay": "tau_p",
}


def check_key(key):
    """Raise ConfigError unless ``key`` is a numeric dotted key that can be varied."""
    if key not in KEYS:
        raise ConfigError(
            f"{key}: cannot be varied (not a numeric loop parameter); accepted keys: "
            f"{', '.join(KEYS)}"
        )


def unit_of(key):
    """SI unit [str] in which values of ``key`` are stored."""
    check_key(key)
    return KEYS[key][0]


def parse_value(key, text):
    """One value of ``key`` (a number in SI, or a string with a unit) as a float in SI."""
    unit = unit_of(key)
    try:
        return to_si(text, unit)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{key}: cannot read {text!r} as a value in {unit} ({exc})") from None


def base_values(params):
    """Every variable key of a validated config, in SI (``Tf``/``mu_v`` None when derived)."""
    motor, current, position = params.motor, params.current_loop, params.position_loop
    values = {
        "motor.R": motor.R, "motor.L": motor.L, "motor.Km": motor.Km, "motor.Ke": motor.Ke,
        "motor.J": motor.J, "motor.mu_v": motor.mu_v,
        "motor.no_load.speed": motor.no_load.speed if motor.no_load else None,
        "motor.no_load.current": motor.no_load.current if motor.no_load else None,
        "gear.ratio": params.gear.ratio,
        "current_loop.Kp": current.Kp, "current_loop.Ki": current.Ki,
        "current_loop.v_max": current.v_max, "current_loop.delay": current.delay,
        "position_loop.Kp": position.Kp, "position_loop.Ki": position.Ki,
        "position_loop.Kd": position.Kd, "position_loop.Tf": position.Tf,
        "position_loop.ff_v": position.ff_v, "position_loop.ff_a": position.ff_a,
        "position_loop.i_max": position.i_max, "position_loop.delay": position.delay,
    }
    return values


def _where(mask):
    return np.flatnonzero(mask)[:10].tolist()


def _check_bounds(key, values):
    unit, bound, strict = KEYS[key]
    bad = ~np.isfinite(values)
    if bound is not None:
        bad |= ~(values > bound) if strict else ~(values >= bound)
    if bad.any():
        rule = "finite" if bound is None else f"{'>' if strict else '>='} {bound:g}"
        first = float(values[bad][0])
        raise ConfigError(
            f"{key}: must be {rule} {unit}, got {first!r} {unit} (samples {_where(bad)})"
        )


def variant_parameters(params, changes, n=None):
    """Loop parameters of n samples: the base config with some keys changed per sample.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        The validated base config.
    changes : dict of str to array_like
        Dotted key -> values in SI (scalar or shape (n,)).
    n : int, optional
        Number of samples; default the common length of the changed arrays (1 if none).

    Returns
    -------
    LoopParameters

    Raises
    ------
    ConfigError
        Naming the key, the first bad value and the samples, for a value outside the range
        the config schema accepts, or a combination it rejects.
    """
    arrays = {}
    for key, values in changes.items():
        check_key(key)
        arrays[key] = np.atleast_1d(np.asarray(values, dtype=float))
    lengths = {a.shape[0] for a in arrays.values() if a.shape[0] != 1}
    if n is None:
        n = lengths.pop() if len(lengths) == 1 else (1 if not lengths else None)
        if n is None:
            shapes = {key: value.shape for key, value in arrays.items()}
            raise ConfigError(f"changed keys have different lengths: {shapes}")
    base = base_values(params)
    if base["motor.mu_v"] is not None and any(k.startswith("motor.no_load.") for k in arrays):
        raise ConfigError("motor.no_load: the config gives motor.mu_v directly; vary motor.mu_v")
    full = {}
    for key, value in base.items():
        if key in arrays:
            array = np.broadcast_to(arrays[key], (n,)).astype(float)
            _check_bounds(key, array)
            full[key] = array
        elif value is not None:
            full[key] = np.full(n, float(value))
        else:
            full[key] = None
    if full["motor.mu_v"] is None:
        # mu_v = Km I0 / w0 (cas_freq.formulas.viscous_friction_from_no_load), per sample;
        # no_load.speed was checked > 0 above or comes from the validated config.
        full["motor.mu_v"] = (
            full["motor.Km"] * full["motor.no_load.current"] / full["motor.no_load.speed"]
        )
    kp, ki, kd = full["position_loop.Kp"], full["position_loop.Ki"], full["position_loop.Kd"]
    if full["position_loop.Tf"] is None:
        undefined = (kd > 0) & (kp == 0)
        if undefined.any():
            raise ConfigError(
                "position_loop.Tf: defaults to Kd/(10*Kp), which is undefined with "
                f"position_loop.Kp = 0 and Kd > 0 (samples {_where(undefined)}): set Tf"
            )
        with np.errstate(divide="ignore", invalid="ignore"):
            full["position_loop.Tf"] = np.where(kd > 0, kd / (10.0 * np.where(kp > 0, kp, 1.0)),
                                                0.0)
    none = (kp == 0) & (ki == 0) & (kd == 0)
    if none.any():
        raise ConfigError(
            f"position_loop: Kp, Ki and Kd are all 0: no position loop (samples {_where(none)})"
        )
    none = (full["current_loop.Kp"] == 0) & (full["current_loop.Ki"] == 0)
    if none.any():
        raise ConfigError(
            f"current_loop: Kp and Ki are both 0: no current loop (samples {_where(none)})"
        )
    fields = {field: full[key] for key, field in FIELDS.items()}
    return LoopParameters(
        **fields, mu_v=full["motor.mu_v"], Tf=full["position_loop.Tf"],
        derivative_on_measurement=np.full(n, params.position_loop.derivative_on == "measurement"),
    )
