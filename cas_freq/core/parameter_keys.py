"""The table of every numeric config key and the rules that read it (the first half of
:mod:`cas_freq.core.parameters`, which re-exports every public name here).

:data:`PARAMETERS` (and :data:`CASCADE_PARAMETERS`, :data:`LINEAR_PARAMETERS` for the other
architectures' units), the keys each architecture refuses, and the functions that resolve a key
for a config (:func:`parameter`, :func:`unit_of`, :func:`check_key`), convert and check a value
(:func:`parse_value`) and derive the two derived parameters (:func:`filter_time_constant`).
Imports nothing from cas_freq but the modules :mod:`cas_freq.core.parameters` names as its own.
"""

import dataclasses
import math
import re

import numpy as np

from cas_freq.core.exceptions import ConfigError, ConfigTypeError
from cas_freq.core.filters_config import (
    FILTER_NUMBERS,
    FILTER_PARAMETERS,
    depth_problem,
    number_field,
)
from cas_freq.core.parameter_record import table as _table

#: Longest accepted transport delay of either loop [s].
MAX_DELAY_S = 0.1
#: Lowest accepted forward gear efficiency [-] (the least efficient worm gears are ~0.2).
MIN_EFFICIENCY = 0.01
#: Most velocity-loop periods a speed estimate from the encoder's counts may span.
MAX_WINDOW = 64


