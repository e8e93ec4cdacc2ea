"""The actuator's numeric parameters, declared once, and the loop parameters of a batch of runs.

:data:`PARAMETERS` is the one table of every numeric config key: its dotted key in the YAML
(``position_loop.Kp``), the :class:`LoopParameters` field that carries it into the model and the
simulator (``cp_Kp``), the SI unit it is stored in (as pint spells it), its lower bound and a
one-line meaning. Everything else reads the table:

- the config schema (:mod:`cas_freq.config.schema`) declares each field with
  ``param("position_loop.Kp")``, so its unit and bound exist only here;
- :func:`parse_value` is the one conversion of a config value (a number in SI or a string with
  a unit) to a float in SI with the bound checked, shared by the schema, ``sweep --set`` and
  ``montecarlo --tolerance``; every refusal reads ``position_loop.Kd: must be >= 0 A*s/rad,
  got -0.1 A*s/rad``;
- :class:`LoopParameters` checks its arrays against the same bounds;
- :func:`variant_parameters` builds the parameters of n samples of a config with some keys
  changed per sample (a sweep, a Monte Carlo run), checking every sample against the same
  bounds.

The two derived parameters have one rule each, used by the schema's properties and by
:func:`variant_parameters` alike, on scalars and arrays:

- :func:`filter_time_constant`: the derivative filter ``Tf = Kd / (10 Kp)`` unless ``Tf`` is
  set (0 where ``Kd`` = 0);
- :func:`viscous_friction`: ``mu_v = Km I0 / w0`` from the motor's no-load point
  (:func:`cas_freq.formulas.viscous_friction_from_no_load`, report §6).

In a batch, derived quantities follow the changed ones as they would if each sample were a
config file: ``Tf`` is derived per sample unless the base config sets ``position_loop.Tf`` or
``position_loop.Tf`` is itself varied; ``mu_v`` is derived per sample from the sample's ``Km``,
``no_load.speed`` and ``no_load.current`` when the base config gives the no-load point (a
tolerance on Km moves mu_v with it, as the report's formula does), and stays fixed when the
base config gives ``motor.mu_v`` (e.g. the fitted variant) unless ``motor.mu_v`` is varied.

Drive architectures (docs/config.md): with a ``velocity_loop:`` section (a cascade) the
position controller commands a velocity, so ``position_loop.Kp``, ``Ki`` and ``ff_v`` have
other units; :data:`CASCADE_PARAMETERS` holds their records and :func:`parameter` (hence
:func:`unit_of`, :func:`parse_value`, sweeps, tolerances and free keys given the config) picks
the record of the config's architecture. :data:`CASCADE_REFUSED` and :data:`CASCADE_ONLY` say
which keys each architecture refuses and why; the filters' numbers are the keys
``filters.<i>.<name>`` (:data:`FILTER_PARAMETERS`).

This module sits at the bottom of the package: it imports only :mod:`cas_freq.exceptions`,
:mod:`cas_freq.formulas`, :mod:`cas_freq.parameter_record` (the :class:`Parameter` record) and
:mod:`cas_freq.filters_config` and :mod:`cas_freq.sampling_config`, which import nothing else
from cas_freq but :mod:`cas_freq.units`.
"""

import dataclasses
import math
import re

import numpy as np

from cas_freq.exceptions import ConfigError, ConfigTypeError
from cas_freq.filters_config import FILTER_NUMBERS, FILTER_PARAMETERS, Filter, depth_problem
from cas_freq.formulas import viscous_friction_from_no_load as viscous_friction
from cas_freq.parameter_record import Parameter
from cas_freq.parameter_record import indices as _indices
from cas_freq.parameter_record import table as _table
from cas_freq.sampling_config import DEFAULT_METHOD, check_static

