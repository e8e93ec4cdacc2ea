"""The validated actuator configuration, as frozen pydantic models.

Every numeric field is stored in SI. Its unit, accepted range and meaning are declared once, in
the parameter table :data:`cas_freq.core.parameters.PARAMETERS`; a field here names its dotted key
with :func:`param`, and is converted by :func:`cas_freq.core.parameters.parse_value`'s own path. The
loader turns pydantic's errors into one message per problem that names the dotted key, the
value and what is accepted (see :mod:`cas_freq.config.loader`).

Keys follow docs/model.md and the report's symbols (``Kp``, ``Ki``, ``Kd``, ``Tf``, ``mu_v``, ...).
"""

import re
from typing import Annotated, Any, Literal

from pydantic import (
    Field,
    ValidatorFunctionWrapHandler,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from cas_freq.config.controllers import (
    CascadePositionLoop,
    CurrentLoop,
    FilterSpec,
    PositionLoop,
    Sampling,
    VelocityLoop,
)
from cas_freq.config.descriptions import Simulant, Worm, worm_efficiencies_of
from cas_freq.config.requirement import Requirement
from cas_freq.config.sections import (
    Section,
    field_type,
    linear_param,
    param,
    refused,
)
from cas_freq.config.wording import OUTPUT
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import (
    VELOCITY_POINTS,
)
from cas_freq.core.formulas import second_order_bandwidth
from cas_freq.core.parameter_keys import parse_grid_values
from cas_freq.core.parameters import (
    LINEAR_ONLY,
    LINEAR_REFUSED,
    Parameter,
    derived_problem,
    drivetrain_problem,
    viscous_friction,
)
from cas_freq.core.sampling_config import (
    conflict_problem,
    sampling_problem,
)
from cas_freq.core.tolerances import parse_tolerance

BASE_VARIANT = "base"
#: A variant's name: a plain YAML key that is also safe in a file name (``out.<name>.csv``):
#: a letter or ``_``, then letters, digits, ``_`` or ``-``, at most 64 characters.
VARIANT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,63}")




class NoLoad(Section):
    """Motor no-load point, from which the viscous friction is derived (report §6)."""

    speed: param("motor.no_load.speed")
    current: param("motor.no_load.current")


class Motor(Section):
    """Motor constants (report Table 3), and either ``mu_v`` or ``no_load``."""

    R: param("motor.R")
    L: param("motor.L")
    Km: param("motor.Km")
    Ke: param("motor.Ke")
    J: param("motor.J")
    mu_v: param("motor.mu_v") | None = None
    no_load: NoLoad | None = None
    coulomb_friction: param("motor.coulomb_friction") = 0.0

    @model_validator(mode="after")
    def _one_friction_source(self):
        if (self.mu_v is None) == (self.no_load is None):
            given = "both" if self.mu_v is not None else "neither"
            raise PydanticCustomError(
                "cas_value",
                f"give exactly one of motor.mu_v or motor.no_load.{{speed, current}}, got {given}",
            )
        problem = derived_problem("motor.mu_v", self.viscous_friction)
        if problem:
            raise PydanticCustomError("cas_value", problem)
        return self

    @property
    def viscous_friction(self):
        """Viscous friction [N*m*s/rad]: ``mu_v``, or derived from the no-load point."""
        if self.mu_v is not None:
            return self.mu_v
        return viscous_friction(self.Km, self.no_load.speed, self.no_load.current)


