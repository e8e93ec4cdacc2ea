"""One numeric parameter of the actuator config: its key, unit, bounds and meaning.

:class:`Parameter` is the record of every table of numeric keys (:data:`cas_freq.core.parameters.
PARAMETERS`, the cascade's and the filters' records, the reference's): it converts a config value
to SI and checks its bound, with the messages every caller shares. It imports only
:mod:`cas_freq.core.exceptions` and :mod:`cas_freq.core.units`.
"""

import dataclasses
import math
import numbers

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.units import split_quantity, to_si

__all__ = ["Parameter", "indices", "table"]


def _shown(value, unit):
    """A config value as an error message quotes it: strings quoted, numbers with the unit."""
    if isinstance(value, str):
        shown = repr(value)
        return shown if len(shown) <= 60 else shown[:56] + "...'"
    if isinstance(value, np.generic):
        value = value.item()
    shown = repr(value)
    return f"{shown if len(shown) <= 40 else shown[:36] + '...'} {unit}"


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One numeric parameter of the actuator config.

    Attributes
    ----------
    key : str
        Dotted config key (``"position_loop.Kp"``).
    field : str or None
        Field of :class:`LoopParameters` that carries it (``"cp_Kp"``), None for a key the
        loop parameters do not hold (the no-load point, which only derives ``mu_v``; the
        simulation's sample rates).
    unit : str
        SI unit the value is stored in, as pint spells it.
    lower : float or None
        Lower bound in ``unit`` (None: any finite value).
    strict : bool
        True for ``> lower``, False for ``>= lower``.
    upper : float or None
        Upper bound in ``unit`` (None: any finite value).
    meaning : str
        One line saying what it is, ending with the unit in brackets.
    smallest : float or None
        Smallest accepted non-zero magnitude (None: the bounds alone).
    datasheet_unit : str or None
        For a key that datasheets give in another unit than SI (the no-load speed, in rpm):
        that unit. A value must then carry a unit; a bare number, which would be read in
        ``unit``, is refused with the hint ``'8520 rpm'?``.
    hint : str or None
        Appended to the refusal of a value whose unit does not fit (a cascade's position gain
        given in A/rad, the PID-on-PI's unit).
    integer : bool
        True for a count (an encoder's counts per revolution): only whole numbers are accepted.

    Units: the value's unit must have ``unit``'s dimension, an angle counted as a dimension of
    its own (:func:`cas_freq.core.units.angle_problem`): a key whose unit carries ``rad`` (a speed,
    ``Ke``, a gain per radian) accepts rpm, rev/s or deg, never a bare 1/time such as ``Hz``
    or ``min^-1``; a key in ``Hz`` refuses ``rad/s`` and ``rpm``. One rule for every key,
    read from its unit here.
    """

    key: str
    field: str | None
    unit: str
    lower: float | None
    strict: bool
    upper: float | None
    meaning: str
    smallest: float | None = None
    datasheet_unit: str | None = None
    hint: str | None = None
    integer: bool = False

    @property
    def label(self):
        """A short label: :attr:`meaning` up to its first ``, `` or ``: `` outside parentheses
        (``"motor terminal resistance R"``, ``"gear ratio N"``)."""
        depth = 0
        for index, char in enumerate(self.meaning):
            depth += {"(": 1, ")": -1}.get(char, 0)
            if depth == 0 and self.meaning.startswith((", ", ": "), index):
                return self.meaning[:index]
        return self.meaning.rpartition(" [")[0] or self.meaning

    @property
    def rule(self):
        """The accepted range as error messages state it: ``">= 1e-06 and <= 1e+06 ohm"``,
        ``"0 or 1e-09..1e+09 A/rad"``, ``"finite"``."""
        if self.smallest is not None:
            size = "|value| " if self.lower is not None and self.lower < 0 else ""
            return f"0 or {size}within {self.smallest:g}..{self.upper:g} {self.unit}"
        parts = []
        if self.lower is not None:
            parts.append(f"{'>' if self.strict else '>='} {self.lower:g}")
        if self.upper is not None:
            parts.append(f"<= {self.upper:g}")
        if not parts:
            return "finite"
        whole = "a whole number " if self.integer else ""
        return f"{whole}{' and '.join(parts)} {self.unit}"

    def accepts(self, values):
        """Bool (array): finite and within the bounds."""
        values = np.asarray(values, dtype=float)
        good = np.isfinite(values)
        with np.errstate(invalid="ignore"):
            if self.lower is not None:
                good &= values > self.lower if self.strict else values >= self.lower
            if self.upper is not None:
                good &= values <= self.upper
            if self.smallest is not None:
                good &= (values == 0) | (np.abs(values) >= self.smallest)
            if self.integer:
                good &= values == np.round(values)
        return good

    def problem(self, value, given=None):
        """What is wrong with one SI ``value`` (``given``: as written), or None if accepted."""
        if self.accepts(value):
            return None
        shown = _shown(value if given is None else given, self.unit)
        rule = "finite" if not math.isfinite(value) else self.rule
        return f"must be {rule}, got {shown}"

    def convert(self, value):
        """One config value (a number in SI, or a string with a unit) as a float in SI.

        Raises
        ------
        TypeError
            For a value that is neither a number nor a string.
        ValueError
            For a string that does not read as a quantity of this unit's dimension, or a value
            outside the accepted range. The messages do not name the key (see
            :func:`parse_value`).
        """
        self.check_has_unit(value)
        try:
            number = to_si(value, self.unit)
        except (OverflowError, ValueError) as exc:
            if not isinstance(value, str):
                raise ValueError(str(exc)) from None
            text = str(exc)
            if not text.startswith("cannot read"):
                text = f"cannot read {_shown(value, self.unit)} as a value in {self.unit}: {text}"
            hint = f"; {self.hint}" if self.hint else ""
            raise ValueError(f"{text} (accepted: {self.rule}){hint}") from None
        problem = self.problem(number, value)
        if problem:
            raise ValueError(problem)
        return number

    def check_has_unit(self, value):
        """Raise ValueError if this key needs a unit (:attr:`datasheet_unit`) and the config
        value ``value`` (a number, or a string) has none."""
        if self.datasheet_unit is None:
            return
        if isinstance(value, str):
            try:
                number, unit = split_quantity(value)
            except (TypeError, ValueError):
                return  # not a quantity at all: to_si says why
            if unit:
                return
        elif isinstance(value, numbers.Real) and not isinstance(value, bool):
            try:
                number = f"{float(value):g}"
            except OverflowError:
                return  # to_si says why
        else:
            return  # not a number: to_si says why
        raise ValueError(
            f"needs a unit, got {_shown(value, '').strip()}: '{number} {self.datasheet_unit}'? "
            f"(a bare number would be read in {self.unit}; datasheets give it in "
            f"{self.datasheet_unit})"
        )

    def check(self, values, label=None, where="samples"):
        """Raise ConfigError unless every value of the array ``values`` is accepted.

        The message names ``label`` (default the key), the range, the first bad value and the
        indices of up to 10 bad ``where`` (samples, runs).
        """
        values = np.asarray(values, dtype=float)
        bad = ~self.accepts(values)
        if bad.any():
            first = float(values[bad][0])
            raise ConfigError(
                f"{label or self.key}: {self.problem(first)} ({where} {indices(bad)})"
            )


def table(*rows):
    """The table of ``rows``: each the positional fields of a Parameter, optionally followed by
    a dict of its keyword fields (``{"datasheet_unit": "rpm"}``)."""
    table = {}
    for row in rows:
        keywords = row[-1] if isinstance(row[-1], dict) else {}
        table[row[0]] = Parameter(*row[:len(row) - bool(keywords)], **keywords)
    return table


def indices(mask):
    """The first 10 indices where ``mask`` is True (for messages)."""
    return np.flatnonzero(mask)[:10].tolist()