#: Every numeric parameter of the config, by dotted key, in the config's order.
PARAMETERS = _table(
    # key, LoopParameters field, SI unit, lower bound, strict, upper bound, meaning[, smallest
    # accepted non-zero magnitude]. The ranges are physical sanity limits, far outside any servo
    # actuator, that keep the numerics finite; each meaning states its range.
    ("motor.R", "R", "ohm", 1e-6, False, 1e6,
     "motor terminal resistance R, 1e-6..1e6 [ohm]"),
    ("motor.L", "L", "H", 1e-12, False, 1.0, "motor terminal inductance L, 1e-12..1 [H]"),
    ("motor.Km", "Km", "N*m/A", 1e-9, False, 1e3, "motor torque constant Km, 1e-9..1e3 [N*m/A]"),
    ("motor.Ke", "Ke", "V*s/rad", 1e-9, False, 1e3,
     "motor back-EMF constant Ke, 1e-9..1e3 [V*s/rad]"),
    ("motor.J", "J", "kg*m^2", 1e-15, False, 1e3, "rotor inertia J, 1e-15..1e3 [kg*m^2]"),
    ("motor.mu_v", "mu_v", "N*m*s/rad", 0.0, False, 1e3,
     "viscous friction mu_v, 0 or 1e-15..1e3, else derived from motor.no_load as Km*I0/w0 "
     "[N*m*s/rad]", 1e-15),
    ("motor.no_load.speed", None, "rad/s", 1e-3, False, 1e7,
     "motor no-load speed w0, from which mu_v is derived, with a unit (datasheets: rpm), "
     "1e-3..1e7 [rad/s]", None, {"datasheet_unit": "rpm"}),
    ("motor.no_load.current", None, "A", 0.0, False, 1e6,
     "motor no-load current I0, from which mu_v is derived, 0 or 1e-9..1e6 [A]", 1e-9),
    ("gear.ratio", "ratio", "dimensionless", 1e-3, False, 1e6,
     "gear ratio N: motor angle = N * output angle, 1e-3..1e6 [dimensionless]"),
    ("current_loop.Kp", "ci_Kp", "V/A", 0.0, False, 1e9,
     "current-loop proportional gain, 0 or 1e-9..1e9 [V/A]", 1e-9),
    ("current_loop.Ki", "ci_Ki", "V/(A*s)", 0.0, False, 1e9,
     "current-loop integral gain, 0 or 1e-9..1e9 [V/(A*s)]", 1e-9),
    ("current_loop.v_max", "v_max", "V", 1e-6, False, 1e6,
     "current-loop voltage limit +/-v_max, 1e-6..1e6 [V]"),
    ("current_loop.delay", "tau_c", "s", 0.0, False, MAX_DELAY_S,
     f"current-loop transport delay tau_c, 0 or 1e-9..{MAX_DELAY_S:g} [s]", 1e-9),
    ("position_loop.Kp", "cp_Kp", "A/rad", 0.0, False, 1e9,
     "position-loop proportional gain, 0 or 1e-9..1e9 [A/rad]", 1e-9),
    ("position_loop.Ki", "cp_Ki", "A/(rad*s)", 0.0, False, 1e9,
     "position-loop integral gain, 0 or 1e-9..1e9 [A/(rad*s)]", 1e-9),
    ("position_loop.Kd", "cp_Kd", "A*s/rad", 0.0, False, 1e9,
     "position-loop derivative gain (numerator Kd*s), 0 or 1e-9..1e9 [A*s/rad]", 1e-9),
    ("position_loop.Tf", "Tf", "s", 1e-9, False, 1.0,
     "derivative filter time constant Tf, default Kd/(10*Kp), 1e-9..1 [s]"),
    # static (LoopParameters.derivative_window), with a sampled position loop (docs/model.md §14)
    ("position_loop.derivative_window", None, "dimensionless", 1.0, False, MAX_WINDOW,
     "position-loop periods the derivative term's difference spans (the mean of the last m "
     f"samples differenced), a whole number, default 1, 1..{MAX_WINDOW} [dimensionless]", None,
     {"integer": True}),
    ("position_loop.ff_v", "ff_v", "A*s/rad", -1e9, False, 1e9,
     "feed-forward of the motor-angle command rate, 0 or |ff_v| 1e-12..1e9 [A*s/rad]", 1e-12),
    ("position_loop.ff_a", "ff_a", "A*s^2/rad", -1e9, False, 1e9,
     "feed-forward of the motor-angle command acceleration, 0 or |ff_a| 1e-12..1e9 "
     "[A*s^2/rad]", 1e-12),
    ("position_loop.i_max", "i_max", "A", 1e-6, False, 1e6,
     "current-command limit +/-i_max, 1e-6..1e6 [A]"),
    ("position_loop.delay", "tau_p", "s", 0.0, False, MAX_DELAY_S,
     f"position-loop transport delay tau_p, 0 or 1e-9..{MAX_DELAY_S:g} [s]", 1e-9),
    ("motor.coulomb_friction", "F_c", "N*m", 0.0, False, 1e3,
     "Coulomb (dry) friction torque on the motor shaft, nonlinear simulation only, 0 or "
     "1e-12..1e3 [N*m]", 1e-12),
    ("gear.efficiency", "eta", "dimensionless", MIN_EFFICIENCY, False, 1.0,
     f"forward gear efficiency eta (motor drives the output), {MIN_EFFICIENCY:g}..1, default 1: "
     "below 1 % a gear takes 100 times the load's power to drive it, no drive, and the "
     "reflected load 1/eta overflows the plant's arithmetic near 0 [dimensionless]"),
    ("gear.backdrive_efficiency", "eta_b", "dimensionless", 0.0, False, 1.0,
     "backdrive efficiency eta_b (the output drives the motor; 0: self-locking), nonlinear "
     "simulation only, 0..1, default eta [dimensionless]"),
    ("gear.stiffness", "K_g", "N*m/rad", 0.0, False, 1e12,
     "gear torsional stiffness K_g at the output (0: rigid gear), 0 or 1e-6..1e12 [N*m/rad]",
     1e-6),
    ("gear.damping", "c_g", "N*m*s/rad", 0.0, False, 1e6,
     "gear mesh damping c_g at the output, in parallel with the gear's spring (needs "
     "gear.stiffness), 0 or 1e-15..1e6 [N*m*s/rad]", 1e-15),
    ("gear.backlash", "backlash", "rad", 0.0, False, 1.0,
     "total play of the gear at the output, nonlinear simulation only, 0 or 1e-12..1 [rad]",
     1e-12),
    ("load.inertia", "J_L", "kg*m^2", 0.0, False, 1e3,
     "load inertia J_L at the output, 0 or 1e-15..1e3 [kg*m^2]", 1e-15),
    ("load.damping", "b_L", "N*m*s/rad", 0.0, False, 1e6,
     "load viscous damping b_L at the output, 0 or 1e-15..1e6 [N*m*s/rad]", 1e-15),
    ("load.hinge_stiffness", "K_h", "N*m/rad", -1e9, False, 1e9,
     "load spring K_h at the output: load moment -K_h*delta (> 0 opposes the motion, < 0 "
     "aids it), 0 or |K_h| 1e-12..1e9 [N*m/rad]", 1e-12),
    ("load.hinge_bias", "tau_h", "N*m", -1e9, False, 1e9,
     "constant load moment at the output, nonlinear simulation only, 0 or |value| "
     "1e-12..1e9 [N*m]", 1e-12),
    # the velocity loop of a cascade (docs/config.md)
    ("position_loop.omega_max", "omega_max", "rad/s", 0.0, True, 1e9,
     "velocity-command limit +/-omega_max of a velocity loop (motor side), default none, "
     "> 0..1e9 [rad/s]"),
    ("velocity_loop.Kp", "cv_Kp", "A*s/rad", 0.0, False, 1e9,
     "velocity-loop proportional gain, 0 or 1e-9..1e9 [A*s/rad]", 1e-9),
    ("velocity_loop.Ki", "cv_Ki", "A/rad", 0.0, False, 1e9,
     "velocity-loop integral gain, 0 or 1e-9..1e9 [A/rad]", 1e-9),
    ("velocity_loop.i_max", "i_max", "A", 1e-6, False, 1e6,
     "current-command limit +/-i_max of the velocity loop, 1e-6..1e6 [A]"),
    ("velocity_loop.delay", "tau_v", "s", 0.0, False, MAX_DELAY_S,
     f"velocity-loop transport delay tau_v, 0 or 1e-9..{MAX_DELAY_S:g} [s]", 1e-9),
    ("velocity_loop.feedback_filter", "tau_vf", "s", 0.0, False, 1.0,
     "time constant tau_vf of the first-order low-pass on the measured velocity (0: none), 0 "
     "or 1e-9..1 [s]", 1e-9),
    ("velocity_loop.ff_a", "ff_a", "A*s^2/rad", -1e9, False, 1e9,
     "feed-forward of the motor-angle command acceleration into the current command, 0 or "
     "|ff_a| 1e-12..1e9 [A*s^2/rad]", 1e-12),
    # static (LoopParameters.velocity_window), with feedback: encoder (docs/model.md §14)
    ("velocity_loop.window", None, "dimensionless", 1.0, False, MAX_WINDOW,
     "velocity-loop periods the speed estimate of feedback: encoder differences the counts "
     f"over, a whole number, default 1, 1..{MAX_WINDOW} [dimensionless]", None,
     {"integer": True}),
    # a linear output (docs/model.md, "Linear output"): the screw, and the load in kg, N/m, N
    ("gear.screw_lead", None, "m", 1e-6, False, 1.0,
     "lead of the output's screw (travel per screw revolution); makes the output linear, "
     "output x = motor angle * lead / (2*pi*gear.ratio), 1e-6..1 [m]"),
    ("load.mass", "J_L", "kg", 0.0, False, 1e6,
     "moving mass m at a linear output, 0 or 1e-12..1e6 [kg]", 1e-12),
    ("load.stiffness", "K_h", "N/m", -1e12, False, 1e12,
     "load spring K at a linear output: load force -K*x (> 0 opposes, < 0 aids the motion), 0 "
     "or |K| 1e-12..1e12 [N/m]", 1e-12),
    ("load.bias", "tau_h", "N", -1e9, False, 1e9,
     "constant load force at a linear output, nonlinear simulation only, 0 or |value| "
     "1e-12..1e9 [N]", 1e-12),
    ("simulation.current_loop_rate", None, "Hz", 1.0, False, 1e9,
     "current-controller sample rate with controllers: sampled, 1..1e9 [Hz]"),
    ("simulation.position_loop_rate", None, "Hz", 1.0, False, 1e9,
     "position-controller sample rate with controllers: sampled, 1..1e9 [Hz]"),
    # the supply of the rate and torque envelope (cas_freq.analysis.rate_envelope): not loop
    # parameters, read from the config by the envelope alone
    ("supply.voltage", None, "V", 1e-6, False, 1e6,
     "supply voltage of the rate and torque envelope, default current_loop.v_max, 1e-6..1e6 "
     "[V]"),
    ("supply.resistance", None, "ohm", 0.0, False, 1e6,
     "supply's source resistance in series with the winding (the voltage sags by it times "
     "the current), default 0, 0 or 1e-9..1e6 [ohm]", 1e-9),
    # the sampled controllers (cas_freq.core.sampling_config): static, LoopParameters.sample_rates
    ("sampling.current_loop", None, "Hz", 1.0, False, 1e9,
     "sample rate of the current controller (absent: continuous), 1..1e9 [Hz]"),
    ("sampling.velocity_loop", None, "Hz", 1.0, False, 1e9,
     "sample rate of the velocity controller of a cascade (absent: continuous), 1..1e9 [Hz]"),
    ("sampling.position_loop", None, "Hz", 1.0, False, 1e9,
     "sample rate of the position controller (absent: continuous), 1..1e9 [Hz]"),
    # the encoders (docs/model.md, "Encoder quantisation"): static, read by the simulation
    # (LoopParameters.counts_per_rev) and by analyze's noise figure
    ("sensors.counts_per_rev", None, "dimensionless", 1.0, False, 1e12,
     "counts per revolution of the motor's encoder as the drive decodes it (x4 in "
     "quadrature), a whole number, default none (not quantised), 1..1e12 [dimensionless]",
     None, {"integer": True}),
    ("sensors.output_counts_per_rev", None, "dimensionless", 1.0, False, 1e12,
     "counts per revolution of the output's encoder (a rotary output), a whole number, "
     "default none (not quantised), 1..1e12 [dimensionless]", None, {"integer": True}),
)

