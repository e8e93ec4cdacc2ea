r"""Exact-delay frequency responses of many actuator variants at once (numpy only).

The same factors as :class:`cas_freq.model.transfer.ActuatorLoops` (MODEL.md), evaluated with
every parameter an array that broadcasts against the complex frequencies:

.. math::
    L_i = C_i e^{-s\tau_c} Y, \quad T_i = \frac{L_i}{1 + L_i}, \quad
    P = e^{-s\tau_p} T_i M, \quad L_p = C_p P, \quad T = \frac{C_r P}{1 + L_p}

with :math:`C_r = C_p`, or :math:`K_p + K_i/s` where the derivative acts on the measurement.
"""

import dataclasses
import types

import numpy as np

#: LoopParameters fields the frequency responses use.
RESPONSE_FIELDS = (
    "R", "L", "Km", "Ke", "J", "mu_v", "ci_Kp", "ci_Ki", "tau_c",
    "cp_Kp", "cp_Ki", "cp_Kd", "Tf", "tau_p", "derivative_on_measurement",
)


class Selector:
    """The response parameters of a batch, with parameters common to every run as scalars.

    Parameters
    ----------
    params : cas_freq.simulation.LoopParameters
        All runs.
    """

    def __init__(self, params):
        self.n = params.n_runs
        self.arrays = {}
        self.scalars = {}
        for name in RESPONSE_FIELDS:
            array = getattr(params, name)
            if array.size and np.all(array == array[0]):
                self.scalars[name] = array[0].item()
            else:
                self.arrays[name] = array

    def __call__(self, index=None, column=False):
        """Parameters of runs ``index`` (default all), shaped (k, 1) if ``column``."""
        values = dict(self.scalars)
        for name, array in self.arrays.items():
            array = array if index is None else array[index]
            values[name] = array[:, None] if column else array
        return types.SimpleNamespace(**values)


def select(params, index=None, column=False):
    """The response parameters of some runs of ``params`` (see :class:`Selector`)."""
    return Selector(params)(index, column)


def _delay(s, tau):
    """e^(-s tau) (1 for a scalar delay of 0)."""
    if np.ndim(tau) == 0 and tau == 0:
        return 1.0
    return np.exp(-s * tau)


@dataclasses.dataclass(frozen=True, eq=False)
class LoopResponses:
    """Complex responses of a batch; each array has the broadcast shape of params and s."""

    current_loop: np.ndarray
    position_loop: np.ndarray
    closed_loop: np.ndarray | None


def responses(p, s, closed=True):
    r"""L_i, L_p and (optionally) T of the runs ``p`` at complex frequencies ``s``.

    Evaluated as ratios with three complex divisions (the costly operation):
    :math:`C_i = n_{ci}/s`, :math:`Y = (Js + \mu_v)/P_m`, so
    :math:`L_i = A/B` with :math:`A = n_{ci} e^{-s\tau_c} (Js + \mu_v)`,
    :math:`B = s P_m`; :math:`T_i M = K_m n_{ci} e^{-s\tau_c} / (s (A + B))` (the factor
    :math:`Js + \mu_v` cancels); :math:`C_p = N_{cp} / (s (T_f s + 1))`, so
    :math:`L_p = N/D` with :math:`N = N_{cp} K_m n_{ci} e^{-s\tau_c} e^{-s\tau_p}` and
    :math:`D = s (T_f s + 1) s (A + B)`, and :math:`T = N/(D + N)` (derivative on the error)
    or :math:`T = (K_p s + K_i)(T_f s + 1) K_m n_{ci} e^{-s\tau_c} e^{-s\tau_p} / (D + N)`
    (on the measurement: only the reference path changes).

    Parameters
    ----------
    p : types.SimpleNamespace
        Parameters from :func:`select`, broadcastable against ``s``.
    s : numpy.ndarray
        Complex frequencies [rad/s] (``1j * omega``).
    closed : bool
        Also compute T.

    Returns
    -------
    LoopResponses
    """
    jm = p.J * s + p.mu_v
    drive = (p.ci_Kp * s + p.ci_Ki) * _delay(s, p.tau_c)
    a = drive * jm
    b = ((p.L * s + p.R) * jm + p.Ke * p.Km) * s
    li = a / b
    n_cp = ((p.cp_Kp * p.Tf + p.cp_Kd) * s + (p.cp_Kp + p.cp_Ki * p.Tf)) * s + p.cp_Ki
    forward = (p.Km * _delay(s, p.tau_p)) * drive
    numerator = n_cp * forward
    denominator = ((p.Tf * s + 1.0) * (s * s)) * (a + b)
    lp = numerator / denominator
    t = None
    if closed:
        closed_den = denominator + numerator
        on_measurement = p.derivative_on_measurement
        if np.any(on_measurement):
            reference = (p.cp_Kp * s + p.cp_Ki) * (p.Tf * s + 1.0) * forward
            t = np.where(on_measurement, reference, numerator) / closed_den
        else:
            t = numerator / closed_den
    return LoopResponses(li, lp, t)


def current_loop(p, s):
    """L_i(s) alone (cheaper than :func:`responses`)."""
    jm = p.J * s + p.mu_v
    return (p.ci_Kp * s + p.ci_Ki) * _delay(s, p.tau_c) * jm / (
        ((p.L * s + p.R) * jm + p.Ke * p.Km) * s
    )
