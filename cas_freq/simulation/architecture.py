r"""What the simulator takes from the declared loop structure: one row per loop, innermost
first (:class:`LoopStep`, :func:`loop_steps`), that both engines step the same way.

The simulator does not compose the loops itself: :func:`loop_steps` reads the structure of
:func:`cas_freq.model.structure.build` (the same one the frequency domain evaluates). Each loop
has a controller (PI or PID with filtered derivative, its clamp), the signal it measures (the
plant's current, speed, angle or the output angle on the motor's scale), filters on that
measurement (analog ones before its sampler, digital ones after), filters in its path (after
its controller), feed-forward of the command's rate and acceleration, its update period (every
step for a continuous controller) and the delay after it. Loop j's reference is the delayed
output of loop j + 1; the outermost loop's is the command; the plant's voltage is the delayed
output of loop 0. Limits (``omega_max``, ``i_max``, ``v_max``) are not linear; they come with
the structure (:attr:`~cas_freq.model.structure.Loop.limit`).

**Filters** (the blocks of a loop's ``path`` or ``sensor``) are continuous linear blocks in
series. Each is realised in a scaled state space (entries of the order of its frequency,
well-conditioned for the exponential), the chain is connected in series, and the chain is
stepped exactly for an input linear over the step, as the plant is
(:func:`~cas_freq.simulation.engine.plant_step_matrices`, first-order hold):

.. math::
    z_{k+1} = \Phi z_k + G_a u_k^+ + G_b u_{k+1}^-, \qquad
    y_{k+1}^\mp = C z_{k+1} + D u_{k+1}^\mp

(the right limit ``+`` of the input at the step's start, the left limit ``-`` at its end: a
step command passes through a filter's direct term at once).

An **analog measurement filter** (``current_feedback``, ``position_feedback``: a loop's
``sensor`` blocks with :attr:`~cas_freq.model.structure.Block.analog`) is continuous whatever
the controllers: its chain is stepped at every step, exactly as above, on the measured current
or angle, before any controller (sampled or not) reads it (:attr:`LoopStep.analog`).

A (digital) filter of a **sampled** loop (in its path or on its measurement after the sampler)
runs at that loop's rate (docs/model.md "Sampled controllers"): the same realisation is
discretised over the period T by the generalised bilinear transform
:math:`s \to (z - 1)/(T (\alpha z + 1 - \alpha))` (alpha 1 backward difference, 1/2 Tustin;
:data:`~cas_freq.simulation.controllers.METHODS`),

.. math::
    A_d = (I - \alpha T A)^{-1} (I + (1 - \alpha) T A), \quad
    B_d = (I - \alpha T A)^{-1} T B, \quad
    C_d = C (I - \alpha T A)^{-1}, \quad D_d = D + \alpha C_d B T

(the formulas of ``scipy.signal.cont2discrete(method="gbt")``), and stepped at each update
with the sampled input, :math:`y_n = C_d z_n + D_d u_n`, :math:`z_{n+1} = A_d z_n + B_d u_n`:
the :class:`FilterChain` with :math:`\Phi = A_d`, :math:`G_a = B_d`, :math:`G_b = 0`, so both
engines step it as a continuous chain, once per update, and hold its output in between.
"""

import dataclasses

import numpy as np

from cas_freq.model import structure as loop_structure
from cas_freq.model.structure import analog_sensor, digital_sensor
from cas_freq.simulation.controllers import METHODS, check_method
from cas_freq.simulation.mechanics import distinct_exponentials

#: The loops a simulated drive can have, innermost first (their names in the structure and in
#: the per-loop update periods the engines take, ``every``).
LOOPS = ("current_loop", "velocity_loop", "position_loop")


@dataclasses.dataclass(frozen=True)
class FilterChain:
    """Filters in series, stepped exactly for an input linear over the step.

    Attributes
    ----------
    phi : numpy.ndarray
        (n_runs, m, m) state transition over one step.
    g_a, g_b : numpy.ndarray
        (n_runs, m) input matrices of the input at the step's start and end.
    c : numpy.ndarray
        (n_runs, m) output row.
    d : numpy.ndarray
        (n_runs,) direct term.
    """

    phi: np.ndarray
    g_a: np.ndarray
    g_b: np.ndarray
    c: np.ndarray
    d: np.ndarray

    @property
    def order(self):
        """Number of states m."""
        return self.phi.shape[1]