#: Keys a sweep or a Monte Carlo run can change per sample: every key that reaches the loop
#: parameters (the sample rates are static, the same for a whole batch, not of a sample), and
#: the numbers of the config's filters (``filters.0.frequency``, :func:`variable_keys`).
VARIABLE_KEYS = tuple(key for key in PARAMETERS
                      if not key.startswith(("simulation.", "sampling.", "sensors.", "supply.")))

_CASCADE_HINT = ("with a velocity_loop the position controller's output is a velocity command: "
                 "{key} is in {unit} (e.g. {example})")

#: The keys whose unit and meaning change with a velocity loop (``velocity_loop:`` present):
#: the position controller then commands a velocity, not a current. :func:`parameter` reads
#: these records for a cascade config, :data:`PARAMETERS`' otherwise.
CASCADE_PARAMETERS = _table(
    ("position_loop.Kp", "cp_Kp", "1/s", 0.0, False, 1e9,
     "position-loop proportional gain of a cascade (velocity command per position error), 0 "
     "or 1e-9..1e9 [1/s]", 1e-9,
     {"hint": _CASCADE_HINT.format(key="position_loop.Kp", unit="1/s", example="'30 s^-1'")}),
    ("position_loop.Ki", "cp_Ki", "1/s^2", 0.0, False, 1e9,
     "position-loop integral gain of a cascade, 0 or 1e-9..1e9 [1/s^2]", 1e-9,
     {"hint": _CASCADE_HINT.format(key="position_loop.Ki", unit="1/s^2", example="'5 s^-2'")}),
    ("position_loop.ff_v", "ff_v", "dimensionless", -1e3, False, 1e3,
     "feed-forward of the motor-angle command rate into the velocity command of a cascade, 0 "
     "or |ff_v| 1e-12..1e3 [dimensionless]", 1e-12,
     {"hint": _CASCADE_HINT.format(key="position_loop.ff_v", unit="[-]", example="1")}),
)

