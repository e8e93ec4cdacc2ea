r"""Frequency responses of the actuator loops, for any number of variants at once (numpy only).

The loops are those the declared structure (:mod:`cas_freq.model.structure`) gives, evaluated
by its recurrence with every parameter an array that broadcasts against the complex
frequencies. For the report's EPOS4 drive:

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
from cas_freq.model.structure import build, stages

#: LoopParameters fields the frequency responses use (where the parameters have them).
RESPONSE_FIELDS = (
    "R", "L", "Km", "Ke", "J", "mu_v", "ci_Kp", "ci_Ki", "tau_c",
    "cp_Kp", "cp_Ki", "cp_Kd", "Tf", "tau_p", "ff_v", "ff_a", "derivative_on_measurement",
    "ratio", "eta", "K_g", "c_g", "J_L", "b_L", "K_h",
    "cv_Kp", "cv_Ki", "tau_v", "tau_vf",
)

#: Fields the whole batch shares (the architecture, the sampling), passed on as they are.
STATIC_FIELDS = ("cascade", "feedback_output", "sample_rates", "sampling_method")

#: Per-run numbers of a filter (cas_freq.parameters.Filter).
FILTER_NUMBERS = ("frequency", "damping", "width", "depth_db")


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
                                     for name in FILTER_NUMBERS})
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

    The recurrence of :mod:`cas_freq.model.structure` on the loops :func:`build` declares, one
    complex division per figure: :math:`L_k = c_k/(b_k f_k E_{k-1})`,
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
    structure = build(p)
    seen = structure.plant.signals[output or structure.output]
    return _recurrence(structure.plant.denominator, seen, structure.names,
                       stages(structure, feedforward), s, closed, delay, loop_at_a_time)


def _recurrence(denominator, seen, names, steps, s, closed, delay, loop_at_a_time):
    """:func:`responses` of the stages ``steps`` of the loops ``names`` over the plant's
    denominator, T read at the plant signal ``seen`` (polynomials)."""
    e = parts.polyval(denominator, s)
    gain = sensed = 1.0  # A_(k-1), F~_(k-1)
    command = 0.0
    cascade, inner, terms, betas = {}, [], [], []
    for name, stage in zip(names, steps, strict=True):
        d = delay.response(s, stage.tau)
        b = parts.polyval(stage.b, s)
        f = parts.polyval(stage.f, s) if len(stage.f) > 1 else stage.f[0]
        beta = b * f
        if closed:
            command = command * b
            if stage.reference is not None:
                command = command + gain * parts.polyval(stage.reference, s) * d
        gain = gain * parts.polyval(stage.a, s) * d
        c = gain * parts.polyval(stage.g, s) * sensed
        cascade[name] = c / (beta * e)
        inner.append(e)
        terms.append(c)
        betas.append(beta)
        e = beta * e + c
        sensed = sensed * f
    t = None
    if closed:
        t = command * sensed * parts.polyval(seen, s) / e
    aat = None
    if loop_at_a_time:
        aat = {}
        upper = 0.0
        above = 1.0
        for k in range(len(terms) - 1, -1, -1):
            upper = upper + terms[k] * above
            above = above * betas[k]
            aat[names[k]] = upper / (above * inner[k])
        aat = dict(reversed(aat.items()))
    return LoopResponses(cascade, t, aat)


def current_loop(p, s, delay=EXACT):
    """L_i(s) alone (cheaper than :func:`responses`)."""
    structure = build(p)
    return _current_loop(stages(structure)[0], structure.plant.denominator, s, delay)


def _current_loop(stage, denominator, s, delay):
    f = parts.polyval(stage.f, s) if len(stage.f) > 1 else stage.f[0]
    return (parts.polyval(stage.a, s) * delay.response(s, stage.tau) * parts.polyval(stage.g, s)
            / (parts.polyval(stage.b, s) * f * parts.polyval(denominator, s)))


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
        structure = build(p)
        self.names = structure.names
        self.denominator = _arrays(structure.plant.denominator)
        self.seen = _arrays(structure.plant.signals[structure.output])
        self.steps = [dataclasses.replace(
            stage, a=_arrays(stage.a), b=_arrays(stage.b), g=_arrays(stage.g),
            f=_arrays(stage.f), tau=_arrays((stage.tau,))[0],
            reference=None if stage.reference is None else _arrays(stage.reference))
            for stage in stages(structure)]

    def _steps(self, runs, count=None):
        return [dataclasses.replace(
            stage, a=_pick(stage.a, runs), b=_pick(stage.b, runs), g=_pick(stage.g, runs),
            f=_pick(stage.f, runs), tau=_pick((stage.tau,), runs)[0],
            reference=None if stage.reference is None else _pick(stage.reference, runs))
            for stage in self.steps[:count]]

    def responses(self, runs, s, closed=True, delay=EXACT, loop_at_a_time=False, through=None):
        """:func:`responses` of the runs ``runs`` (indices, one per value of ``s``); with
        ``through`` (a loop's name; not with ``closed`` or ``loop_at_a_time``) only the loops
        up to that one (those outside it do not change it)."""
        count = None
        if through is not None and not (closed or loop_at_a_time):
            count = self.names.index(through) + 1
        return _recurrence(_pick(self.denominator, runs), _pick(self.seen, runs),
                           self.names[:count], self._steps(runs, count), s, closed, delay,
                           loop_at_a_time)

    def current_loop(self, runs, s, delay=EXACT):
        """:func:`current_loop` of the runs ``runs``."""
        return _current_loop(self._steps(runs, 1)[0], _pick(self.denominator, runs), s, delay)


def _arrays(polynomial):
    """The coefficients as arrays (n,) where they vary, else as they are (0-d arrays as
    floats: the same number)."""
    return tuple(float(c) if np.ndim(c) == 0 else np.asarray(c) for c in polynomial)


def _pick(polynomial, runs):
    """The coefficients (of :func:`_arrays`) of the runs ``runs``."""
    return tuple(c[runs] if isinstance(c, np.ndarray) else c for c in polynomial)
