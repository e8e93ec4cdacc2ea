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
  (:func:`cas_freq.core.formulas.viscous_friction_from_no_load`, report §6).

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

The table and the key rules live in :mod:`cas_freq.core.parameter_keys` (re-exported here); this
module holds :class:`LoopParameters` and the batches built from configs. It sits at the bottom
of the package: it imports only :mod:`cas_freq.core.exceptions`,
:mod:`cas_freq.core.formulas`, :mod:`cas_freq.core.parameter_record` (the :class:`Parameter`
record) and
:mod:`cas_freq.core.filters_config` and :mod:`cas_freq.core.sampling_config`, which import nothing
else
from cas_freq but :mod:`cas_freq.core.units`.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import (
    FILTER_NUMBERS,
    FILTER_PARAMETERS,
    VELOCITY_POINTS,
    Filter,
    depth_problem,
    number_field,
)
from cas_freq.core.formulas import viscous_friction_from_no_load as viscous_friction
from cas_freq.core.parameter_keys import (
    CASCADE_ONLY,
    CASCADE_PARAMETERS,
    CASCADE_REFUSED,
    LINEAR_ONLY,
    LINEAR_PARAMETERS,
    LINEAR_REFUSED,
    MAX_DELAY_S,
    MAX_WINDOW,
    MIN_EFFICIENCY,
    PARAMETERS,
    VARIABLE_KEYS,
    _value_at,
    base_values,
    check_key,
    derived_problem,
    effective_ratio,
    filter_time_constant,
    is_cascade,
    is_linear,
    loop_values,
    parameter,
    parse_value,
    unit_of,
    variable_keys,
)
from cas_freq.core.parameter_record import Parameter
from cas_freq.core.parameter_record import indices as _indices
from cas_freq.core.sampling_config import DEFAULT_METHOD, check_static