#: The keys whose unit and meaning change at a linear output (``gear.screw_lead`` set): the
#: output moves in metres. :func:`parameter` reads these records for a linear config.
LINEAR_PARAMETERS = _table(
    ("gear.ratio", "ratio", "dimensionless", 1e-3, False, 1e6,
     "reduction N before the screw of a linear output: motor angle = N * screw angle, "
     "1e-3..1e6 [dimensionless]"),
    ("load.damping", "b_L", "N*s/m", 0.0, False, 1e9,
     "load viscous damping b_L at a linear output, 0 or 1e-15..1e9 [N*s/m]", 1e-15),
    ("gear.stiffness", "K_g", "N/m", 0.0, False, 1e15,
     "axial stiffness K_g of the screw drive at the output (0: rigid), 0 or 1e-6..1e15 [N/m]",
     1e-6),
    ("gear.damping", "c_g", "N*s/m", 0.0, False, 1e9,
     "damping c_g of the screw drive at the output, in parallel with its spring (needs "
     "gear.stiffness), 0 or 1e-15..1e9 [N*s/m]", 1e-15),
    ("gear.backlash", "backlash", "m", 0.0, False, 0.1,
     "total axial play of the screw drive at the output, nonlinear simulation only, 0 or "
     "1e-12..0.1 [m]", 1e-12),
)