class Gear(Section):
    """Gear between motor and fin: fin angle = motor angle / ratio; rigid unless ``stiffness``
    is given (docs/model.md, "Load and drivetrain"). A ``worm`` (lead angle, friction) gives
    the two efficiencies instead of ``efficiency`` and ``backdrive_efficiency``."""

    ratio: param("gear.ratio")
    efficiency: param("gear.efficiency") = 1.0
    backdrive_efficiency: param("gear.backdrive_efficiency") | None = None
    stiffness: param("gear.stiffness") = 0.0
    damping: param("gear.damping") = 0.0
    backlash: param("gear.backlash") = 0.0
    worm: Worm | None = None

    @model_validator(mode="after")
    def _worm(self):
        return worm_efficiencies_of(self)

    @property
    def backdrive(self):
        """Backdrive efficiency [-]: ``backdrive_efficiency``, else the forward efficiency."""
        if self.backdrive_efficiency is None:
            return self.efficiency
        return self.backdrive_efficiency


class LinearGear(Section):
    """Reduction and screw of a linear output: output x = motor angle * screw_lead / (2 pi
    ratio) [m] (docs/model.md, "Linear output"); stiffness, damping and play are axial, at the
    output."""

    ratio: linear_param("gear.ratio")
    screw_lead: param("gear.screw_lead")
    efficiency: param("gear.efficiency") = 1.0
    backdrive_efficiency: param("gear.backdrive_efficiency") | None = None
    stiffness: linear_param("gear.stiffness") = 0.0
    damping: linear_param("gear.damping") = 0.0
    backlash: linear_param("gear.backlash") = 0.0

    backdrive = Gear.backdrive


class Load(Section):
    """What the fin carries, at the fin (docs/model.md, "Load and drivetrain"); all absent
    (0) by default: the report's unloaded bench. A ``simulant`` gives ``inertia`` from its
    geometry."""

    inertia: param("load.inertia") = 0.0
    simulant: Simulant | None = None
    damping: param("load.damping") = 0.0
    hinge_stiffness: param("load.hinge_stiffness") = 0.0
    hinge_bias: param("load.hinge_bias") = 0.0
    mass: refused(LINEAR_ONLY["load.mass"], quote=True) = None
    stiffness: refused(LINEAR_ONLY["load.stiffness"], quote=True) = None
    bias: refused(LINEAR_ONLY["load.bias"], quote=True) = None

    @model_validator(mode="after")
    def _simulant(self):
        if self.simulant is None:
            return self
        if "inertia" in self.model_fields_set:
            raise PydanticCustomError(
                "cas_value", "simulant: the simulant's geometry gives the load inertia; "
                "remove load.inertia (or load.simulant)")
        object.__setattr__(self, "inertia", self.simulant.inertia)
        return self

    @property
    def rotary_inertia(self):
        """The load's inertia as the model holds it (``J_L``) [kg*m^2]."""
        return self.inertia


class LinearLoad(Section):
    """What a linear output moves, at the output: a mass, a damper, a spring (-K*x) and a
    constant force; all absent (0) by default."""

    mass: param("load.mass") = 0.0
    damping: linear_param("load.damping") = 0.0
    stiffness: param("load.stiffness") = 0.0
    bias: param("load.bias") = 0.0
    inertia: refused(LINEAR_REFUSED["load.inertia"], quote=True) = None
    hinge_stiffness: refused(LINEAR_REFUSED["load.hinge_stiffness"], quote=True) = None
    hinge_bias: refused(LINEAR_REFUSED["load.hinge_bias"], quote=True) = None

    @property
    def rotary_inertia(self):
        """The load as the model holds it (``J_L``, the mass) [kg, i.e. kg*m^2/rad^2 with the
        output in m]."""
        return self.mass


class Sensors(Section):
    """The encoders' resolution (docs/model.md, "Encoder quantisation", and §15,
    "Disturbance and noise").

    ``counts_per_rev``: counts per revolution of the motor's encoder (after its decoding, e.g.
    x4 in quadrature); ``output_counts_per_rev``: of the output's encoder (a rotary output).
    In the simulation every loop that reads an angle reads it quantised to its encoder's
    count; the quantisation noise of the encoder the position loop reads gives analyze's
    ``noise.current_rms_A``. Absent: not quantised, no noise figure.
    """

    counts_per_rev: param("sensors.counts_per_rev") | None = None
    output_counts_per_rev: param("sensors.output_counts_per_rev") | None = None


