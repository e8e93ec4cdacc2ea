r"""Frequency responses of the actuator loops, for any number of variants at once (numpy only).

The loops are those the declared structure (:mod:`cas_freq.model.structure`) gives, evaluated
by the walk over its loop table (:func:`cas_freq.model.table.walk`) in complex values, every
parameter an array that broadcasts against the complex frequencies. For the report's EPOS4 drive:

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

from cas_freq.core.filters_config import Filter
from cas_freq.model.delay import EXACT
from cas_freq.model.structure import build
from cas_freq.model.table import (
    Values,
    at_a_time,
    cascade,
    command,
    references,
    shaped,
    table,
    walk,
)

#: LoopParameters fields the frequency responses use (where the parameters have them).
RESPONSE_FIELDS = (
    "R", "L", "Km", "Ke", "J", "mu_v", "ci_Kp", "ci_Ki", "tau_c",
    "cp_Kp", "cp_Ki", "cp_Kd", "Tf", "tau_p", "ff_v", "ff_a", "derivative_on_measurement",
    "ratio", "eta", "K_g", "c_g", "J_L", "b_L", "K_h",
    "cv_Kp", "cv_Ki", "tau_v", "tau_vf",
)

#: Fields the whole batch shares (the architecture, the sampling), passed on as they are.
STATIC_FIELDS = ("cascade", "feedback_output", "sample_rates", "sampling_method",
                 "velocity_from_encoder", "velocity_window",
                 "derivative_window")


class Selector:
    """The response parameters of a batch, with parameters common to every run as scalars.

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        All runs.
    """

    def __init__(self, params):
        self.n = params.n_runs
        self.arrays = {}
        self.scalars = {name: getattr(params, name) for name in STATIC_FIELDS
                        if hasattr(params, name)}
        for name in RESPONSE_FIELDS:
            if not hasattr(params, name):
                continue
            array = getattr(params, name)
            if array.size and np.all(array == array[0]):
                self.scalars[name] = array[0].item()
            else:
                self.arrays[name] = array
        self.filters = tuple(getattr(params, "filters", ()))

    def __call__(self, index=None, column=False):
        """Parameters of runs ``index`` (default all), shaped (k, 1) if ``column``."""
        values = dict(self.scalars)
        for name, array in self.arrays.items():
            values[name] = _rows_of(array, index, column)
        values["filters"] = tuple(
            types.SimpleNamespace(at=item.at, kind=item.kind,
                                  **{name: _rows_of(getattr(item, name), index, column)
                                     for name in Filter.NUMBERS})
            for item in self.filters)
        return types.SimpleNamespace(**values)


def _rows_of(array, index, column):
    array = np.asarray(array)
    if array.size and np.all(array == array.reshape(-1)[0]):
        return array.reshape(-1)[0].item()
    array = array if index is None else array[index]
    return array[:, None] if column else array


@dataclasses.dataclass(frozen=True, eq=False)
class LoopResponses:
    """Complex responses of a batch; each array has the broadcast shape of params and s.

    ``loops`` maps each loop's name (innermost first) to its response broken at its
    controller's output with the loops inside closed (the cascade view);
    ``loop_at_a_time`` the same with every other loop closed (None unless asked for);
    ``closed_loop`` is T (None unless asked for).
    """

    loops: dict
    closed_loop: np.ndarray | None
    loop_at_a_time: dict | None = None

    @property
    def current_loop(self):
        """L_i [-]."""
        return self.loops["current_loop"]

    @property
    def position_loop(self):
        """L_p [-]."""
        return self.loops["position_loop"]


def responses(p, s, closed=True, delay=EXACT, feedforward=False, loop_at_a_time=False,
              output=None):
    r"""Every loop's response and (optionally) T of the runs ``p`` at complex frequencies ``s``.

    The walk over the loop table (:mod:`cas_freq.model.table`) of the loops :func:`build`
    declares, one complex division per figure: :math:`L_k = c_k/(b_k f_k E_{k-1})`,
    :math:`T = \tilde F\, g_{out} \sum_k A_{k-1}\varphi_k \prod_{m>k} b_m / E_{top}`.

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
    loop_at_a_time : bool
        Also compute every loop broken with all the others closed.
    output : str, optional
        The plant signal T reads (default the structure's output: N delta; ``"current"`` gives
        i per motor-angle command).

    Returns
    -------
    LoopResponses
    """
    found = table(build(p), feedforward, output=output)
    return evaluate(found, Values(s, delay), closed, loop_at_a_time)


def evaluate(rows, values, closed=True, loop_at_a_time=False, count=None):
    """:func:`responses` of a :class:`~cas_freq.model.table.Table` in the complex algebra
    ``values`` (:class:`~cas_freq.model.table.Values`), of its first ``count`` loops (all by
    default; those outside a loop do not change its cascade view)."""
    found = walk(rows, values, count)
    t = None
    if closed:
        numerator = command(found.steps, references(rows, values), values)
        t = numerator * found.sensed * values.poly(rows.seen) / found.e
        t = shaped(t, rows, values)
    return LoopResponses(cascade(found.steps), t,
                         at_a_time(found.steps) if loop_at_a_time else None)


def current_loop(p, s, delay=EXACT):
    """L_i(s) alone (cheaper than :func:`responses`)."""
    rows = table(build(p))
    return evaluate(rows, Values(s, delay), False, count=1).loops[rows.names[0]]


class PreparedResponses:
    """:func:`responses` and :func:`current_loop` of a few runs of a batch at a time, the
    structure built and multiplied out once for the whole batch (the margin searches
    evaluate a handful of points of some runs hundreds of times per batch; building the
    structure for each call cost more than the arithmetic). Every coefficient is the same
    number as :func:`responses` of those runs computes, so the responses are the same to
    the bit.

    Parameters
    ----------
    p : types.SimpleNamespace
        Every run's parameters, each a scalar or an array (n,) (a :class:`Selector`'s call).
    """

    def __init__(self, p):
        self.table = table(build(p)).arrays()
        self.names = self.table.names

    def responses(self, runs, s, closed=True, delay=EXACT, loop_at_a_time=False, through=None):
        """:func:`responses` of the runs ``runs`` (indices, one per value of ``s``); with
        ``through`` (a loop's name; not with ``closed`` or ``loop_at_a_time``) only the loops
        up to that one (those outside it do not change it)."""
        count = None
        if through is not None and not (closed or loop_at_a_time):
            count = self.names.index(through) + 1
        return evaluate(self.table.pick(runs, count), Values(s, delay), closed, loop_at_a_time)

    def current_loop(self, runs, s, delay=EXACT):
        """:func:`current_loop` of the runs ``runs``."""
        return self.responses(runs, s, False, delay, through=self.names[0]).loops[self.names[0]]
