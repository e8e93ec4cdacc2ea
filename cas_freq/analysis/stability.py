r"""Closed-loop stability from the poles of the Padé model (MODEL.md, "Stability"), numpy only.

The position closed loop contains the current closed loop, so its poles decide both. A pole
whose real part is within a relative 1e-9 of zero is called marginal: the loop neither grows nor
decays there, and no frequency-domain figure of it is trustworthy.

Method
------
The poles are the eigenvalues of the closed-loop state matrix, assembled here in numpy from the
same blocks as :func:`cas_freq.model.systems.linear_model` (which needs python-control, and
``import control`` loads matplotlib): the plant states (i, omega, theta), the PI integrator of
C_i, the two Padé cascades of :func:`cas_freq.model.delay.pade_realization` and the two states
of C_p (integrator and derivative filter). With n the Padé order there are 2n + 6 states, the
degree of the characteristic polynomial

.. math::
    P_i = d_{ci} d_c D + n_{ci} n_c (Js + \mu_v), \qquad
    P = d_{cp} d_p \, s \, P_i + n_{cp} n_p n_{ci} n_c K_m

(Y = (Js + \mu_v)/D, C_i = n_{ci}/d_{ci}, C_p = n_{cp}/d_{cp}, Padé delays n_c/d_c and
n_p/d_p; the factor Js + \mu_v cancels exactly in T_i M).

Eigenvalues of the block matrix are preferred to the roots of P: P mixes poles from ~10 rad/s
(position integrator) to ~1e5 rad/s (Padé poles of the 0.06 ms delay), so its coefficients span
tens of decades even in a scaled variable, and polynomial roots are sensitive to relative
coefficient errors that grow with that spread and with the degree (2n + 6 = 66 at n = 30).
The block matrix has entries that are the physical coefficients themselves (no products), each
Padé section is a balanced 1x1 or 2x2 block, and LAPACK's ``geev`` balances the whole matrix
before the QR iteration, so each eigenvalue is accurate to about machine precision times the
balanced matrix norm divided by its condition; the same as python-control's model, which
realises the same blocks.

Exact common factors are cancelled before realising, so no spurious pole appears:
``Ki = 0`` in either controller drops its integrator, ``Kd = 0`` drops the derivative filter
(even with ``Tf`` set), and with ``mu_v = 0`` the current loop's integrator pole cancels the zero
of Y at s = 0 (the frictionless shaft drifts at constant speed with i = 0, a mode unobservable
from i): the current-loop verdict then uses ``C_i Y = J (K_p s + K_i) / D``. The whole loop
observes that mode through theta and keeps all 2n + 6 states. The derivative placement (error or
measurement) changes only the reference path, not the poles.
"""

import dataclasses

import numpy as np

from cas_freq.model.delay import pade_realization

#: |Re p| <= MARGINAL_TOLERANCE * max(1, |p|) counts as on the imaginary axis.
MARGINAL_TOLERANCE = 1e-9


@dataclasses.dataclass(frozen=True)
class Stability:
    """Closed-loop stability verdict.

    Attributes
    ----------
    verdict : str
        ``"stable"``, ``"marginal"`` or ``"unstable"``.
    pade_order : int
        Padé order of the delays in the model whose poles were computed.
    current_loop_verdict : str
        The same verdict for the current loop T_i alone.
    poles : tuple of (float, float)
        Closed-loop poles of T as (real, imaginary) [rad/s], sorted by real part, largest first.
    """

    verdict: str
    pade_order: int
    current_loop_verdict: str
    poles: tuple

    @property
    def stable(self):
        """True only for a strictly stable closed loop."""
        return self.verdict == "stable"


