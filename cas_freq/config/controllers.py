"""The controllers' sections of the config: the current loop, the position loop (its
PID-on-PI and cascade forms), the velocity loop, the filters at their points and the
sampling of each loop (docs/config.md); every numeric field stored in SI, as the parameter
table declares it (:func:`cas_freq.config.sections.param`)."""

from typing import Literal

from pydantic import (
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from cas_freq.config.sections import (
    Feedback,
    Section,
    cascade_param,
    field_type,
    param,
    refused,
)
from cas_freq.core.filters_config import (
    DEFAULT_DAMPING,
    FILTER_NUMBERS,
    depth_problem,
    point_problem,
    type_problem,
)
from cas_freq.core.parameters import (
    CASCADE_ONLY,
    CASCADE_REFUSED,
    FILTER_PARAMETERS,
    derived_problem,
    filter_time_constant,
)
from cas_freq.core.sampling_config import (
    DEFAULT_METHOD,
    LOOPS,
    sample_rates,
)


class CurrentLoop(Section):
    """PI current controller (report Table 1) and its transport delay."""

    Kp: param("current_loop.Kp")
    Ki: param("current_loop.Ki")
    v_max: param("current_loop.v_max")
    delay: param("current_loop.delay")

    @model_validator(mode="after")
    def _some_gain(self):
        if self.Kp == 0 and self.Ki == 0:
            raise PydanticCustomError("cas_value", "Kp and Ki are both 0: no current loop")
        return self


class PositionLoop(Section):
    """PID position controller with filtered derivative (report Table 2) and its delay."""

    Kp: param("position_loop.Kp")
    Ki: param("position_loop.Ki")
    Kd: param("position_loop.Kd")
    Tf: param("position_loop.Tf") | None = None
    ff_v: param("position_loop.ff_v") = 0.0
    ff_a: param("position_loop.ff_a") = 0.0
    i_max: param("position_loop.i_max")
    delay: param("position_loop.delay")
    derivative_on: Literal["error", "measurement"] = "error"
    derivative_window: param("position_loop.derivative_window") = 1
    feedback: Feedback = "motor"
    omega_max: refused(CASCADE_ONLY["position_loop.omega_max"]) = None

    @model_validator(mode="after")
    def _filter_defined(self):
        if self.Kd > 0 and self.Tf is None and self.Kp == 0:
            raise PydanticCustomError(
                "cas_value",
                "Tf defaults to Kd/(10*Kp), which is undefined with Kp = 0 and Kd > 0: set Tf",
            )
        if self.Kp == 0 and self.Ki == 0 and self.Kd == 0:
            raise PydanticCustomError("cas_value", "Kp, Ki and Kd are all 0: no position loop")
        if self.derivative_window != 1 and self.Kd == 0:
            raise PydanticCustomError("cas_value", f"derivative_window: "
                                      f"{self.derivative_window:g} periods of a derivative term, "
                                      "but Kd = 0: give Kd > 0, or leave the window at 1")
        problem = derived_problem("position_loop.Tf", self.filter_time_constant)
        if problem:
            raise PydanticCustomError("cas_value", problem)
        return self

    @property
    def filter_time_constant(self):
        """Derivative filter time constant [s]: ``Tf``, or Kd/(10*Kp) (0 when Kd = 0)."""
        return filter_time_constant(self.Kp, self.Kd, self.Tf)


class CascadePositionLoop(Section):
    """P or PI position controller of a cascade: its output is the velocity command
    [rad/s, motor] of the velocity loop (docs/config.md)."""

    Kp: cascade_param("position_loop.Kp")
    Ki: cascade_param("position_loop.Ki") = 0.0
    ff_v: cascade_param("position_loop.ff_v") = 0.0
    omega_max: param("position_loop.omega_max") | None = None
    delay: param("position_loop.delay")
    feedback: Feedback = "motor"
    Kd: refused(CASCADE_REFUSED["position_loop.Kd"]) = None
    Tf: refused(CASCADE_REFUSED["position_loop.Tf"]) = None
    derivative_on: refused(CASCADE_REFUSED["position_loop.derivative_on"]) = None
    derivative_window: refused(CASCADE_REFUSED["position_loop.derivative_window"]) = None
    i_max: refused(CASCADE_REFUSED["position_loop.i_max"]) = None
    ff_a: refused(CASCADE_REFUSED["position_loop.ff_a"]) = None

    @model_validator(mode="after")
    def _some_gain(self):
        if self.Kp == 0 and self.Ki == 0:
            raise PydanticCustomError("cas_value", "Kp and Ki are both 0: no position loop")
        return self

    @property
    def filter_time_constant(self):
        """No derivative term in a cascade: 0 [s]."""
        return 0.0


class VelocityLoop(Section):
    """PI velocity controller of a cascade, between the position and the current loops, with
    its current-command limit, delay, feedback low-pass and acceleration feed-forward.
    ``feedback``: ``speed`` (default) reads the motor's speed; ``encoder`` the speed the drive
    estimates from the motor encoder's counts, their difference over ``window`` velocity-loop
    periods (default 1) through the feedback low-pass (a sampled velocity loop only)."""

    Kp: param("velocity_loop.Kp")
    Ki: param("velocity_loop.Ki")
    i_max: param("velocity_loop.i_max")
    delay: param("velocity_loop.delay") = 0.0
    feedback_filter: param("velocity_loop.feedback_filter") = 0.0
    ff_a: param("velocity_loop.ff_a") = 0.0
    feedback: Literal["speed", "encoder"] = "speed"
    window: param("velocity_loop.window") = 1

    @model_validator(mode="after")
    def _some_gain(self):
        if self.Kp == 0 and self.Ki == 0:
            raise PydanticCustomError("cas_value", "Kp and Ki are both 0: no velocity loop")
        return self

    @model_validator(mode="after")
    def _estimate_filtered(self):
        if self.feedback == "encoder" and not self.feedback_filter > 0:
            raise PydanticCustomError(
                "cas_value", "feedback: encoder (the speed as the drive estimates it from the "
                "motor encoder's counts, docs/model.md §14) needs feedback_filter > 0 s, the "
                "estimate's first-order low-pass, e.g. 0.2 ms")
        if self.window != 1 and self.feedback != "encoder":
            raise PydanticCustomError(
                "cas_value", f"window: {self.window:g} periods is the speed estimate's "
                "(feedback: encoder); feedback: speed reads the speed itself, so window must "
                "stay 1")
        return self


def _filter_field(name):
    """Type of a filter's number ``name`` (:data:`FILTER_PARAMETERS`)."""
    return field_type(FILTER_PARAMETERS[name], f"filters.N.{name}")


class FilterSpec(Section):
    """One filter of ``filters:`` (:mod:`cas_freq.core.filters_config`): its point, its type and its
    numbers (``damping`` of a lowpass2 defaults to 0.7071; a notch needs ``width`` and
    ``depth``).

    Attributes
    ----------
    at : str
        Its point: current_command (after the controller that commands the current),
        velocity_command (after the position controller, before the velocity loop; needs a
        velocity loop), velocity_feedback (on the measured velocity; needs a velocity loop),
        current_feedback (on the measured current) or position_feedback (on the position
        loop's measured angle); the last two are analog: before the sampler of a sampled drive
        (anti-aliasing). position_command: on the command before every loop (a set-point
        filter: T changes, no margin does).
    type : str
        lowpass1, lowpass2, notch or leadlag (``zero`` and ``pole`` [rad/s]).
    """

    at: str
    type: str
    frequency: _filter_field("frequency") | None = None
    damping: _filter_field("damping") | None = None
    width: _filter_field("width") | None = None
    depth: _filter_field("depth") | None = None
    zero: _filter_field("zero") | None = None
    pole: _filter_field("pole") | None = None

    @field_validator("at", "type", "depth")
    @classmethod
    def _checked(cls, value, info):
        """The point, the type and the depth, each by its check of filters_config."""
        check = {"at": point_problem, "type": type_problem, "depth": depth_problem}
        problem = check[info.field_name](value) if value is not None else None
        if problem:
            raise PydanticCustomError("cas_value", problem)
        return value

    @model_validator(mode="before")
    @classmethod
    def _default_damping(cls, data):
        if isinstance(data, dict) and data.get("type") == "lowpass2" and "damping" not in data:
            data = {**data, "damping": DEFAULT_DAMPING}
        return data

    @model_validator(mode="after")
    def _numbers_of_type(self):
        taken = FILTER_NUMBERS[self.type]
        extra = [name for name in FILTER_PARAMETERS
                 if getattr(self, name) is not None and name not in taken]
        if extra:
            raise PydanticCustomError(
                "cas_value", f"a {self.type} filter takes {', '.join(taken)}, not "
                f"{', '.join(extra)}")
        missing = [name for name in taken if getattr(self, name) is None]
        if missing:
            raise PydanticCustomError(
                "cas_value", f"a {self.type} filter needs {' and '.join(missing)}")
        return self


class Sampling(Section):
    """The controllers' sample rates and discretisation (:mod:`cas_freq.core.sampling_config`).

    A rate per loop (``current_loop: 25 kHz``, ``velocity_loop`` with a velocity loop only,
    ``position_loop: 2.5 kHz``); an absent loop is continuous. When any loop is sampled the
    current loop is; an inner loop's rate is an integer multiple of the next outer sampled
    loop's. ``method``: how a sampled controller is discretised, ``backward`` (default) or
    ``tustin``. ``simulation.controllers: sampled`` with its two rates is an older spelling of
    the same declaration (both given: they must agree).

    Attributes
    ----------
    method : str
        How a sampled controller is discretised: ``backward`` (s -> (1 - z^-1)/T) or
        ``tustin`` (s -> (2/T)(z - 1)/(z + 1)).
    """

    current_loop: param("sampling.current_loop") | None = None
    velocity_loop: param("sampling.velocity_loop") | None = None
    position_loop: param("sampling.position_loop") | None = None
    method: Literal["backward", "tustin"] = DEFAULT_METHOD

    @property
    def rates(self):
        """Loop name -> rate [Hz] or None (continuous), innermost first."""
        return {name: getattr(self, name) for name in LOOPS}

    @property
    def sample_rates(self):
        """The sampled loops as (loop name, rate [Hz]) pairs, innermost first; () when every
        controller is continuous (:attr:`cas_freq.core.parameters.LoopParameters.sample_rates`)."""
        return sample_rates(self.rates)