__all__ = [
    "CASCADE_ONLY",
    "CASCADE_PARAMETERS",
    "CASCADE_REFUSED",
    "FILTER_PARAMETERS",
    "LINEAR_ONLY",
    "LINEAR_PARAMETERS",
    "LINEAR_REFUSED",
    "PARAMETERS",
    "STATIC_FIELDS",
    "VARIABLE_KEYS",
    "LoopParameters",
    "Parameter",
    "base_values",
    "check_key",
    "derived_problem",
    "drivetrain_problem",
    "filter_time_constant",
    "effective_ratio",
    "is_cascade",
    "loop_structure",
    "is_linear",
    "loop_values",
    "parameter",
    "parse_value",
    "unit_of",
    "variable_keys",
    "variant_parameters",
    "viscous_friction",
]


#: Longest accepted transport delay of either loop [s].
MAX_DELAY_S = 0.1
#: Lowest accepted forward gear efficiency [-] (the least efficient worm gears are ~0.2).
MIN_EFFICIENCY = 0.01


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
     "load spring K_h at the output: load moment -K_h*delta (> 0 opposes, < 0 aids "
     "deflection), 0 or |K_h| 1e-12..1e9 [N*m/rad]", 1e-12),
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
    # the sampled controllers (cas_freq.sampling_config): static, LoopParameters.sample_rates
    ("sampling.current_loop", None, "Hz", 1.0, False, 1e9,
     "sample rate of the current controller (absent: continuous), 1..1e9 [Hz]"),
    ("sampling.velocity_loop", None, "Hz", 1.0, False, 1e9,
     "sample rate of the velocity controller of a cascade (absent: continuous), 1..1e9 [Hz]"),
    ("sampling.position_loop", None, "Hz", 1.0, False, 1e9,
     "sample rate of the position controller (absent: continuous), 1..1e9 [Hz]"),
    # the sensors (docs/model.md §15, "Disturbance and noise"): read by analyze's noise figure
    ("sensors.counts_per_rev", None, "dimensionless", 1.0, False, 1e12,
     "counts per revolution of the encoder the position loop reads (the motor's, or the "
     "output's with position_loop.feedback: output), default none, 1..1e12 [dimensionless]"),
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
#: Filter-number key -> Filter attribute.
_FILTER_FIELDS = {"frequency": "frequency", "damping": "damping", "width": "width",
                  "depth": "depth_db"}


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
        if index >= len(loop.filters) or name not in _FILTER_FIELDS:
            return None
        return getattr(loop.filters[index], _FILTER_FIELDS[name])
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