class Supply(Section):
    """The supply behind the drive, for the rate and torque envelope
    (:mod:`cas_freq.analysis.rate_envelope`): its voltage (default ``current_loop.v_max``)
    and its source resistance (default 0), which the winding current flows through."""

    voltage: param("supply.voltage") | None = None
    resistance: param("supply.resistance") = 0.0


class Simulation(Section):
    """The older spelling of ``sampling:``, for the current and position loops.

    ``controllers: continuous`` (default) declares nothing: the controllers are continuous
    unless ``sampling:`` samples them. ``sampled`` samples both at the given rates with
    zero-order hold (the EPOS4 runs its current loop at 25 kHz and its position loop at
    2.5 kHz), as ``sampling: {current_loop: ..., position_loop: ...}`` does; a
    ``position_loop_rate`` of null leaves the position loop continuous. Once validated, the
    section states what ``sampling:`` declares, so ``rates_hz`` follows it.
    """

    controllers: Literal["continuous", "sampled"] = "continuous"
    current_loop_rate: param("simulation.current_loop_rate") = 25e3
    position_loop_rate: param("simulation.position_loop_rate") | None = 2.5e3

    @property
    def rates(self):
        """The rates this spelling declares: loop name -> rate [Hz] or None (continuous)."""
        if self.controllers == "continuous":
            return {}
        return {"current_loop": self.current_loop_rate, "position_loop": self.position_loop_rate}

    @property
    def rates_hz(self):
        """(current, position) sample rates [Hz], each None for a continuous controller; the
        config's ``sampling:`` once validated (the rates the nonlinear simulation runs)."""
        if self.controllers == "continuous":
            return None, None
        return self.current_loop_rate, self.position_loop_rate


# ---- reference: measured or published results to compare against -------------------------------

#: The numeric keys of the ``reference:`` section (comparison data, never model parameters), in
#: the form of :data:`cas_freq.core.parameters.PARAMETERS` so that they are converted and bounded by
#: the same :meth:`~cas_freq.core.parameters.Parameter.convert`.
REFERENCE_PARAMETERS = {
    p.key: p for p in (
        Parameter("reference.step_amplitude", None, "rad", 0.0, True, 3.1416,
                  "step size at the output of the reference step, (0, 180] [rad]"),
        Parameter("reference.rise_time", None, "s", 0.0, False, 1e3,
                  "reference step's 10-90 % rise time, 0..1e3 [s]"),
        Parameter("reference.overshoot_pct", None, "percent", 0.0, False, 1e3,
                  "reference step's overshoot, 0..1e3 [percent]"),
        Parameter("reference.settling_time", None, "s", 0.0, False, 1e3,
                  "reference step's 2 % settling time, 0..1e3 [s]"),
        Parameter("reference.fit.wn", None, "rad/s", 0.0, True, 1e9,
                  "natural frequency of the reference second-order fit, > 0 [rad/s]"),
        Parameter("reference.fit.zeta", None, "dimensionless", 0.0, False, 1e3,
                  "damping ratio of the reference second-order fit, >= 0 [dimensionless]"),
        Parameter("reference.fit.td", None, "s", 0.0, False, 1e3,
                  "delay of the reference second-order fit, 0..1e3 [s]"),
        Parameter("reference.fit.bandwidth", None, "rad/s", 0.0, True, 1e9,
                  "bandwidth the reference states for its fit (default: the closed form of "
                  "wn and zeta) [rad/s]"),
    )
}


def reference_param(key):
    """Type of a float field of the ``reference:`` section (like :func:`param`)."""
    return field_type(REFERENCE_PARAMETERS[key], key)