#: Keys of a rotary output that a linear output refuses, and what it takes instead.
LINEAR_REFUSED = {
    "load.inertia": "a linear output (gear.screw_lead) takes load.mass [kg]",
    "load.hinge_stiffness": "a linear output (gear.screw_lead) takes load.stiffness [N/m]",
    "load.hinge_bias": "a linear output (gear.screw_lead) takes load.bias [N]",
}
#: Keys of a linear output that a rotary output refuses, and what it takes instead.
LINEAR_ONLY = {
    "gear.screw_lead": "the config's output is rotary: a screw (a linear output) is declared in "
                       "the config file, not varied",
    "load.mass": "the moving mass of a linear output (gear.screw_lead); a rotary output takes "
                 "load.inertia [kg*m^2]",
    "load.stiffness": "the load spring of a linear output (gear.screw_lead); a rotary output "
                      "takes load.hinge_stiffness [N*m/rad]",
    "load.bias": "the load force of a linear output (gear.screw_lead); a rotary output takes "
                 "load.hinge_bias [N*m]",
}

#: Keys of the PID-on-PI position loop that a cascade refuses, and why.
CASCADE_REFUSED = {
    "position_loop.Kd": "not used with a velocity loop (the position controller is P or PI)",
    "position_loop.Tf": "not used with a velocity loop (the position controller is P or PI)",
    "position_loop.derivative_on": "not used with a velocity loop (the position controller is P "
                                   "or PI)",
    "position_loop.derivative_window": "not used with a velocity loop (the position controller "
                                       "is P or PI)",
    "position_loop.i_max": "not used with a velocity loop: the current command's limit is "
                           "velocity_loop.i_max",
    "position_loop.ff_a": "not used with a velocity loop: the acceleration feed-forward is "
                          "velocity_loop.ff_a",
}
#: Keys that exist only with a velocity loop, and why a config without one refuses them.
CASCADE_ONLY = {
    key: ("clamps the velocity command of a velocity loop, and the config has no velocity_loop "
          "section" if key == "position_loop.omega_max" else
          "the config has no velocity_loop section (a velocity loop is declared by it)")
    for key in PARAMETERS if key.startswith("velocity_loop.") or key == "position_loop.omega_max"
}

_FILTER_KEY = re.compile(r"filters\.(0|[1-9]\d{0,3})\.(\w+)")


def is_cascade(config):
    """True when validated ``config`` (an ActuatorConfig, or None) has a velocity loop."""
    return getattr(config, "velocity_loop", None) is not None


def is_linear(config):
    """True when validated ``config`` (an ActuatorConfig, or None) has a linear output (a
    screw: ``gear.screw_lead``)."""
    return getattr(getattr(config, "gear", None), "screw_lead", None) is not None


def effective_ratio(ratio, screw_lead=None):
    """The model's gear ratio N [rad/rad, or rad/m at a linear output]: motor angle = N *
    output.

    At a linear output x = theta * lead / (2 pi ratio), so N = 2 pi ratio / lead [rad/m] = 1/n;
    every load at the output then reflects as a rotary one does (docs/model.md, "Linear
    output"). Scalars or arrays.
    """
    if screw_lead is None:
        return ratio
    return 2.0 * math.pi * np.asarray(ratio, dtype=float) / screw_lead


def _refused_keys(config):
    """Keys ``config``'s architecture and output refuse, with why (:func:`variable_keys`)."""
    refused = dict(CASCADE_REFUSED if is_cascade(config) else CASCADE_ONLY)
    refused.update(LINEAR_REFUSED if is_linear(config) else LINEAR_ONLY)
    return refused


def parameter(key, config=None):
    """The :class:`Parameter` of dotted ``key`` as ``config``'s architecture reads it.

    Parameters
    ----------
    key : str
        A key of :data:`PARAMETERS`, or a filter's number ``filters.<i>.<name>``.
    config : cas_freq.config.ActuatorConfig, optional
        With a velocity loop, the keys of :data:`CASCADE_PARAMETERS` have the cascade's unit
        and range; without (or None), the PID-on-PI's.

    Raises
    ------
    ConfigError
        For an unknown key.
    """
    if is_cascade(config) and key in CASCADE_PARAMETERS:
        return CASCADE_PARAMETERS[key]
    if is_linear(config) and key in LINEAR_PARAMETERS:
        return LINEAR_PARAMETERS[key]
    if key in PARAMETERS:
        return PARAMETERS[key]
    match = _FILTER_KEY.fullmatch(key)
    if match and match.group(2) in FILTER_PARAMETERS:
        return dataclasses.replace(FILTER_PARAMETERS[match.group(2)], key=key)
    raise ConfigError(f"{key}: not a numeric parameter; known keys: {', '.join(PARAMETERS)}, "
                      f"filters.<i>.{{{', '.join(FILTER_PARAMETERS)}}}")


