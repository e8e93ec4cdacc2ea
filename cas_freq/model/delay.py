"""Transport delays: exact, or Padé approximants that stay well conditioned at any order.

The frequency response of a delay is exact (``exp(-s*tau)``) or Padé. The Padé approximant of
order n is evaluated in the normalised variable ``x = s*tau``, where its coefficients are
moderate, and realised as a state-space cascade of first- and second-order all-pass sections.
Multiplying out the transfer function instead overflows: at n = 8 and tau = 0.4 ms its
coefficients span more than 60 decades and python-control's arithmetic returns NaN.

The coefficients, the poles, the frequency response and the numpy state-space cascade
(:func:`pade_realization`) need numpy only; python-control is imported only by
:func:`pade_system`, which returns a :class:`control.StateSpace`.
"""

import dataclasses
import functools
import math
import re
from fractions import Fraction

import numpy as np

from cas_freq.core.exceptions import ConfigError

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
        """Frequency response of delays ``tau`` [s] (a scalar or an array broadcasting
        against ``s``) at complex frequencies ``s`` [rad/s]."""
        s = np.asarray(s, dtype=complex)
        if np.ndim(tau) == 0 and tau == 0:
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
    r"""Denominator coefficients of the order-n Padé approximant of ``exp(-x)`` (tau = 1).

    The [n/n] Padé approximant of :math:`e^{-x}` is :math:`D(-x)/D(x)` with

    .. math::
        D(x) = \sum_{k=0}^{n} q_k x^k, \qquad
        q_k = \frac{(2n-k)!\, n!}{(2n)!\, k!\, (n-k)!}

    (G. H. Golub and C. F. Van Loan, *Matrix Computations*, 3rd ed., 1996, §11.3.1, the
    :math:`D_{pq}` of the matrix-exponential Padé approximant with p = q = n and z = -x; the same
    formula python-control's ``pade`` evaluates). Each :math:`q_k` is computed exactly as a
    fraction of integers and rounded once to float, so every coefficient is correctly rounded.

    Parameters
    ----------
    order : int
        Padé order n >= 1.

    Returns
    -------
    numpy.ndarray
        ``n + 1`` coefficients, highest power first, constant term 1 (numerator: the same
        polynomial at ``-x``, i.e. :math:`p_k = (-1)^k q_k`).
    """
    n = order
    coefficients = [
        Fraction(math.factorial(2 * n - k) * math.factorial(n),
                 math.factorial(2 * n) * math.factorial(k) * math.factorial(n - k))
        for k in range(n, -1, -1)
    ]
    den = np.array([float(c) for c in coefficients])
    den.setflags(write=False)  # cached: shared by every caller
    return den


def pade_poles(tau, order):
    """Poles [rad/s] of the order-n Padé approximant of a delay ``tau`` [s] (> 0)."""
    return np.roots(pade_denominator(order)) / tau


def pade_realization(tau, order):
    """State-space Padé approximant of a delay as numpy arrays (the cascade of :func:`pade_system`).

    Each real pole p < 0 gives ``(-s - p)/(s - p) = -1 + 2|p|/(s - p)`` and each complex pair
    ``a ± jb`` gives ``(s^2 + 2a s + r^2)/(s^2 - 2a s + r^2) = 1 + 4a s/((s - a)^2 + b^2)``,
    realised in modal (real block-diagonal) form with input and output weights of similar size.
    The sections are chained in series, so the product is ``D(-s tau)/D(s tau)``.

    Parameters
    ----------
    tau : float
        Delay [s], >= 0 (0 gives a static unit gain with no state).
    order : int
        Padé order n >= 1.

    Returns
    -------
    tuple of numpy.ndarray
        ``(A, B, C, D)`` with shapes ``(m, m), (m, 1), (1, m), (1, 1)``; ``m = order`` states
        (0 for ``tau == 0``). Units: input and output as the delayed signal, time in [s].
    """
    a_all = np.zeros((0, 0))
    b_all = np.zeros((0, 1))
    c_all = np.zeros((1, 0))
    d_all = np.ones((1, 1))
    if tau == 0:
        return a_all, b_all, c_all, d_all
    for pole in _section_poles(pade_poles(tau, order)):
        if pole.imag == 0:
            p = pole.real
            g = math.sqrt(2.0 * abs(p))
            a, b, c, d = [[p]], [[g]], [[g if p < 0 else -g]], [[-1.0]]
        else:
            re_p, im_p = pole.real, abs(pole.imag)
            g = 2.0 * math.sqrt(abs(re_p))
            a = [[re_p, im_p], [-im_p, re_p]]
            b = [[g], [0.0]]
            c = [[4.0 * re_p / g, -4.0 * re_p**2 / (g * im_p)]]
            d = [[1.0]]
        a, b, c, d = (np.asarray(m, dtype=float) for m in (a, b, c, d))
        # series: previous sections feed this one
        m1, m2 = a_all.shape[0], a.shape[0]
        a_new = np.zeros((m1 + m2, m1 + m2))
        a_new[:m1, :m1] = a_all
        a_new[m1:, :m1] = b @ c_all
        a_new[m1:, m1:] = a
        b_all = np.vstack([b_all, b @ d_all])
        c_all = np.hstack([d @ c_all, c])
        d_all = d @ d_all
        a_all = a_new
    return a_all, b_all, c_all, d_all


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
