"""The output's kind and unit: an angle (a rotary output, shown in deg) or a length (a linear
output, ``gear.screw_lead``, shown in mm), declared once.

Inside the model and the simulator the output is one variable in SI whatever its kind: rad at
a rotary output, m at a linear one (the gear ratio is then N = 2 pi ratio / lead [rad/m],
:func:`cas_freq.core.parameters.effective_ratio`). The results' typed records keep the names of the
rotary case (``StepFigures.amplitude_deg`` holds ``degrees(x)`` of the output's SI value x);
this module is where a linear output's figures get their own names and unit: every JSON dict
and table of an output quantity goes through :func:`output_json` / :meth:`OutputUnit.show`,
which rename ``..._deg`` to ``..._mm`` (``step.amplitude_mm``) and scale the value, and every
output quantity a user gives (a step, an amplitude, a move) is read by :func:`read_output`,
which refuses an angle at a linear output and a length at a rotary one, saying what to give.

This module imports only :mod:`cas_freq.core.units` (the unit conversion) and, where it converts
arrays, numpy.
"""

import dataclasses
import math
import re

from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.units import has_unit, to_si

__all__ = ["ANGLE", "LENGTH", "OutputUnit", "output_json", "output_unit", "read_output",
           "wrong_kind"]


@dataclasses.dataclass(frozen=True)
class OutputUnit:
    """How one kind of output is measured and shown.

    Attributes
    ----------
    kind : str
        ``"angle"`` or ``"length"``.
    si : str
        SI unit of the output inside the model, as pint spells it (``"rad"``, ``"m"``).
    shown : str
        Unit of printed figures and JSON keys (``"deg"``, ``"mm"``).
    scale : float
        Factor from the SI value to ``shown``.
    example : str
        An example step, as options take it (``"10deg"``, ``"5mm"``).
    largest : float
        Largest accepted |step|, |amplitude| or |move| [SI].
    largest_text : str
        ``largest`` as written in messages (``"90 deg"``).
    spring : str
        The load spring at the output as text names it (``"K_h"``, ``"K"``).
    spring_unit : str
        Its unit (``"N*m/rad"``, ``"N/m"``).
    rate_examples : tuple of str
        Example speed and acceleration limits of a move (``"2000deg/s"``, ``"1e5deg/s^2"``).
    """

    kind: str
    si: str
    shown: str
    scale: float
    example: str
    largest: float
    largest_text: str
    spring: str
    spring_unit: str
    rate_examples: tuple = ()


    @property
    def linear(self):
        """True for a length."""
        return self.kind == "length"

    def key(self, key):
        """A JSON key of an output quantity in this unit: ``amplitude_deg`` -> ``amplitude_mm``,
        ``peak_rate_deg_s`` -> ``peak_rate_mm_s`` (unchanged for an angle)."""
        return re.sub(r"_deg(?=$|_s$|_s2$)", f"_{self.shown}", key)

    def value(self, value_deg):
        """A typed record's ``_deg`` value in :attr:`shown` (unchanged for an angle)."""
        return value_deg if self.kind == "angle" else math.radians(value_deg) * self.scale

    @property
    def quantity(self):
        """What the output's value is called in axis labels: ``"angle"``, ``"position"``."""
        return "angle" if self.kind == "angle" else "position"

    def from_si(self, values):
        """Output values [SI] (an array) in :attr:`shown` (``numpy.degrees`` for an angle)."""
        import numpy as np

        return np.degrees(values) if self.kind == "angle" else np.asarray(values) * self.scale

    @property
    def example_step(self):
        """:attr:`example` in SI [rad or m]: the step a study takes when none is given."""
        return to_si(self.example, self.si)

    def show(self, value_deg):
        """A typed record's ``_deg`` value as text in this unit: ``"10 deg"``, ``"5 mm"``."""
        return f"{self.value(value_deg):g} {self.shown}"

    def symbol(self, value_deg):
        """The same for labels of figures and tables: ``"10°"``, ``"5 mm"``."""
        text = f"{self.value(value_deg):g}"
        return f"{text}°" if self.shown == "deg" else f"{text} {self.shown}"


#: A rotary output: angles in rad, shown in deg.
ANGLE = OutputUnit("angle", "rad", "deg", math.degrees(1.0), "10deg", math.pi / 2, "90 deg",
                   "K_h", "N*m/rad", ("2000deg/s", "1e5deg/s^2"))
#: A linear output: lengths in m, shown in mm.
LENGTH = OutputUnit("length", "m", "mm", 1e3, "5mm", 1.0, "1 m", "K", "N/m",
                    ("100mm/s", "2000mm/s^2"))


def output_unit(config):
    """The :class:`OutputUnit` of a validated config (a linear output has ``gear.screw_lead``)."""
    return LENGTH if getattr(config, "linear", False) else ANGLE


#: JSON keys (their last part) that hold an output quantity in degrees: the conditions of a
#: run (step, amplitude, move) and its output figures (errors, residuals).
OUTPUT_KEYS = re.compile(r"(amplitudes?|distance|peak_rate|velocity|acceleration|deceleration"
                         r"|tracking_error_max|tracking_error_rms|final_error|max_abs_error|rms_error|limit_onset_amplitude"
                         r"|step)_deg(_s|_s2)?$")