def pole_verdict(poles):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for continuous-time poles [rad/s]."""
    poles = np.asarray(poles, dtype=complex)
    if poles.size == 0:
        return "stable"
    tolerance = MARGINAL_TOLERANCE * np.maximum(1.0, np.abs(poles))
    if np.any(poles.real > tolerance):
        return "unstable"
    if np.any(np.abs(poles.real) <= tolerance):
        return "marginal"
    return "stable"


def closed_loop_stability(params, pade_order):
    """Stability of the current loop and of the whole actuator, from Padé-model poles.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Validated parameters.
    pade_order : int
        Padé order of the delays.

    Returns
    -------
    Stability
    """
    poles = closed_loop_poles(params, pade_order)
    return Stability(
        verdict=pole_verdict(poles),
        pade_order=pade_order,
        current_loop_verdict=pole_verdict(current_loop_poles(params, pade_order)),
        poles=tuple((float(p.real), float(p.imag)) for p in poles),
    )


def closed_loop_poles(params, pade_order):
    """Poles [rad/s] of T = theta/theta_cmd with Padé delays, sorted by real part, largest first.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Validated parameters.
    pade_order : int
        Padé order n >= 1 of both delays.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s]; 2n + 6 of them unless a controller term is zero.
    """
    motor = params.motor
    # i_cmd -> (i, theta): PI, current delay, plant (states i, omega, theta)
    plant = _plant(motor, np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    forward = _series(
        _series(_current_controller(params.current_loop),
                pade_realization(params.current_loop.delay, pade_order)),
        plant,
    )
    inner = _close_loop(forward, feedback_row=0, output_row=1)
    # position controller -> position delay -> inner loop, closed on theta
    loop = _series(
        _series(_position_controller(params.position_loop),
                pade_realization(params.position_loop.delay, pade_order)),
        inner,
    )
    return _sorted(np.linalg.eigvals(_close_loop(loop, 0, 0)[0]))


def current_loop_poles(params, pade_order):
    """Poles [rad/s] of T_i = i/i_cmd with a Padé current delay (exact cancellations removed).

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Validated parameters.
    pade_order : int
        Padé order n >= 1 of the current-loop delay.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s], sorted by real part, largest first.
    """
    motor, loop = params.motor, params.current_loop
    delay = pade_realization(loop.delay, pade_order)
    if motor.viscous_friction == 0 and loop.Ki > 0:
        # C_i Y = (Kp s + Ki) J / D: with mu_v = 0, J omega' = Km i, so i = (J/Km) s omega and
        # the plant (i, omega) read out as Kp i + (J Ki/Km) omega has exactly this transfer.
        output = np.array([[loop.Kp, motor.J * loop.Ki / motor.Km]])
        forward = _series(delay, _plant(motor, output, states=2))
    else:
        forward = _series(
            _series(_current_controller(loop), delay),
            _plant(motor, np.array([[1.0, 0.0]]), states=2),
        )
    return _sorted(np.linalg.eigvals(_close_loop(forward, 0, 0)[0]))


def _sorted(poles):
    return poles[np.argsort(-poles.real, kind="stable")]


def _plant(motor, output, states=3):
    """Motor (report Fig. 5), input V [V], states (i, omega[, theta]), outputs ``output @ x``."""
    mu = motor.viscous_friction
    a = np.array([
        [-motor.R / motor.L, -motor.Ke / motor.L, 0.0],
        [motor.Km / motor.J, -mu / motor.J, 0.0],
        [0.0, 1.0, 0.0],
    ])[:states, :states]
    b = np.array([[1.0 / motor.L], [0.0], [0.0]])[:states]
    return a, b, np.asarray(output, dtype=float), np.zeros((output.shape[0], 1))


def _current_controller(loop):
    """C_i = Kp + Ki/s [V/A]; no state when Ki = 0."""
    if loop.Ki == 0:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[loop.Kp]])
    return np.zeros((1, 1)), np.ones((1, 1)), np.array([[loop.Ki]]), np.array([[loop.Kp]])


def _position_controller(loop):
    """C_p = Kp + Ki/s + Kd s/(Tf s + 1) [A/rad]: integrator (if Ki > 0), filter (if Kd > 0).

    The derivative term is (Kd/Tf) (1 - 1/(Tf s + 1)): a filter state x' = (e - x)/Tf.
    """
    diagonal, b, c = [], [], []
    d = loop.Kp
    if loop.Ki > 0:
        diagonal.append(0.0)
        b.append(1.0)
        c.append(loop.Ki)
    if loop.Kd > 0:
        tf = loop.filter_time_constant
        diagonal.append(-1.0 / tf)
        b.append(1.0 / tf)
        c.append(-loop.Kd / tf)
        d += loop.Kd / tf
    m = len(diagonal)
    return (np.diag(np.asarray(diagonal, dtype=float)).reshape(m, m),
            np.asarray(b, dtype=float).reshape(m, 1), np.asarray(c, dtype=float).reshape(1, m),
            np.array([[d]]))


def _series(first, second):
    """``first`` then ``second`` (single input; ``first`` single output)."""
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    m1, m2 = a1.shape[0], a2.shape[0]
    a = np.zeros((m1 + m2, m1 + m2))
    a[:m1, :m1] = a1
    a[m1:, :m1] = b2 @ c1
    a[m1:, m1:] = a2
    return a, np.vstack([b1, b2 @ d1]), np.hstack([d2 @ c1, c2]), d2 @ d1


def _close_loop(system, feedback_row, output_row):
    """Unity negative feedback u = r - y[feedback_row]; returns (A, B, C, D) for y[output_row].

    The fed-back output must be strictly proper (zero feedthrough), as every loop here is.
    """
    a, b, c, d = system
    if np.any(d[feedback_row] != 0):
        raise AssertionError("feedback through a direct term")  # pragma: no cover
    a_closed = a - b @ c[feedback_row:feedback_row + 1]
    return a_closed, b, c[output_row:output_row + 1], d[output_row:output_row + 1]