def _feedforward(loop, n):
    """(rate, acceleration) coefficients of a loop's feed-forward polynomial Phi(s)."""
    if loop.feedforward is None:
        return np.zeros(n), np.zeros(n)
    padded = (0.0, 0.0, 0.0) + tuple(loop.feedforward)
    return (np.broadcast_to(np.asarray(padded[-2], dtype=float), (n,)).copy(),
            np.broadcast_to(np.asarray(padded[-3], dtype=float), (n,)).copy())


def _per_run(value, n):
    return np.broadcast_to(np.asarray(value, dtype=float), (n,)).astype(float)


def controller(loop, n):
    """A loop's controller as the engines step it: (Kp, Ki, Kd, Tf, limit) per run, from the
    structure (:attr:`~cas_freq.model.structure.Block.gains`,
    :attr:`~cas_freq.model.structure.Loop.limit`)."""
    return tuple(_per_run(value, n) for value in (*loop.controller.gains, loop.limit))


@dataclasses.dataclass(frozen=True)
class LoopStep:
    """One loop of the structure as the engines step it (per run: arrays of shape (n_runs,)).

    Attributes
    ----------
    name : str
        The loop's name in the structure (:data:`LOOPS`).
    signal : str
        What it measures (:data:`cas_freq.model.structure.SIGNALS`).
    kp, ki, kd, tf, limit : numpy.ndarray
        Its controller's gains, derivative filter time constant [s] and output clamp.
    ff_v, ff_a : numpy.ndarray
        Feed-forward of the motor-angle command's rate and acceleration into its output.
    delay : numpy.ndarray
        The delay after its controller [s].
    every : int or None
        Update period of a sampled controller in steps; None for a continuous one.
    on_measurement : numpy.ndarray
        Bool: the derivative acts on the measurement, not on the error.
    analog, sensor, path : FilterChain or None
        Its analog measurement filters (continuous, stepped every step), its digital ones
        (at its rate) and the filters after its controller (at its rate).
    derivative : FilterChain or None
        The digital blocks on its derivative term's input alone (the window of
        :attr:`~cas_freq.model.structure.Loop.derivative`, at its rate).
    quantum : numpy.ndarray or None
        One count of the encoder it reads, on the scale of its measured signal [rad of the
        motor] (:func:`encoder_quantum`); None where it reads no quantised angle.
    """

    name: str
    signal: str
    kp: np.ndarray
    ki: np.ndarray
    kd: np.ndarray
    tf: np.ndarray
    limit: np.ndarray
    ff_v: np.ndarray
    ff_a: np.ndarray
    delay: np.ndarray
    every: int | None
    on_measurement: np.ndarray
    analog: FilterChain | None = None
    sensor: FilterChain | None = None
    path: FilterChain | None = None
    quantum: np.ndarray | None = None
    derivative: FilterChain | None = None

    @property
    def sampled(self):
        """The controller is sampled."""
        return self.every is not None

    @property
    def has_feedforward(self):
        """Some run has a feed-forward into this loop's output."""
        return bool(np.any(self.ff_v != 0) or np.any(self.ff_a != 0))


def encoder_quantum(params, signal):
    r"""One count of the encoder that measures ``signal`` (a loop's measured signal,
    :data:`~cas_freq.model.structure.SIGNALS`) on that signal's scale, per run [rad of the
    motor], or None where it is not quantised.

    The motor's encoder of C counts per revolution reads the motor angle in steps of
    :math:`q = 2\pi/C`; the output's of C_o counts reads the output angle in steps of
    :math:`2\pi/C_o`, which the loops see on the motor's scale (N delta) as
    :math:`N \cdot 2\pi/C_o` (docs/model.md, "Encoder quantisation").
    """
    counts = {"motor_angle": params.counts_per_rev,
              "output_angle": params.output_counts_per_rev}.get(signal)
    if counts is None:
        return None
    quantum = _per_run(2.0 * np.pi / counts, params.n_runs)
    return quantum * params.ratio if signal == "output_angle" else quantum


def quantised(value, quantum):
    """``value`` rounded to a whole number of counts ``quantum`` (ties up: the same operation
    in both engines, so they agree to the bit)."""
    return quantum * np.floor(value / quantum + 0.5)


