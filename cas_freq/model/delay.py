"""Transport delays: exact, or Padé approximants that stay well conditioned at any order.

The frequency response of a delay is exact (``exp(-s*tau)``) or Padé. The Padé approximant of
order n is evaluated in the normalised variable ``x = s*tau``, where its coefficients are
moderate, and realised as a state-space cascade of first- and second-order all-pass sections.
Multiplying out the transfer function instead overflows: at n = 8 and tau = 0.4 ms its
coefficients span more than 60 decades and python-control's arithmetic returns NaN.

python-control is imported only when a Padé delay is asked for.
"""

import dataclasses
import functools
import re

import numpy as np

from cas_freq.exceptions import ConfigError

#: Padé order used for rational models (poles, state space) when none is given.
DEFAULT_PADE_ORDER = 6

#: Largest Padé order accepted: the normalised coefficients stay above 1e-60 up to here.
MAX_PADE_ORDER = 30


@dataclasses.dataclass(frozen=True)
class DelayModel:
    """How transport delays are represented.

    Attributes
    ----------
    order : int or None
        Padé order n >= 1, or None for the exact delay ``exp(-s*tau)``.
    """

    order: int | None = None

    def __post_init__(self):
        if self.order is not None:
            if isinstance(self.order, bool) or not isinstance(self.order, int):
                raise ConfigError(f"delay model: Padé order must be an integer, got {self.order!r}")
            if not 1 <= self.order <= MAX_PADE_ORDER:
                raise ConfigError(
                    f"delay model: Padé order must be 1..{MAX_PADE_ORDER}, got {self.order}"
                )

    @classmethod
    def parse(cls, text):
        """Read ``"exact"`` or ``"pade:N"`` (as on the command line)."""
        text = str(text).strip().lower()
        if text == "exact":
            return cls(None)
        match = re.fullmatch(r"pade:(\d+)", text)
        if not match:
            raise ConfigError(f"--delay: expected 'exact' or 'pade:N' (N >= 1), got {text!r}")
        return cls(int(match.group(1)))

    @property
    def exact(self):
        """True for the exact delay."""
        return self.order is None

    @property
    def label(self):
        """``"exact"`` or ``"pade:N"``."""
        return "exact" if self.exact else f"pade:{self.order}"

    def response(self, s, tau):
        """Frequency response of a delay of ``tau`` [s] at complex frequencies ``s`` [rad/s]."""
        s = np.asarray(s, dtype=complex)
        if tau == 0:
            return np.ones_like(s)
        if self.exact:
            return np.exp(-s * tau)
        den = pade_denominator(self.order)
        x = s * tau
        # Padé [n/n] of exp(-x) is D(-x)/D(x).
        return np.polyval(den, -x) / np.polyval(den, x)


#: The exact delay model (frozen, so safe as a default argument).
EXACT = DelayModel()


@functools.cache
def pade_denominator(order):
    """Denominator coefficients of the order-n Padé approximant of ``exp(-x)`` (tau = 1).

    Taken from python-control's :func:`control.pade`; highest power first. The numerator is the
    same polynomial at ``-x``.
    """
    import control

    num, den = control.pade(1.0, order)
    den = np.asarray(den, dtype=float)
    if not np.allclose(np.asarray(num), den * (-1.0) ** np.arange(order, -1, -1), rtol=1e-9):
        raise AssertionError("control.pade no longer returns D(-x)/D(x)")  # pragma: no cover
    return den / den[-1]


def pade_poles(tau, order):
    """Poles [rad/s] of the order-n Padé approximant of a delay ``tau`` [s] (> 0)."""
    return np.roots(pade_denominator(order)) / tau


def pade_system(tau, order):
    """State-space Padé approximant of a delay, as a cascade of all-pass sections.

    Each real pole p gives ``(-s - p)/(s - p)`` and each complex pair ``p, conj(p)`` gives
    ``(s^2 + 2 Re(p) s + |p|^2) / (s^2 - 2 Re(p) s + |p|^2)``; every section has unit DC gain
    and unit magnitude, so their product is exactly ``D(-s tau)/D(s tau)`` while no coefficient
    spans more than the square of one pole's magnitude.

    Parameters
    ----------
    tau : float
        Delay [s], >= 0 (0 gives a static unit gain).
    order : int
        Padé order n >= 1.

    Returns
    -------
    control.StateSpace
        SISO system with ``order`` states (none for ``tau == 0``).
    """
    import control

    if tau == 0:
        return control.ss([], [], [], [[1.0]])
    sections = []
    for pole in _section_poles(pade_poles(tau, order)):
        if pole.imag == 0:
            p = pole.real
            sections.append(control.tf([-1.0, -p], [1.0, -p]))
        else:
            a, r2 = pole.real, abs(pole) ** 2
            sections.append(control.tf([1.0, 2 * a, r2], [1.0, -2 * a, r2]))
    system = control.ss(sections[0])
    for section in sections[1:]:
        system = control.series(system, control.ss(section))
    return system


def _section_poles(poles):
    """One representative per real pole or complex-conjugate pair (upper half plane)."""
    chosen = []
    for pole in poles:
        if abs(pole.imag) <= 1e-9 * abs(pole):
            chosen.append(complex(pole.real, 0.0))
        elif pole.imag > 0:
            chosen.append(pole)
    return chosen