@dataclasses.dataclass(frozen=True, eq=False)
class LoopParameters:
    """Parameters of ``n_runs`` actuators, in SI, motor-shaft coordinates (docs/model.md).

    Every attribute is a read-only float array of shape (n_runs,), except
    ``derivative_on_measurement`` (bool array) and the static fields ``cascade``,
    ``feedback_output``, ``filters``, ``sample_rates`` and ``sampling_method``
    (:data:`STATIC_FIELDS`), which are the same for every run of a batch: they choose the loop's
    structure. Each float field carries one key of
    :data:`PARAMETERS` (or of :data:`CASCADE_PARAMETERS`). The keys' accepted ranges are
    checked where a value enters (the config schema, :func:`variant_parameters`), not here: an
    internal scan (the stable range of the hinge stiffness, :mod:`cas_freq.analysis.drivetrain`)
    may go past them, and a user must never see an error about a key they did not set. Here
    every value must be finite (``omega_max`` may be +inf), ``Tf`` > 0 where ``cp_Kd`` > 0,
    ``cp_Kd`` = 0 in a cascade, and the drivetrain fields consistent
    (:func:`drivetrain_problem`).

    Attributes
    ----------
    R, L, Km, Ke, J, mu_v : numpy.ndarray
        Motor: resistance [ohm], inductance [H], torque constant [N*m/A], back-EMF constant
        [V*s/rad], inertia [kg*m^2], viscous friction [N*m*s/rad].
    ratio : numpy.ndarray
        Gear ratio N [-]: motor angle = N * output angle. At a linear output N = 2 pi
        gear.ratio / gear.screw_lead [rad/m] (:func:`effective_ratio`), the output and every
        output quantity are in metres, and the load fields hold the linear load's numbers
        (``J_L`` the mass [kg], ``b_L`` [N*s/m], ``K_h`` [N/m], ``tau_h`` [N], ``K_g`` [N/m],
        ``c_g`` [N*s/m], ``backlash`` [m]): the same equations, n = 1/N [m/rad].
    ci_Kp, ci_Ki, v_max, tau_c : numpy.ndarray
        Current loop: PI gains [V/A], [V/(A*s)], output limit [V], transport delay [s].
    cp_Kp, cp_Ki, cp_Kd, Tf : numpy.ndarray
        Position loop: PID gains [A/rad], [A/(rad*s)], [A*s/rad] and derivative filter time
        constant [s] (0 only where ``cp_Kd`` is 0). In a cascade P or PI gains [1/s], [1/s^2]
        (velocity command per position error), ``cp_Kd`` = ``Tf`` = 0.
    ff_v, ff_a : numpy.ndarray
        Feed-forward of the motor-angle command rate [A*s/rad] into the current command (in a
        cascade [-], into the velocity command) and of its acceleration [A*s^2/rad] into the
        current command (a cascade's ``velocity_loop.ff_a``).
    i_max, tau_p : numpy.ndarray
        Current-command limit [A] (a cascade's ``velocity_loop.i_max``) and position-loop
        transport delay [s].
    derivative_on_measurement : numpy.ndarray of bool
        True where the derivative acts on -theta instead of on the error.
    F_c : numpy.ndarray
        Coulomb friction on the motor shaft [N*m] (nonlinear simulation only).
    eta, eta_b : numpy.ndarray
        Forward and backdrive gear efficiencies [-] (eta_b: nonlinear simulation only).
    K_g, c_g, backlash : numpy.ndarray
        Gear stiffness at the fin [N*m/rad] (0: rigid), the mesh damping in parallel with it
        [N*m*s/rad] and total play at the fin [rad] (nonlinear simulation only).
    J_L, b_L, K_h, tau_h : numpy.ndarray
        Load at the fin: inertia [kg*m^2], damping [N*m*s/rad], hinge stiffness [N*m/rad]
        and constant hinge moment [N*m] (nonlinear simulation only). All the load and
        drivetrain fields default to "absent" (0, efficiencies 1).
    omega_max : numpy.ndarray
        Limit of a cascade's velocity command [rad/s, motor] (+inf: none).
    cv_Kp, cv_Ki, tau_v, tau_vf : numpy.ndarray
        Velocity loop of a cascade: PI gains [A*s/rad], [A/rad], transport delay between the
        velocity controller and the current loop [s], time constant of the first-order
        low-pass on the measured velocity [s] (0: none). All 0 without a velocity loop.
    cascade : bool
        Static: True for a cascade (a velocity loop between the position and current loops).
    feedback_output : bool
        Static: True when the position loop measures the output angle (reflected to the motor,
        N*delta) instead of the motor angle.
    filters : tuple of cas_freq.filters_config.Filter
        Static points and kinds of the loop's filters (their numbers per run), in series in the
        config's order; empty by default.
    sample_rates : tuple of (str, float)
        Static: the sampled loops, innermost first, as (loop name, rate [Hz]) pairs, e.g.
        ``(("current_loop", 25000.0), ("position_loop", 2500.0))``; a loop not named is
        continuous, () (the default) means every controller is continuous. The config's
        ``sampling:`` declaration (:mod:`cas_freq.sampling_config`, whose rules it obeys).
    sampling_method : str
        Static: how the sampled controllers are discretised, ``"backward"`` (default) or
        ``"tustin"`` (``sampling.method``).
    """

    R: np.ndarray
    L: np.ndarray
    Km: np.ndarray
    Ke: np.ndarray
    J: np.ndarray
    mu_v: np.ndarray
    ratio: np.ndarray
    ci_Kp: np.ndarray
    ci_Ki: np.ndarray
    v_max: np.ndarray
    tau_c: np.ndarray
    cp_Kp: np.ndarray
    cp_Ki: np.ndarray
    cp_Kd: np.ndarray
    Tf: np.ndarray
    ff_v: np.ndarray
    ff_a: np.ndarray
    i_max: np.ndarray
    tau_p: np.ndarray
    derivative_on_measurement: np.ndarray
    F_c: np.ndarray = 0.0
    eta: np.ndarray = 1.0
    eta_b: np.ndarray = 1.0
    K_g: np.ndarray = 0.0
    c_g: np.ndarray = 0.0
    backlash: np.ndarray = 0.0
    J_L: np.ndarray = 0.0
    b_L: np.ndarray = 0.0
    K_h: np.ndarray = 0.0
    tau_h: np.ndarray = 0.0
    omega_max: np.ndarray = math.inf
    cv_Kp: np.ndarray = 0.0
    cv_Ki: np.ndarray = 0.0
    tau_v: np.ndarray = 0.0
    tau_vf: np.ndarray = 0.0
    cascade: bool = False
    feedback_output: bool = False
    filters: tuple = ()
    sample_rates: tuple = ()
    sampling_method: str = DEFAULT_METHOD

    def __post_init__(self):
        names = _array_fields(self)
        try:
            arrays = np.broadcast_arrays(*(np.atleast_1d(getattr(self, n)) for n in names))
        except ValueError:
            shapes = {n: np.shape(getattr(self, n)) for n in names}
            raise ConfigError(f"simulation parameters: shapes do not broadcast: {shapes}") from None
        for name, array in zip(names, arrays, strict=True):
            if array.ndim != 1:
                raise ConfigError(f"simulation parameters: {name}: must be 1-D, got {array.shape}")
            dtype = bool if name == "derivative_on_measurement" else float
            array = np.array(array, dtype=dtype)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        for name in names:
            values = getattr(self, name)
            bad = ~np.isfinite(values)
            if name == "omega_max":  # +inf: no limit
                bad &= values != math.inf
            if bad.any():
                raise ConfigError(f"simulation parameters: {name}: must be finite, got "
                                  f"{float(getattr(self, name)[bad][0])} (runs {_indices(bad)})")
        bad = (self.cp_Kd > 0) & ~(self.Tf > 0)
        if bad.any():
            raise ConfigError(
                f"simulation parameters: Tf: must be > 0 s where cp_Kd > 0 (runs {_indices(bad)})"
            )
        problem = drivetrain_problem(self.K_g, self.J_L, self.backlash, self.c_g, where="runs")
        if problem:
            raise ConfigError(f"simulation parameters: {problem}")
        self._check_static()

    def _check_static(self):
        """Check the static fields and broadcast the filters' numbers to n_runs."""
        for name in ("cascade", "feedback_output"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ConfigError(f"simulation parameters: {name}: must be one bool for the "
                                  f"batch (static), got {getattr(self, name)!r}")
            object.__setattr__(self, name, bool(getattr(self, name)))
        bad = self.cp_Kd != 0 if self.cascade else np.zeros(self.n_runs, bool)
        if bad.any():
            raise ConfigError("simulation parameters: cp_Kd: must be 0 in a cascade (the "
                              f"position controller is P or PI) (runs {_indices(bad)})")
        filters = tuple(self.filters)
        if not all(isinstance(f, Filter) for f in filters):
            raise ConfigError("simulation parameters: filters: must be a tuple of Filter")
        if not self.cascade and any(f.at == "velocity_feedback" for f in filters):
            raise ConfigError("simulation parameters: filters: a velocity_feedback filter "
                              "needs a velocity loop (cascade)")
        try:
            filters = tuple(f.broadcast(self.n_runs) for f in filters)
        except ValueError:
            raise ConfigError(f"simulation parameters: filters: the numbers' lengths do not "
                              f"match n_runs = {self.n_runs}") from None
        object.__setattr__(self, "filters", filters)
        object.__setattr__(self, "sample_rates",
                           check_static(self.sample_rates, self.sampling_method, self.cascade))

    @property
    def compliant(self):
        """Bool array: True where the gear has a stiffness (the two-mass model)."""
        return self.K_g > 0

    @property
    def loaded(self):
        """Bool array: True where any load or drivetrain term differs from "absent"."""
        return ((self.F_c != 0) | (self.eta != 1) | (self.eta_b != 1) | (self.K_g != 0)
                | (self.c_g != 0) | (self.backlash != 0) | (self.J_L != 0) | (self.b_L != 0)
                | (self.K_h != 0) | (self.tau_h != 0))

    @property
    def n_runs(self):
        """Number of runs."""
        return self.R.shape[0]

    @classmethod
    def from_configs(cls, configs):
        """One run per validated :class:`cas_freq.config.ActuatorConfig`."""
        configs = list(configs)
        if not configs:
            raise ConfigError("simulation parameters: need at least one config")
        structure = loop_structure(configs[0])
        if any(loop_structure(config) != structure for config in configs[1:]):
            raise ConfigError("simulation parameters: the configs of one batch must share their "
                              "loop structure (velocity loop, position feedback, filters' points "
                              "and types, sampling)")
        rows = [_row(config) for config in configs]
        filters = tuple(Filter.stacked(group)
                        for group in zip(*(_filters(config) for config in configs), strict=True))
        return cls(**{key: np.array([row[key] for row in rows]) for key in rows[0]},
                   cascade=structure[0], feedback_output=structure[1], filters=filters,
                   sample_rates=structure[3], sampling_method=structure[4])

    @classmethod
    def from_config(cls, config):
        """A single run from one validated :class:`cas_freq.config.ActuatorConfig`."""
        return cls.from_configs([config])

    def replace(self, **changes):
        """A copy with some parameters changed; every array is broadcast to a common length
        (the static fields are replaced for the whole batch)."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise ConfigError(f"simulation parameters: unknown names {sorted(unknown)}")
        return dataclasses.replace(self, **changes)

    def without_feedforward(self):
        """A copy with ff_v = ff_a = 0: the loop of docs/model.md's T, whose bandwidth is ω_BW."""
        zero = np.zeros(self.n_runs)
        return self.replace(ff_v=zero, ff_a=zero)

    def take(self, rows):
        """The runs ``rows`` (a slice, or an array of run indices, repeats allowed)."""
        taken = {name: getattr(self, name)[rows] for name in _array_fields(self)}
        return dataclasses.replace(self, **taken,
                                   filters=tuple(f.take(rows) for f in self.filters))

    def run(self, index):
        """The parameters of run ``index`` alone (n_runs = 1)."""
        return self.take(slice(index, index + 1))


#: LoopParameters fields that are the same for the whole batch (not arrays).
STATIC_FIELDS = ("cascade", "feedback_output", "filters", "sample_rates", "sampling_method")


def _array_fields(params):
    """Names of the per-run array fields of LoopParameters ``params``."""
    return [f.name for f in dataclasses.fields(params) if f.name not in STATIC_FIELDS]


#: Values of fields a config's architecture leaves out: no velocity loop, no derivative term.
_ABSENT = {"cv_Kp": 0.0, "cv_Ki": 0.0, "tau_v": 0.0, "tau_vf": 0.0, "omega_max": math.inf,
           "cp_Kd": 0.0, "Tf": 0.0}


def drivetrain_problem(stiffness, load_inertia, backlash, damping=0.0, where="samples",
                       linear=False):
    """What is wrong with a combination of drivetrain values (arrays), or None.

    A compliant gear (``gear.stiffness`` > 0) needs a load inertia (the load side of the
    two-mass model; at a linear output, ``linear``, a moving mass); backlash is a dead zone in
    the gear's spring and the mesh damping acts in parallel with it, so both need a stiffness.
    The message ends with the indices of the bad ``where`` (samples, runs), unless ``where`` is
    None (one config).
    """
    stiffness_unit = "N/m" if linear else "N*m/rad"
    load = "load.mass > 0 kg" if linear else "load.inertia > 0 kg*m^2"
    load_name = load.partition(" ")[0]
    stiffness, load_inertia, backlash, damping = np.broadcast_arrays(
        *(np.atleast_1d(np.asarray(v, dtype=float))
          for v in (stiffness, load_inertia, backlash, damping))
    )
    bad = (damping > 0) & ~(stiffness > 0)
    if bad.any():
        return ("gear.damping: the mesh damping acts in parallel with the gear's spring, so it "
                f"needs gear.stiffness > 0 {stiffness_unit} as well{_which(where, bad)}")
    bad = (stiffness > 0) & ~(load_inertia > 0)
    if bad.any():
        return (f"gear.stiffness: a compliant gear needs {load} (the load side of the two-mass "
                f"model), got {load_name} = 0{_which(where, bad)}")
    bad = (backlash > 0) & ~(stiffness > 0)
    if bad.any():
        return ("gear.backlash: the play is a dead zone in the gear's spring, so it needs "
                f"gear.stiffness > 0 {stiffness_unit} as well{_which(where, bad)}")
    return None


def _which(where, bad):
    """`` (samples [0, 3])`` naming the bad entries, or nothing for one config."""
    return "" if where is None else f" ({where} {_indices(bad)})"


def loop_structure(config):
    """The static fields of a validated config: (cascade, feedback_output, the filters' points
    and types, sample_rates, sampling_method). Runs of one batch share them."""
    return (is_cascade(config), config.position_loop.feedback == "output",
            tuple((item.at, item.type) for item in config.filters),
            config.sampling.sample_rates, config.sampling.method)


def _filters(config, numbers=None):
    """The Filter records of a validated config; ``numbers``: filter keys -> values replacing
    the config's (arrays of a batch)."""
    numbers = numbers or {}
    filters = []
    for i, item in enumerate(config.filters):
        values = {}
        for name in FILTER_NUMBERS[item.type]:
            key = f"filters.{i}.{name}"
            values[_FILTER_FIELDS[name]] = numbers.get(key, getattr(item, name))
        filters.append(Filter(item.at, item.type, **values))
    return tuple(filters)


def _row(config):
    """One run's array fields from a validated config (derived ``mu_v`` and ``Tf`` resolved,
    the fields its architecture leaves out at their :data:`_ABSENT` values)."""
    row = dict(_ABSENT)
    for key in variable_keys(config):
        record = parameter(key, config)
        value = _value_at(config, key)
        if record.field is not None and value is not None:
            row[record.field] = value
    if is_linear(config):
        row["ratio"] = effective_ratio(config.gear.ratio, config.gear.screw_lead)
    row["mu_v"] = config.motor.viscous_friction
    if not is_cascade(config):
        row["Tf"] = config.position_loop.filter_time_constant
    row["derivative_on_measurement"] = config.position_loop.derivative_on == "measurement"
    row["eta_b"] = config.gear.backdrive
    return row


def variant_parameters(params, changes, n=None):
    """Loop parameters of n samples: the base config with some keys changed per sample.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        The validated base config.
    changes : dict of str to array_like
        Dotted key -> values in SI (scalar or shape (n,)): keys of the config's architecture
        (:func:`variable_keys`), its filters' numbers ``filters.<i>.<name>`` included.
    n : int, optional
        Number of samples; default the common length of the changed arrays (1 if none).

    Returns
    -------
    LoopParameters

    Raises
    ------
    ConfigError
        Naming the key, the first bad value and the samples, for a value outside the range
        the config schema accepts, or a combination it rejects; naming the key and why for a
        key the config's architecture does not have (``position_loop.Kd`` with a velocity loop).
    """
    arrays = {}
    for key, values in changes.items():
        check_key(key, params)
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
            parameter(key, params).check(array)
            problem = depth_problem(array) if key.endswith(".depth") else None
            if problem:
                raise ConfigError(f"{key}: {problem}")
            full[key] = array
        elif value is not None:
            full[key] = np.full(n, float(value))
        else:
            full[key] = None
    if full["motor.mu_v"] is None:
        # the no-load speed was checked > 0 above or comes from the validated config
        full["motor.mu_v"] = viscous_friction(
            full["motor.Km"], full["motor.no_load.speed"], full["motor.no_load.current"]
        )
        problem = derived_problem("motor.mu_v", full["motor.mu_v"])
        if problem:
            raise ConfigError(problem)
    if full["gear.backdrive_efficiency"] is None:
        full["gear.backdrive_efficiency"] = full["gear.efficiency"]
    linear = is_linear(params)
    problem = drivetrain_problem(full["gear.stiffness"],
                                 full["load.mass" if linear else "load.inertia"],
                                 full["gear.backlash"], full["gear.damping"], linear=linear)
    if problem:
        raise ConfigError(problem)
    cascade = is_cascade(params)
    if not cascade:
        _derive_filter_time_constant(full)
    _check_some_gain(full, cascade)
    fields = dict(_ABSENT)
    for key in variable_keys(params):
        record = parameter(key, params)
        if record.field is not None and full[key] is not None:
            fields[record.field] = full[key]
    if linear:
        fields["ratio"] = effective_ratio(full["gear.ratio"], full["gear.screw_lead"])
    structure = loop_structure(params)
    return LoopParameters(
        **fields,
        derivative_on_measurement=np.full(n, params.position_loop.derivative_on == "measurement"),
        cascade=cascade, feedback_output=structure[1],
        filters=tuple(f.broadcast(n) for f in _filters(params, full)),
        sample_rates=structure[3], sampling_method=structure[4],
    )


def _derive_filter_time_constant(full):
    """Set ``full["position_loop.Tf"]`` (arrays of a batch) to Kd/(10*Kp) unless set."""
    if full["position_loop.Tf"] is not None:
        return
    kp, kd = full["position_loop.Kp"], full["position_loop.Kd"]
    undefined = (kd > 0) & (kp == 0)
    if undefined.any():
        raise ConfigError(
            "position_loop.Tf: defaults to Kd/(10*Kp), which is undefined with "
            f"position_loop.Kp = 0 and Kd > 0 (samples {_indices(undefined)}): set Tf"
        )
    full["position_loop.Tf"] = filter_time_constant(kp, kd)
    problem = derived_problem("position_loop.Tf", full["position_loop.Tf"])
    if problem:
        raise ConfigError(problem)


def _check_some_gain(full, cascade):
    """Raise ConfigError for samples (arrays of a batch) where a loop has no gain at all."""
    kp, ki = full["position_loop.Kp"], full["position_loop.Ki"]
    kd = 0.0 if cascade else full["position_loop.Kd"]
    none = (kp == 0) & (ki == 0) & (kd == 0)
    if none.any():
        names = "Kp and Ki are both 0" if cascade else "Kp, Ki and Kd are all 0"
        raise ConfigError(
            f"position_loop: {names}: no position loop (samples {_indices(none)})"
        )
    for section in ("current_loop", "velocity_loop") if cascade else ("current_loop",):
        none = (full[f"{section}.Kp"] == 0) & (full[f"{section}.Ki"] == 0)
        if none.any():
            raise ConfigError(f"{section}: Kp and Ki are both 0: no {section.split('_')[0]} "
                              f"loop (samples {_indices(none)})")