__all__ = [
    "CASCADE_ONLY",
    "CASCADE_PARAMETERS",
    "CASCADE_REFUSED",
    "FILTER_PARAMETERS",
    "LINEAR_ONLY",
    "LINEAR_PARAMETERS",
    "LINEAR_REFUSED",
    "MAX_DELAY_S",
    "MIN_EFFICIENCY",
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


@dataclasses.dataclass(frozen=True, eq=False)
class LoopParameters:
    """Parameters of ``n_runs`` actuators, in SI, motor-shaft coordinates (docs/model.md).

    Every attribute is a read-only float array of shape (n_runs,), except
    ``derivative_on_measurement`` (bool array) and the static fields ``cascade``,
    ``feedback_output``, ``filters``, ``sample_rates``, ``sampling_method`` and the encoders'
    ``counts_per_rev``, ``output_counts_per_rev`` (:data:`STATIC_FIELDS`), which are the same
    for every run of a batch: they choose the loop's structure and its sensors. Each float
    field carries one key of :data:`PARAMETERS` (or of :data:`CASCADE_PARAMETERS`). The keys'
    accepted ranges are checked where a value enters (the config schema,
    :func:`variant_parameters`), not here: an internal scan (the stable range of the hinge
    stiffness, :mod:`cas_freq.analysis.drivetrain`) may go past them, and a user must never see
    an error about a key they did not set. Here every value must be finite (``omega_max`` may
    be +inf), ``Tf`` > 0 where ``cp_Kd`` > 0, ``cp_Kd`` = 0 in a cascade, and the drivetrain
    fields consistent (:func:`drivetrain_problem`).

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
    filters : tuple of cas_freq.core.filters_config.Filter
        Static points and kinds of the loop's filters (their numbers per run), in series in the
        config's order; empty by default.
    sample_rates : tuple of (str, float)
        Static: the sampled loops, innermost first, as (loop name, rate [Hz]) pairs, e.g.
        ``(("current_loop", 25000.0), ("position_loop", 2500.0))``; a loop not named is
        continuous, () (the default) means every controller is continuous. The config's
        ``sampling:`` declaration (:mod:`cas_freq.core.sampling_config`, whose rules it obeys).
    sampling_method : str
        Static: how the sampled controllers are discretised, ``"backward"`` (default) or
        ``"tustin"`` (``sampling.method``).
    velocity_from_encoder : bool
        Static: a cascade's velocity loop reads the speed estimated from the motor encoder's
        counts (``velocity_loop.feedback: encoder``: their difference over
        ``velocity_window`` periods through the feedback low-pass ``tau_vf``), not the motor's
        speed.
    velocity_window : int
        Static: the velocity-loop periods that estimate differences the counts over
        (``velocity_loop.window``, default 1; above 1 only with ``velocity_from_encoder``).
    derivative_window : int
        Static: the position-loop periods the PID's derivative term differences over, the mean
        of the last m samples of its input (``position_loop.derivative_window``, default 1;
        above 1 only for a PID-on-PI position loop with Kd > 0; a continuous one runs the
        derivative itself, the window's limit).
    counts_per_rev, output_counts_per_rev : float or None
        Static: counts per revolution of the motor's encoder and of the output's
        (``sensors.counts_per_rev``, ``sensors.output_counts_per_rev``); None (the default):
        not quantised. In the simulation every loop that reads an angle reads it quantised to
        its encoder's count (docs/model.md, "Encoder quantisation").
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
    counts_per_rev: float | None = None
    output_counts_per_rev: float | None = None
    velocity_from_encoder: bool = False
    velocity_window: int = 1
    derivative_window: int = 1

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
        points = [f.at for f in filters if f.at in VELOCITY_POINTS]
        if points and not self.cascade:
            raise ConfigError(f"simulation parameters: filters: a {points[0]} filter needs a "
                              "velocity loop (cascade)")
        try:
            filters = tuple(f.broadcast(self.n_runs) for f in filters)
        except ValueError:
            raise ConfigError(f"simulation parameters: filters: the numbers' lengths do not "
                              f"match n_runs = {self.n_runs}") from None
        object.__setattr__(self, "filters", filters)
        object.__setattr__(self, "sample_rates",
                           check_static(self.sample_rates, self.sampling_method, self.cascade))
        encoder = bool(self.velocity_from_encoder)
        object.__setattr__(self, "velocity_from_encoder", encoder)
        if encoder and not (self.cascade and np.all(self.tau_vf > 0)):
            raise ConfigError("simulation parameters: velocity_from_encoder: needs a velocity "
                              "loop (cascade) and tau_vf > 0 in every run (the estimate's "
                              f"low-pass; runs {_indices(~(self.tau_vf > 0))})")
        window = self.velocity_window
        if not (isinstance(window, (int, np.integer)) and 1 <= window <= MAX_WINDOW
                and (encoder or window == 1)):
            raise ConfigError(f"simulation parameters: velocity_window: must be a whole number "
                              f"of periods 1..{MAX_WINDOW} (above 1 only with "
                              f"velocity_from_encoder), got {window!r}")
        object.__setattr__(self, "velocity_window", int(window))
        window = self.derivative_window  # a continuous position loop ignores it (its limit)
        if not (isinstance(window, (int, np.integer)) and 1 <= window <= MAX_WINDOW and (
                window == 1 or (not self.cascade and np.all(self.cp_Kd > 0)))):
            raise ConfigError(f"simulation parameters: derivative_window: must be a whole "
                              f"number of periods 1..{MAX_WINDOW} (above 1 only for a PID-on-PI "
                              f"position loop with cp_Kd > 0 in every run), got {window!r}")
        object.__setattr__(self, "derivative_window", int(window))
        for name in ("counts_per_rev", "output_counts_per_rev"):
            counts = getattr(self, name)
            if counts is not None and not (isinstance(counts, (int, float, np.number))
                                           and math.isfinite(counts) and counts >= 1):
                raise ConfigError(f"simulation parameters: {name}: must be None or a count "
                                  f">= 1 per revolution (static), got {counts!r}")
            object.__setattr__(self, name, None if counts is None else float(counts))

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
                   sample_rates=structure[3], sampling_method=structure[4],
                   counts_per_rev=structure[5], output_counts_per_rev=structure[6],
                   velocity_from_encoder=structure[7], velocity_window=structure[8],
                   derivative_window=structure[9])

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
STATIC_FIELDS = ("cascade", "feedback_output", "filters", "sample_rates", "sampling_method",
                 "counts_per_rev", "output_counts_per_rev", "velocity_from_encoder",
                 "velocity_window", "derivative_window")


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
    and types, sample_rates, sampling_method, the motor's and the output's encoder counts per
    revolution, the velocity loop read from the encoder and over how many periods, the
    derivative's window). Runs of one batch share them."""
    sensors = config.sensors
    velocity = getattr(config, "velocity_loop", None)
    return (is_cascade(config), config.position_loop.feedback == "output",
            tuple((item.at, item.type) for item in config.filters),
            config.sampling.sample_rates, config.sampling.method,
            sensors.counts_per_rev, sensors.output_counts_per_rev,
            velocity is not None and velocity.feedback == "encoder",
            int(velocity.window) if velocity is not None else 1,
            int(getattr(config.position_loop, "derivative_window", None) or 1))


def _filters(config, numbers=None):
    """The Filter records of a validated config; ``numbers``: filter keys -> values replacing
    the config's (arrays of a batch)."""
    numbers = numbers or {}
    filters = []
    for i, item in enumerate(config.filters):
        values = {}
        for name in FILTER_NUMBERS[item.type]:
            key = f"filters.{i}.{name}"
            values[number_field(name)] = numbers.get(key, getattr(item, name))
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
        counts_per_rev=structure[5], output_counts_per_rev=structure[6],
        velocity_from_encoder=structure[7], velocity_window=structure[8],
        derivative_window=structure[9],
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


def current_limit(params):
    """The current-command limit i_max [A] of a validated config: the velocity loop's with
    one, else the position loop's."""
    velocity = getattr(params, "velocity_loop", None)
    return (velocity if velocity is not None else params.position_loop).i_max