class ReferenceFit(Section):
    """A second-order-plus-delay fit of the reference step (ARL-TR-9136 §7 form)."""

    wn: reference_param("reference.fit.wn") | None = None
    zeta: reference_param("reference.fit.zeta") | None = None
    td: reference_param("reference.fit.td") | None = None
    bandwidth: reference_param("reference.fit.bandwidth") | None = None

    @property
    def bandwidth_rad_s(self):
        """The stated bandwidth, else the closed form of (wn, zeta), else None [rad/s]."""
        if self.bandwidth is not None:
            return self.bandwidth
        if self.wn is not None and self.zeta is not None:
            return second_order_bandwidth(self.wn, self.zeta)
        return None


class Reference(Section):
    """Measured or published results to compare the model with (shown by the report only when
    declared; never used by the model). Every figure is optional."""

    source: str = ""
    step_amplitude: reference_param("reference.step_amplitude") | None = None
    rise_time: reference_param("reference.rise_time") | None = None
    overshoot_pct: reference_param("reference.overshoot_pct") | None = None
    settling_time: reference_param("reference.settling_time") | None = None
    fit: ReferenceFit | None = None


class LoadEnvelopeSpec(Section):
    """What the report's load envelope sweeps (:mod:`cas_freq.studies.envelope`).

    ``hinge_stiffness``: the grid of ``load.hinge_stiffness`` at the fin, ``MIN:MAX:N`` (N
    evenly spaced, 2 <= N <= 201) or a list, numbers in N*m/rad or strings with a unit;
    ``variants``: which variants (default every variant); ``step``: the fin step of the step
    figures (default the first step requirement's).
    """

    hinge_stiffness: tuple[float, ...]
    variants: tuple[str, ...] | None = None
    step: float | None = None

    @field_validator("hinge_stiffness", mode="before")
    @classmethod
    def _grid(cls, value):
        text = ",".join(str(v) for v in value) if isinstance(value, (list, tuple)) else value
        try:
            values = parse_grid_values("load.hinge_stiffness", str(text))
        except ConfigError as exc:
            raise PydanticCustomError("cas_value", str(exc).replace("--set ", "")) from None
        if not 2 <= values.size <= 201:
            raise PydanticCustomError(
                "cas_value", f"expected 2 to 201 hinge stiffness values, got {values.size}")
        return tuple(float(v) for v in values)

    _step_angle = field_validator("step", mode="before")(Requirement._angle.__func__)