def _filter_keys(config):
    """The variable keys of ``config``'s filters, ``filters.<i>.<name>``, in order."""
    return tuple(f"filters.{i}.{name}" for i, item in enumerate(getattr(config, "filters", ()))
                 for name in FILTER_NUMBERS[item.type])


def variable_keys(config=None):
    """The keys a sweep can vary in ``config``: those of its architecture among
    :data:`VARIABLE_KEYS`, then its filters' numbers (every VARIABLE_KEYS key without a
    config)."""
    if config is None:
        return VARIABLE_KEYS
    refused = _refused_keys(config)
    return (*(key for key in VARIABLE_KEYS if key not in refused), *_filter_keys(config))


def check_key(key, config=None):
    """Raise ConfigError unless ``key`` is a numeric dotted key that can be varied (in
    ``config``'s architecture and filters, when given)."""
    if key not in VARIABLE_KEYS and not _FILTER_KEY.fullmatch(key):
        static = key in PARAMETERS and key.startswith(("sampling.", "simulation."))
        why = ("a sample rate is static, one for every run of a batch: give one value, or a "
               "variant per rate" if static else "not a numeric loop parameter")
        raise ConfigError(
            f"{key}: cannot be varied ({why}); accepted keys: {', '.join(variable_keys(config))}"
        )
    if config is None:
        if key not in VARIABLE_KEYS:
            parameter(key)  # an unknown filter number
        return
    refused = _refused_keys(config)
    if key in refused:
        raise ConfigError(f"{key}: {refused[key]}")
    match = _FILTER_KEY.fullmatch(key)
    if match and key not in _filter_keys(config):
        index, name = int(match.group(1)), match.group(2)
        filters = getattr(config, "filters", ())
        if index >= len(filters):
            raise ConfigError(f"{key}: the config has {len(filters)} filter(s) "
                              f"(filters.0 to filters.{len(filters) - 1})" if filters else
                              f"{key}: the config has no filters")
        kind = filters[index].type
        raise ConfigError(f"{key}: a {kind} filter has no {name}; it takes "
                          f"{', '.join(FILTER_NUMBERS[kind])}")


def loop_values(loop, key, config=None):
    """The per-run values [SI] of variable ``key`` in LoopParameters ``loop`` (built from
    ``config``): its field, or a filter's number; None for a key no field carries (the no-load
    point)."""
    match = _FILTER_KEY.fullmatch(key)
    if match:
        index, name = int(match.group(1)), match.group(2)
        if index >= len(loop.filters) or name not in FILTER_PARAMETERS:
            return None
        return getattr(loop.filters[index], number_field(name))
    if key == "gear.ratio" and is_linear(config):  # the loop holds N = 2 pi ratio / lead
        return loop.ratio * config.gear.screw_lead / (2.0 * math.pi)
    field = parameter(key, config).field
    return None if field is None else getattr(loop, field)


def unit_of(key, config=None):
    """SI unit [str] in which values of ``key`` are stored (in ``config``'s architecture)."""
    return parameter(key, config).unit


def parse_value(key, value, config=None):
    """One value of ``key`` (a number in SI, or a string with a unit) as a float in SI.

    The one string-to-SI path of the package: the config schema converts every numeric field
    with it too, so the unit, the bound and the message are the same everywhere. ``config``
    selects the unit of a key whose unit depends on the architecture (:func:`parameter`).

    Raises
    ------
    ConfigTypeError
        For a value that is neither a number nor a string.
    ConfigError
        For an unknown key, an unreadable value or one outside the accepted range, e.g.
        ``position_loop.Kd: must be >= 0 A*s/rad, got -0.1 A*s/rad``.
    """
    record = parameter(key, config)
    try:
        number = record.convert(value)
    except TypeError as exc:
        raise ConfigTypeError(f"{key}: {exc}") from None
    except ValueError as exc:
        raise ConfigError(f"{key}: {exc}") from None
    problem = depth_problem(number) if key.endswith(".depth") else None
    if problem:
        raise ConfigError(f"{key}: {problem}")
    return number