def loop_steps(params, dt, every=None, method="backward"):
    """The loops of ``params`` innermost first (tuple of :class:`LoopStep`), from the
    structure (:func:`cas_freq.model.structure.build`).

    ``every`` maps loop names (:data:`LOOPS`) to update periods in steps (None or absent:
    continuous); a sampled loop's digital filters are discretised by ``method``.
    """
    every = every or {}
    n = params.n_runs
    loops = loop_structure.build(params).loops
    steps = []
    for j, loop in enumerate(loops):
        period = every.get(loop.name)
        on_measurement = np.zeros(n, dtype=bool)
        if j == len(loops) - 1:  # the derivative of the outermost PID (structure.build)
            on_measurement = np.broadcast_to(params.derivative_on_measurement, (n,)) != 0
        steps.append(LoopStep(
            loop.name, loop.feedback, *controller(loop, n), *_feedforward(loop, n),
            _per_run(loop.delay, n), period, on_measurement,
            analog=filter_chain(analog_sensor(loop), n, dt),
            sensor=filter_chain(digital_sensor(loop), n, dt, period, method),
            path=filter_chain(loop.path, n, dt, period, method),
            quantum=encoder_quantum(params, loop.feedback),
            derivative=filter_chain(loop.derivative, n, dt, period, method),
        ))
    return tuple(steps)


def _discretised(a, b, c, d, period, alpha):
    """A continuous realisation (per run) discretised over ``period`` [s] by the generalised
    bilinear transform of weight ``alpha`` (module notes): (A_d, B_d, C_d, D_d)."""
    m = a.shape[1]
    ima = np.eye(m) - alpha * period * a
    a_d = np.linalg.solve(ima, np.eye(m) + (1.0 - alpha) * period * a)
    b_d = np.linalg.solve(ima, period * b[:, :, None])[:, :, 0]
    c_d = np.linalg.solve(np.swapaxes(ima, 1, 2), c[:, :, None])[:, :, 0]
    return a_d, b_d, c_d, d + alpha * np.einsum("ri,ri->r", c, b_d)


def _digital_chain(blocks, n, period, alpha):
    """A sampled chain discretised over ``period`` [s] (:class:`FilterChain`, G_b = 0): the
    whole chain at once, or, with a digital FIR block (:attr:`Block.fir`) in it, each block
    (the FIR as it is) in series."""
    if not any(block.fir for block in blocks):
        spaces = [_discretised(*loop_structure.chain_state_space(blocks, n), period, alpha)]
    else:
        spaces = [loop_structure.fir_state_space(block, n) if block.fir else
                  _discretised(*loop_structure.block_state_space(block, n), period, alpha)
                  for block in blocks]
    a, b, c, d = spaces[0]
    for space in spaces[1:]:
        a, b, c, d = loop_structure.series_state_space((a, b, c, d), space)
    return FilterChain(np.ascontiguousarray(a), b, np.zeros(b.shape), c, d)


def filter_chain(blocks, n, dt, every=None, method="backward"):
    """The blocks in series (:class:`FilterChain`), or None for no block.

    Stepped exactly over ``dt`` [s] (a continuous chain), or, with ``every`` (a sampled
    chain, updated every ``every`` steps), discretised over ``every * dt`` by ``method``
    (module notes).
    """
    if not blocks:
        return None
    if every is not None:
        return _digital_chain(blocks, n, every * dt, METHODS[check_method(method)])
    a, b, c, d = loop_structure.chain_state_space(blocks, n)
    m = a.shape[1]
    augmented = np.zeros((n, m + 2, m + 2))
    augmented[:, :m, :m] = a
    augmented[:, :m, m] = b
    augmented[:, m, m + 1] = 1.0 / dt
    e = distinct_exponentials(augmented * dt)
    return FilterChain(np.ascontiguousarray(e[:, :m, :m]), e[:, :m, m] - e[:, :m, m + 1],
                       e[:, :m, m + 1].copy(), np.ascontiguousarray(c), d)


class FilterState:
    """A :class:`FilterChain`'s state over a batch (numpy; the reference engine)."""

    def __init__(self, chain):
        self.chain = chain
        self.z = np.zeros(chain.phi.shape[:2])
        self.u = None  # the input's right limit at the last step

    def start(self, u_left, u_right):
        """Outputs at t = 0 from rest (left and right limits)."""
        self.u = u_right
        d = self.chain.d
        return d * u_left, d * u_right

    def step(self, u_left, u_right):
        """Advance one step to an input with limits ``u_left``, ``u_right`` at its end."""
        ch = self.chain
        self.z = (np.einsum("rij,rj->ri", ch.phi, self.z) + ch.g_a * self.u[:, None]
                  + ch.g_b * u_left[:, None])
        self.u = u_right
        y = np.einsum("ri,ri->r", ch.c, self.z)
        return y + ch.d * u_left, y + ch.d * u_right
