r"""Frequency responses of the actuator loops, for any number of variants at once (numpy only).

The loops of docs/model.md, built from :mod:`cas_freq.model.parts`, with every parameter an
array that broadcasts against the complex frequencies:

.. math::
    L_i = C_i e^{-s\tau_c} Y, \quad T_i = \frac{L_i}{1 + L_i}, \quad
    P = e^{-s\tau_p} T_i M, \quad L_p = C_p P, \quad S = \frac{1}{1 + L_p}, \quad
    T = \frac{C_r P}{1 + L_p}

with :math:`C_r = C_p`, or :math:`K_p + K_i/s` where the derivative acts on the measurement.
The delays are exact (:math:`e^{-s\tau}`) or Padé of any order
(:class:`~cas_freq.model.delay.DelayModel`). Feed-forward :math:`F(s) = FF_v s + FF_a s^2` is
not part of T (docs/model.md); ``closed_loop(feedforward=True)`` adds it to the reference path.

A single variant is a batch of one: :class:`ActuatorLoops` is a convenience view of one
variant's responses as functions of s.
"""

import dataclasses
import types

import numpy as np

from cas_freq.model import parts
from cas_freq.model.delay import EXACT

#: LoopParameters fields the frequency responses use.
RESPONSE_FIELDS = (
    "R", "L", "Km", "Ke", "J", "mu_v", "ci_Kp", "ci_Ki", "tau_c",
    "cp_Kp", "cp_Ki", "cp_Kd", "Tf", "tau_p", "ff_v", "ff_a", "derivative_on_measurement",
    "ratio", "eta", "K_g", "c_g", "J_L", "b_L", "K_h",
)


