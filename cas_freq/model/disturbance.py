r"""What reaches the output and the current from outside the command: a load torque at the
output and noise on a measurement, with every loop closed (docs/model.md, "15. Stiffness,
effort and noise": "Dynamic stiffness", "Disturbance and noise").

Both come from the declared loop structure (:mod:`cas_freq.model.structure`), over the same
terms as the loops: with :math:`\tilde A_k = A_k \tilde F_{k-1} \sigma_k` (loop k's forward
gains with their delays, the sensor denominators inside it and its own sensor numerators
:math:`\sigma_k`, so that :math:`c_k = \tilde A_k n^V_{y_k}`) and :math:`\beta_m = b_m f_m`:

.. math::
    \frac{N\delta}{M} = \frac{n^M_{out} \prod_m \beta_m
        + \sum_k \tilde A_k\, \kappa_{y_k} \prod_{m > k} \beta_m}{E_{top}}, \qquad
    \frac{i}{\nu} = -\frac{D \sum_k w_k \tilde A_k \prod_{m > k} \beta_m}{E_{top}}

where :math:`n^M_{out}` is the output's numerator per load torque and :math:`\kappa_y` the
plant's coupling of loop k's measured signal y (:attr:`~cas_freq.model.structure.Plant.coupling`,
:math:`(n^M_{out} n^V_y - n^V_{out} n^M_y)/\Delta`: the plant's two inputs eliminated, so no
:math:`\Delta` is divided), and :math:`\nu` a noise that enters loop k's measurement (before its
sensor filters) as :math:`w_k \nu` (:math:`w_k` a polynomial: 1 for an angle, s for the speed
derived from it, 0 where it does not enter). Delays exact or Padé as in
:func:`cas_freq.model.loops.responses`. These are the continuous loops' responses.
"""

import numpy as np

import cas_freq.model.parts as parts
from cas_freq.model.delay import EXACT
from cas_freq.model.structure import build
from cas_freq.model.table import Values, entering, table, walk


def _closed(structure, s, delay, weights):
    r"""(:math:`\sum_k \tilde A_k h_k \prod_{m>k}\beta_m`, :math:`\prod_m \beta_m`,
    :math:`E_{top}`) at ``s``, with ``weights[k]`` the polynomial :math:`h_k` entering loop
    k's measurement before its sensor numerators (None: nothing enters there)."""
    rows = table(structure)
    values = Values(s, delay)
    found = walk(rows, values)
    total, betas = entering(found.steps, rows, weights, values)
    return total, betas, found.e


def load_response(p, s, delay=EXACT):
    r"""The output per load torque at the output, every loop closed: :math:`\delta/M`
    [rad/(N*m)], or [m/N] at a linear output (its force in place of the torque).

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters broadcastable against ``s`` (:class:`cas_freq.model.loops.Selector`).
    s : numpy.ndarray
        Complex frequencies [rad/s].
    delay : DelayModel
        Exact (default) or Padé delays.

    Returns
    -------
    numpy.ndarray
        Complex :math:`\delta/M`; the dynamic stiffness is its reciprocal's magnitude.
    """
    s = np.asarray(s, dtype=complex)
    structure = build(p)
    plant = structure.plant
    total, betas, e = _closed(structure, s, delay,
                              [plant.coupling[loop.feedback] for loop in structure.loops])
    return (parts.polyval(plant.load[structure.output], s) * betas + total) / (e * p.ratio)


def noise_current(p, s, weights, delay=EXACT):
    r"""The motor current per unit noise on the measurements, every loop closed:
    :math:`i/\nu` [A per unit of :math:`\nu`].

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters broadcastable against ``s``.
    s : numpy.ndarray
        Complex frequencies [rad/s].
    weights : dict of str to tuple
        Loop name -> polynomial :math:`w_k` by which the noise enters that loop's measurement
        (a loop not named: none enters).
    delay : DelayModel
        Exact (default) or Padé delays.

    Returns
    -------
    numpy.ndarray
        Complex :math:`i/\nu`.
    """
    s = np.asarray(s, dtype=complex)
    structure = build(p)
    total, _, e = _closed(structure, s, delay,
                          [weights.get(loop.name) for loop in structure.loops])
    return -parts.polyval(structure.plant.signals["current"], s) * total / e


def encoder_weights(p, structure=None):
    r"""Where the quantisation noise of the position loop's encoder enters, per unit of the
    encoder's angle: loop name -> :math:`w_k`.

    The position loop reads the encoder: the motor's (weight 1 on the motor angle) or, with
    the position loop on the output, the output's (weight N: the loops see N delta). A velocity
    loop measuring the motor's speed reads the motor encoder's derivative (weight s) when the
    position loop reads the motor encoder; with an output encoder its motor encoder's
    resolution is not given and its noise is left out.
    """
    structure = structure or build(p)
    top = structure.loops[-1]
    on_motor = top.feedback == "motor_angle"
    weights = {top.name: (1.0,) if on_motor else (p.ratio,)}
    for loop in structure.loops[:-1]:
        if on_motor and loop.feedback == "motor_velocity":
            weights[loop.name] = (1.0, 0.0)
        elif on_motor and loop.feedback == "motor_angle":  # the speed from the counts
            weights[loop.name] = (1.0,)
    return weights