class ActuatorConfig(Section):
    """A whole actuator: motor, gear, both loops, and the named variants of the file.

    ``output_name`` names what the actuator moves (``fin``) in labels and text; without it they
    say "output". ``control_surface: true`` says the output is a control surface (a fin, a
    rudder): text then speaks of the flight-control system and of the deflection δ
    (:class:`~cas_freq.config.wording.OutputWords`). Data keys (CSV columns, JSON and API
    fields) never depend on either. ``drive`` names the drive the gains are written for
    (``epos4``: ``tune`` also prints them in its units); without it no drive is assumed.
    """

    name: Annotated[str, Field(min_length=1)]
    description: str = ""
    output_name: str | None = None
    control_surface: bool = False
    drive: Literal["epos4"] | None = None
    motor: Motor
    gear: Gear | LinearGear
    load: Load | LinearLoad = Load()
    current_loop: CurrentLoop
    velocity_loop: VelocityLoop | None = None
    position_loop: PositionLoop | CascadePositionLoop
    filters: tuple[FilterSpec, ...] = ()
    sampling: Sampling = Sampling()
    sensors: Sensors = Sensors()
    simulation: Simulation = Simulation()
    supply: Supply = Supply()
    requirements: tuple[Requirement, ...] = ()
    tolerances: dict[str, str | float] = {}
    reference: Reference | None = None
    load_envelope: LoadEnvelopeSpec | None = None
    variants: dict[str, dict[str, Any] | None] = {}

    @classmethod
    def model_validate(cls, obj, **kwargs):
        """Validate ``obj``; a ``velocity_loop`` section makes ``position_loop`` a
        :class:`CascadePositionLoop` (its gains in the cascade's units)."""
        context = dict(kwargs.pop("context", None) or {})
        context.setdefault("cascade", isinstance(obj, dict)
                           and obj.get("velocity_loop") is not None)
        gear = obj.get("gear") if isinstance(obj, dict) else None
        context.setdefault("linear", isinstance(gear, dict)
                           and gear.get("screw_lead") is not None)
        return super().model_validate(obj, context=context, **kwargs)

    @field_validator("gear", mode="wrap")
    @classmethod
    def _gear(cls, value, handler: ValidatorFunctionWrapHandler, info):
        if isinstance(value, (Gear, LinearGear)):
            return value
        return (LinearGear if (info.context or {}).get("linear") else Gear).model_validate(value)

    @field_validator("load", mode="wrap")
    @classmethod
    def _load(cls, value, handler: ValidatorFunctionWrapHandler, info):
        if isinstance(value, (Load, LinearLoad)):
            return value
        return (LinearLoad if (info.context or {}).get("linear") else Load).model_validate(value)

    @model_validator(mode="after")
    def _load_matches_gear(self):
        if isinstance(self.gear, LinearGear) and isinstance(self.load, Load):
            object.__setattr__(self, "load", LinearLoad())  # the default load: absent
        return self

    @model_validator(mode="after")
    def _rotary_sections(self):
        if not self.linear:
            return self
        if self.load_envelope is not None:
            raise PydanticCustomError(
                "cas_value", "load_envelope: the load envelope sweeps a rotary output's "
                "load.hinge_stiffness [N*m/rad]; this version has none for a linear output "
                "(gear.screw_lead): remove the section")
        if self.reference is not None and self.reference.step_amplitude is not None:
            raise PydanticCustomError(
                "cas_value", "reference.step_amplitude: an angle; this version reads no "
                "reference step of a linear output (gear.screw_lead): remove the key")
        if self.sensors.output_counts_per_rev is not None:
            raise PydanticCustomError(
                "cas_value", "sensors.output_counts_per_rev: counts per revolution of a rotary "
                "output's encoder; a linear output's (gear.screw_lead) is not modelled: remove "
                "the key")
        return self

    @property
    def linear(self):
        """True for a linear output (``gear.screw_lead``): lengths at the output."""
        return isinstance(self.gear, LinearGear)

    @field_validator("position_loop", mode="wrap")
    @classmethod
    def _position_loop(cls, value, handler: ValidatorFunctionWrapHandler, info):
        if isinstance(value, (PositionLoop, CascadePositionLoop)):
            return value
        model = CascadePositionLoop if (info.context or {}).get("cascade") else PositionLoop
        return model.model_validate(value)

    @model_validator(mode="after")
    def _one_sampling(self):
        """Reconcile ``sampling:`` and ``simulation.controllers: sampled`` into one declaration,
        check its rules (:func:`cas_freq.core.sampling_config.sampling_problem`), and make both
        sections state it (``simulation.rates_hz`` follows ``sampling:``)."""
        declared, old = self.sampling.rates, self.simulation.rates
        given = any(rate is not None for rate in declared.values())
        if given and old:
            problem = conflict_problem(declared, old)
            if problem:
                raise PydanticCustomError("cas_value", problem)
        rates = declared if given else {**declared, **old}
        problem = sampling_problem(rates, self.velocity_loop is not None)
        if problem:
            raise PydanticCustomError("cas_value", problem)
        object.__setattr__(self, "sampling", self.sampling.model_copy(update=rates))
        if rates.get("current_loop") is not None:
            object.__setattr__(self, "simulation", self.simulation.model_copy(update={
                "controllers": "sampled", "current_loop_rate": rates["current_loop"],
                "position_loop_rate": rates.get("position_loop")}))
        return self

    @model_validator(mode="after")
    def _encoder_velocity_sampled(self):
        velocity = self.velocity_loop
        if velocity is not None and velocity.feedback == "encoder" \
                and self.sampling.rates.get("velocity_loop") is None:
            raise PydanticCustomError(
                "cas_value", "velocity_loop.feedback: encoder estimates the speed from the "
                "counts over one sample period of the velocity loop, so the velocity loop must "
                "be sampled: give sampling.velocity_loop (e.g. 2.5 kHz), or feedback: speed")
        window = getattr(self.position_loop, "derivative_window", None) or 1
        if window != 1 and self.sampling.rates.get("position_loop") is None:
            raise PydanticCustomError(
                "cas_value", f"position_loop.derivative_window: {window:g} periods of the "
                "position loop's samples, so the position loop must be sampled: give "
                "sampling.position_loop (e.g. 2.5 kHz), or leave the window at 1")
        return self

    @model_validator(mode="after")
    def _filter_points(self):
        for index, item in enumerate(self.filters):
            if item.at in VELOCITY_POINTS and self.velocity_loop is None:
                raise PydanticCustomError(
                    "cas_value", f"filters.{index}.at: {item.at} needs a velocity loop "
                    "(a velocity_loop section); use current_command")
        return self

    @field_validator("output_name")
    @classmethod
    def _output_name(cls, value):
        if value is not None and not re.fullmatch(r"[A-Za-z][A-Za-z0-9 _-]{0,39}", value):
            raise PydanticCustomError(
                "cas_value", "expected a name for labels (1 to 40 letters, digits, spaces, '_' "
                "or '-', starting with a letter, e.g. fin), got {value}", {"value": repr(value)})
        return value

    @field_validator("control_surface", mode="before")
    @classmethod
    def _control_surface(cls, value):
        if not isinstance(value, bool):
            raise PydanticCustomError(
                "cas_value", "expected true or false (true: the output is a control surface, "
                "e.g. a fin), got {value}", {"value": repr(value)})
        return value

    @property
    def output_label(self):
        """What labels and text call the output: ``output_name``, else ``"output"``
        (:mod:`cas_freq.config.wording`)."""
        return self.output_name or OUTPUT

    @model_validator(mode="after")
    def _envelope_variants(self):
        names = (BASE_VARIANT, *self.variants)
        envelope = self.load_envelope
        unknown = [n for n in (envelope.variants or ()) if n not in names] if envelope else []
        if unknown:
            raise PydanticCustomError(
                "cas_value", f"load_envelope.variants: unknown variant(s) {', '.join(unknown)}; "
                f"accepted: {', '.join(names)}")
        return self

    @model_validator(mode="after")
    def _drivetrain(self):
        problem = drivetrain_problem(self.gear.stiffness, self.load.rotary_inertia,
                                     self.gear.backlash, self.gear.damping, where=None,
                                     linear=self.linear)
        if problem:
            raise PydanticCustomError("cas_value", problem)
        return self

    @model_validator(mode="after")
    def _tolerances(self):
        for key, value in self.tolerances.items():
            try:
                parse_tolerance(f"{key}={value}", self)
            except ConfigError as exc:
                message = str(exc).replace("--tolerance ", "", 1)
                raise PydanticCustomError("cas_value", f"tolerances: {message}") from None
        return self

    @property
    def tolerance_list(self):
        """The ``tolerances:`` section as :class:`~cas_freq.core.tolerances.Tolerance` records,
        in the file's order (the box the worst case searches, the Monte Carlo's default)."""
        return tuple(parse_tolerance(f"{key}={value}", self)
                     for key, value in self.tolerances.items())

    @model_validator(mode="after")
    def _unique_requirement_ids(self):
        ids = [requirement.id for requirement in self.requirements]
        repeated = sorted({name for name in ids if ids.count(name) > 1})
        if repeated:
            raise PydanticCustomError(
                "cas_value", f"requirements: ids must be unique, repeated: {', '.join(repeated)}"
            )
        return self