class Selector:
    """The response parameters of a batch, with parameters common to every run as scalars.

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters
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


@dataclasses.dataclass(frozen=True, eq=False)
class LoopResponses:
    """Complex responses of a batch; each array has the broadcast shape of params and s.

    ``closed_loop`` is None unless asked for.
    """

    current_loop: np.ndarray
    position_loop: np.ndarray
    closed_loop: np.ndarray | None


def responses(p, s, closed=True, delay=EXACT, feedforward=False):
    r"""L_i, L_p and (optionally) T of the runs ``p`` at complex frequencies ``s``.

    Evaluated as ratios with few complex divisions (the costly operation): with
    :math:`C_i = n_{ci}/s` and :math:`Y = D_m/(Z_e D_m + K_e K_m s n_\theta)`,
    :math:`L_i = A/B` with :math:`A = n_{ci} e^{-s\tau_c} D_m` and
    :math:`B = s (Z_e D_m + K_e K_m s n_\theta)` (:math:`D_m, n_\theta, n_{out}` the drivetrain of
    :func:`cas_freq.model.parts.mechanics`);
    :math:`T_i M = K_m n_{ci} e^{-s\tau_c} n_\theta / (A + B)` (the factor :math:`D_m` cancels);
    :math:`C_p = n_{cp} / (s (T_f s + 1))`, so :math:`L_p = N/D` with
    :math:`N = n_{cp} K_m n_{ci} e^{-s\tau_c} e^{-s\tau_p} n_\theta` and
    :math:`D = s (T_f s + 1) (A + B)`, and :math:`T = N_r/(D + N)` with :math:`N_r` as N with
    :math:`n_{out}` in place of :math:`n_\theta` (the fin, :math:`N\delta/\theta_{cmd}`) for
    the derivative on the error, or the reference path :math:`(K_p s + K_i)(T_f s + 1)` in
    place of :math:`n_{cp}` on the measurement, plus :math:`F s (T_f s + 1)` with feed-forward.

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters broadcastable against ``s`` (see :class:`Selector`).
    s : numpy.ndarray
        Complex frequencies [rad/s] (``1j * omega``).
    closed : bool
        Also compute T.
    delay : DelayModel
        Exact (default) or Padé delays.
    feedforward : bool
        Let the feed-forward act on the command in T.

    Returns
    -------
    LoopResponses
    """
    d, n_theta, n_out, factored = _mechanics(p, s)
    drive = parts.polyval(parts.current_controller(p), s) * delay.response(s, p.tau_c)
    a = drive * d
    # with D = s D_1 (no hinge stiffness) d is D_1: A and B are divided by s, D is not
    coupling = parts.back_emf_coupling(p)
    if n_theta is not None:
        coupling = coupling * n_theta
    b = (parts.polyval(parts.electrical(p), s) * d + (coupling if factored else coupling * s)) * s
    li = a / b
    n_cp = parts.polyval(parts.position_controller(p), s)
    forward = (p.Km * delay.response(s, p.tau_p)) * drive
    numerator = n_cp * forward
    filter_ = parts.polyval(parts.position_filter(p), s)
    denominator = (filter_ * (s * s if factored else s)) * (a + b)
    if n_theta is not None:  # the fin (T) sees n_out/n_theta of the motor angle
        forward_out = forward * n_out
        forward = forward * n_theta
        numerator = n_cp * forward
    else:
        forward_out = forward
    lp = numerator / denominator
    t = None
    if closed:
        closed_den = denominator + numerator
        reference = n_cp * forward_out
        on_measurement = p.derivative_on_measurement
        if np.any(on_measurement):
            measured = parts.polyval(parts.reference_path(p), s) * filter_ * forward_out
            reference = np.where(on_measurement, measured, reference)
        if feedforward:
            rate = (p.ff_a * s + p.ff_v) * s
            reference = reference + rate * s * filter_ * forward_out
        t = reference / closed_den
    return LoopResponses(li, lp, t)


def _mechanics(p, s):
    """The drivetrain of :func:`cas_freq.model.parts.mechanics` at ``s``: (D or D/s, n_theta,
    n_out, factored). ``factored``: D's constant term (the hinge stiffness) is 0 in every run,
    and the first value is D/s (the unloaded loop's J s + mu_v, evaluated as the report's
    model always was: fewer operations, the same numbers). n_theta and n_out are None where
    they are 1 (a rigid gear: the fin follows the motor)."""
    d, n_theta, n_out = parts.mechanics(p)
    factored = not np.any(d[-1])
    d = parts.polyval(d[:-1] if factored else d, s)
    if len(n_theta) == 1:
        return d, None, None, factored
    return d, parts.polyval(n_theta, s), parts.polyval(n_out, s), factored


def current_loop(p, s, delay=EXACT):
    """L_i(s) alone (cheaper than :func:`responses`)."""
    d, n_theta, _, factored = _mechanics(p, s)
    coupling = parts.back_emf_coupling(p)
    if n_theta is not None:
        coupling = coupling * n_theta
    return (parts.polyval(parts.current_controller(p), s) * delay.response(s, p.tau_c)
            * d / ((parts.polyval(parts.electrical(p), s) * d
                    + (coupling if factored else coupling * s)) * s))


class ActuatorLoops:
    """Frequency responses of every loop of one actuator, as functions of s.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.parameters.LoopParameters
        Validated parameters (SI) of one variant.
    delay : DelayModel, optional
        Exact delays (default) or Padé of some order.

    Notes
    -----
    Each method takes complex frequencies ``s`` [rad/s] (use ``1j * omega``) and returns the
    complex response, vectorised over ``s``. All come from :func:`responses`.
    """

    def __init__(self, params, delay=EXACT):
        params = parts.one_variant(params)
        self.params = params
        self.delay = delay
        self._p = Selector(params)()  # one run: every parameter a scalar

    def _responses(self, s, closed=True, feedforward=False):
        return responses(self._p, np.asarray(s, dtype=complex), closed, self.delay, feedforward)

    def current_loop(self, s):
        """L_i(s) = C_i(s) e^(-s tau_c) Y(s), broken at the voltage [-]."""
        return current_loop(self._p, np.asarray(s, dtype=complex), self.delay)

    def current_closed_loop(self, s):
        """T_i(s) = L_i/(1 + L_i) = i/i_cmd [-]."""
        loop = self.current_loop(s)
        return loop / (1.0 + loop)

    def position_loop(self, s):
        """L_p(s) = C_p(s) e^(-s tau_p) T_i(s) M(s), broken at the current command [-]."""
        return self._responses(s, closed=False).position_loop

    def sensitivity(self, s):
        """S(s) = 1/(1 + L_p) [-]."""
        return 1.0 / (1.0 + self.position_loop(s))

    def closed_loop(self, s, feedforward=False):
        """T(s) = theta/theta_cmd = delta/delta_cmd [-] (with the feed-forward if asked)."""
        return self._responses(s, feedforward=feedforward).closed_loop

    def current_response(self, s):
        r"""i/delta_cmd [A/rad]: the motor current per fin command, without feed-forward.

        The current command is the position controller's output :math:`C_r \theta_{cmd} -
        C_p \theta` delayed by tau_p, so
        :math:`i/\delta_{cmd} = N e^{-s\tau_p} T_i C_r/(1 + L_p)`, with :math:`C_r = C_p` for
        the derivative on the error and the reference path
        :math:`(K_p s + K_i)/s` for the derivative on the measurement.
        """
        p = self._p
        s = np.asarray(s, dtype=complex)
        if np.any(p.derivative_on_measurement):
            reference = parts.polyval(parts.reference_path(p), s) / s
        else:
            reference = (parts.polyval(parts.position_controller(p), s)
                         / (s * parts.polyval(parts.position_filter(p), s)))
        return (p.ratio * self.delay.response(s, p.tau_p) * self.current_closed_loop(s)
                * reference * self.sensitivity(s))

    @property
    def total_delay(self):
        """Sum of both transport delays [s] (sets how finely a grid must sample the phase)."""
        return float(self._p.tau_c + self._p.tau_p)