#: Largest grid accepted (points).
MAX_POINTS = 1_000_000


def parse_grid_values(key, spec, config=None):
    """Values [SI] of one grid axis: ``start:stop:count`` or ``a,b,c`` (in the unit of
    ``config``'s architecture, :func:`cas_freq.core.parameters.parameter`).

    Raises
    ------
    ConfigError
        For a key that cannot be varied or a spec that does not parse, naming what is accepted.
    """
    check_key(key, config)
    accepted = (f"--set {key}={spec}: expected START:STOP:COUNT (COUNT >= 1 evenly spaced "
                f"values) or a list A,B,C, numbers in {unit_of(key, config)} or with units")
    text = str(spec).strip()
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise ConfigError(accepted)
        start, stop = (parse_value(key, part.strip(), config) for part in parts[:2])
        try:
            count = int(parts[2])
        except ValueError:
            raise ConfigError(accepted) from None
        if count < 1 or not (math.isfinite(start) and math.isfinite(stop)):
            raise ConfigError(accepted)
        if count > MAX_POINTS:
            raise ConfigError(f"--set {key}: {count} values, more than the {MAX_POINTS} points a "
                              "sweep accepts")
        return np.linspace(start, stop, count)
    parts = [part.strip() for part in text.split(",")]
    if not parts or any(not part for part in parts):
        raise ConfigError(accepted)
    if len(parts) > MAX_POINTS:
        raise ConfigError(f"--set {key}: {len(parts)} values, more than the {MAX_POINTS} points "
                          "a sweep accepts")
    return np.array([parse_value(key, part, config) for part in parts])


def is_grid_spec(value):
    """True for a ``--set`` value that is a grid (contains ``:`` or ``,``)."""
    return isinstance(value, str) and (":" in value or "," in value)


def filter_time_constant(kp, kd, tf=None):
    """The derivative filter time constant [s]: ``tf`` if given, else Kd/(10*Kp), 0 where Kd = 0.

    Parameters
    ----------
    kp, kd : float or array_like
        Position-loop proportional [A/rad] and derivative [A*s/rad] gains.
    tf : float or array_like, optional
        The set time constant [s]; returned unchanged.

    Returns
    -------
    float or numpy.ndarray
        A float for scalar gains, else an array of their broadcast shape.

    Raises
    ------
    ValueError
        Where Kd > 0 and Kp = 0 (the default is undefined there: set Tf).
    """
    if tf is not None:
        return tf
    kp, kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
    if np.any((kd > 0) & ~(kp > 0)):
        raise ValueError("Tf defaults to Kd/(10*Kp), which is undefined with Kp = 0 and Kd > 0: "
                         "set Tf")
    with np.errstate(divide="ignore", invalid="ignore"):
        result = np.where(kd > 0, kd / (10.0 * np.where(kp > 0, kp, 1.0)), 0.0)
    return float(result) if result.ndim == 0 else result


def derived_problem(key, values):
    """What is wrong with derived values of ``key`` (``position_loop.Tf`` from Kd/(10*Kp),
    ``motor.mu_v`` from the no-load point), or None: they must lie in the key's own range."""
    values = np.atleast_1d(np.asarray(values, dtype=float))
    parameter = PARAMETERS[key]
    if key == "position_loop.Tf":
        # 0 (no filter) where there is no derivative term
        parameter = dataclasses.replace(parameter, lower=0.0, smallest=parameter.lower)
    bad = ~parameter.accepts(values)
    if not bad.any():
        return None
    how = "Kd/(10*Kp)" if key == "position_loop.Tf" else "Km*I0/w0 (motor.no_load)"
    return (f"{key}: derived as {how} = {float(values[bad][0]):g} {parameter.unit}, outside "
            f"{parameter.rule}: set {key} or change the values it is derived from")


def _value_at(config, key):
    """The value of dotted ``key`` in a validated config (None where a section is absent)."""
    node = config
    for part in key.split("."):
        if isinstance(node, (tuple, list)):  # filters.0.frequency
            node = node[int(part)] if part.isdigit() and int(part) < len(node) else None
        else:
            node = getattr(node, part, None) if node is not None else None
    return node


def base_values(params):
    """Every variable key of a validated config, in SI (``Tf``/``mu_v`` None when derived;
    the keys of the other architecture None), then its filters' numbers."""
    return {key: _value_at(params, key) for key in (*VARIABLE_KEYS, *_filter_keys(params))}