#: JSON keys of the load spring at the output (``analyze``'s drivetrain), renamed at a linear
#: output, whose spring is in N/m.
_SPRING_KEYS = {"hinge_stiffness_n_m_rad": "load_stiffness_n_m",
                "stable_hinge_stiffness_n_m_rad": "stable_load_stiffness_n_m"}


def output_json(data, unit, residual_keys=("rms_residual",)):
    """``data`` (a JSON-ready dict or list, nested) with every output quantity in ``unit``.

    For an angle ``data`` is returned unchanged. For a length, each key matching
    :data:`OUTPUT_KEYS` is renamed (``amplitude_deg`` -> ``amplitude_mm``) and its value
    scaled from degrees of the SI value to mm; the fit's residual (``rms_residual``, in the
    SI unit) is given in mm as ``rms_residual_mm``; the load spring's keys name N/m
    (``load_stiffness_n_m``).
    """
    if not unit.linear:
        return data
    if isinstance(data, list):
        return [output_json(item, unit, residual_keys) for item in data]
    if not isinstance(data, dict):
        return data
    out = {}
    for key, value in data.items():
        if OUTPUT_KEYS.search(key) and not isinstance(value, (dict, bool)):
            out[unit.key(key)] = _scaled(value, unit)
        elif key in _SPRING_KEYS:
            out[_SPRING_KEYS[key]] = value
        elif key in residual_keys and isinstance(value, (int, float)):
            out[f"{key}_{unit.shown}"] = value * unit.scale
        else:
            out[key] = output_json(value, unit, residual_keys)
    return out


def _scaled(value, unit):
    """A ``_deg`` value (a number, None or a list of them) in ``unit``."""
    if isinstance(value, (list, tuple)):
        return [_scaled(item, unit) for item in value]
    return None if value is None else unit.value(value)


def wrong_kind(text, unit, option):
    """The refusal of ``text`` when it is an output quantity of the other kind (a length at a
    rotary output, an angle at a linear one), else None: ``--step: 10 deg is an angle; this
    actuator's output is linear: give a length, e.g. 5mm``."""
    other = LENGTH if unit is ANGLE else ANGLE
    try:
        to_si(text, other.si)
        if not has_unit(text):
            return None
    except (ValueError, TypeError):
        return None
    given = "a length" if unit is ANGLE else "an angle"
    wanted = "an angle" if unit is ANGLE else "a length"
    actuator = "linear" if unit.linear else "rotary"
    head = f"{option}: " if option else ""
    return (f"{head}{text} is {given}; this actuator's output is {actuator}: give {wanted}, "
            f"e.g. {unit.example}")


def read_output(text, unit, option, nonzero=True):
    """An output quantity given with a unit (``"5mm"``, ``"10deg"``) in SI [rad or m].

    Parameters
    ----------
    text : str
        The value with its unit.
    unit : OutputUnit
        The output's kind: an angle is refused at a linear output and a length at a rotary one,
        naming what to give (:func:`wrong_kind`).
    option : str
        The option or key named in messages (``"--step"``).
    nonzero : bool
        Refuse 0 (a step, a move).

    Raises
    ------
    ValueError
        One line naming ``option``, the value and what is accepted.
    """
    what = "an angle" if unit is ANGLE else "a length"
    try:
        value = to_si(text, unit.si)
        if not has_unit(text):
            raise ValueError("it has no unit")
    except (ValueError, TypeError) as exc:
        wrong = wrong_kind(text, unit, option)
        if wrong:
            raise ValueError(wrong) from None
        raise ValueError(f"{option}: expected {what} with a unit such as {unit.example}, got "
                         f"{text!r} ({exc})") from None
    if (nonzero and not value != 0) or abs(value) > unit.largest:
        raise ValueError(f"{option}: must be {'non-zero and ' if nonzero else ''}within "
                         f"±{unit.largest_text} at the output, got {text!r}")
    return value


def angle(text, option):
    """An angle with a unit ('10deg', '0.1 rad') in radians, non-zero and within ±90 deg."""
    try:
        value = to_si(text, "rad")  # raises ValueError for text that is not a number and a unit
        if not has_unit(text):
            raise ValueError("it has no unit")
    except (ValueError, TypeError) as exc:
        raise CasFreqError(f"{option}: expected an angle with a unit such as 10deg, got "
                           f"{text!r} ({exc})") from None
    if not value != 0 or abs(value) > math.pi / 2:
        raise CasFreqError(
            f"{option}: must be non-zero and within ±90 deg at the output, got {text!r}"
        )
    return value


def output_step(text, option, variants):
    """A step (or move) at the output with a unit, in SI: an angle [rad] within ±90 deg at a
    rotary output ('10deg'), a length [m] within ±1 m at a linear one ('5mm'); the other kind
    is refused naming what to give (:func:`cas_freq.core.output.read_output`)."""
    units = {output_unit(loaded.params) for loaded in variants}
    if len(units) > 1:
        raise CasFreqError(f"{option}: the selected variants mix rotary and linear outputs; "
                           "select one kind with --variant")
    try:
        return read_output(text, units.pop(), option)
    except ValueError as exc:
        raise CasFreqError(str(exc)) from None
