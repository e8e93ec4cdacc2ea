r"""What the simulator takes from the declared loop structure: the loops' controllers, their
delays and feed-forward, the filters as exactly discretised state-space blocks, the signal each
loop measures.

The simulator does not compose the loops itself: :func:`inner_blocks` reads the structure of
:func:`cas_freq.model.structure.build` (the same one the frequency domain evaluates) and
returns the numbers each engine's steps use. Limits (``omega_max``, ``i_max``, ``v_max``) are
not linear and so not in the structure; they come from the parameters.

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
or angle, before any controller (sampled or not) reads it (:attr:`Inner.current_sensor`,
:attr:`Inner.angle_sensor`).

A (digital) filter after a **sampled** controller runs at that controller's rate (one at the current
command at the rate of the controller that commands the current, one on the velocity feedback
at the velocity loop's rate; docs/model.md "Sampled controllers"): the same realisation is
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
from cas_freq.simulation.delay_line import delay_steps
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


@dataclasses.dataclass(frozen=True)
class Inner:
    """The blocks between the position controller and the current loop, and the position
    loop's measurement (every architecture has one: the report's PID-on-PI without filters
    has no velocity loop and no filter chain, and is stepped by the same code).

    Attributes
    ----------
    cascade : bool
        A velocity loop between the position loop and the current loop.
    output_feedback : bool
        The position loop measures the output angle on the motor's scale, N*delta.
    velocity_kp, velocity_ki, velocity_limit, velocity_ff_a : numpy.ndarray or None
        The velocity PI's gains [A*s/rad], [A/rad], its current limit [A] and the
        feed-forward of the motor-angle command's acceleration [A*s^2/rad] (cascade only).
    velocity_delay : float or numpy.ndarray
        Delay between the velocity controller and the current loop [s] (cascade only, else 0).
    path : FilterChain or None
        Filters at the current command (after the controller that commands the current).
    sensor : FilterChain or None
        Filters on the measured motor speed (the velocity loop's feedback filter and the
        ``velocity_feedback`` filters).
    commander_every : int or None
        Update period in steps of the controller that commands the current (the velocity
        controller, or the position controller without one) where it is sampled; the path
        chain (and the sensor chain, the velocity loop's) is then discretised over it. None
        for a continuous one.
    current_sensor, angle_sensor : FilterChain or None
        The analog filters on the measured current and on the position loop's measured angle
        (``current_feedback``, ``position_feedback``): continuous, stepped at every step
        before a controller (sampled or not) reads the measurement.
    """

    cascade: bool
    output_feedback: bool
    velocity_kp: object = None
    velocity_ki: object = None
    velocity_limit: object = None
    velocity_ff_a: object = None
    velocity_delay: object = 0.0
    path: FilterChain | None = None
    sensor: FilterChain | None = None
    commander_every: int | None = None
    current_sensor: FilterChain | None = None
    angle_sensor: FilterChain | None = None


@dataclasses.dataclass(frozen=True)
class Position:
    """The position controller's numbers, as the engines use them.

    ``kp``, ``ki``, ``kd``, ``tf`` the PID's (P/PI in a cascade: ``kd`` 0), ``limit`` the clamp
    of its output (i_max, or omega_max in a cascade), ``ff_v`` and ``ff_a`` the feed-forward
    of the motor-angle command's rate and acceleration into its output, ``delay`` the delay
    after it [s].
    """

    kp: np.ndarray
    ki: np.ndarray
    kd: np.ndarray
    tf: np.ndarray
    limit: np.ndarray
    ff_v: np.ndarray
    ff_a: np.ndarray
    delay: object


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


def current(params):
    """The current controller of ``params``: (Kp, Ki, Kd, Tf, v_max) per run, from the
    structure."""
    return controller(loop_structure.build(params).loops[0], params.n_runs)


def position(params):
    """The position controller of ``params`` (:class:`Position`), from the structure."""
    n = params.n_runs
    loop = loop_structure.build(params).loops[-1]
    ff_v, ff_a = _feedforward(loop, n)
    return Position(*controller(loop, n), ff_v, ff_a, loop.delay)


def _discretised(a, b, c, d, period, alpha):
    """A chain's realisation discretised over ``period`` [s] by the generalised bilinear
    transform of weight ``alpha`` (module notes), as a :class:`FilterChain` (G_b = 0)."""
    n, m = a.shape[:2]
    ima = np.eye(m) - alpha * period * a
    a_d = np.linalg.solve(ima, np.eye(m) + (1.0 - alpha) * period * a)
    b_d = np.linalg.solve(ima, period * b[:, :, None])[:, :, 0]
    c_d = np.linalg.solve(np.swapaxes(ima, 1, 2), c[:, :, None])[:, :, 0]
    d_d = d + alpha * np.einsum("ri,ri->r", c, b_d)
    return FilterChain(np.ascontiguousarray(a_d), b_d, np.zeros((n, m)), c_d, d_d)


def filter_chain(blocks, n, dt, every=None, method="backward"):
    """The blocks in series (:class:`FilterChain`), or None for no block.

    Stepped exactly over ``dt`` [s] (a continuous chain), or, with ``every`` (a sampled
    chain, updated every ``every`` steps), discretised over ``every * dt`` by ``method``
    (module notes).
    """
    if not blocks:
        return None
    a, b, c, d = loop_structure.chain_state_space(blocks, n)
    if every is not None:
        return _discretised(a, b, c, d, every * dt, METHODS[check_method(method)])
    m = a.shape[1]
    augmented = np.zeros((n, m + 2, m + 2))
    augmented[:, :m, :m] = a
    augmented[:, :m, m] = b
    augmented[:, m, m + 1] = 1.0 / dt
    e = distinct_exponentials(augmented * dt)
    return FilterChain(np.ascontiguousarray(e[:, :m, :m]), e[:, :m, m] - e[:, :m, m + 1],
                       e[:, :m, m + 1].copy(), np.ascontiguousarray(c), d)


def inner_blocks(params, dt, every=None, method="backward"):
    """The blocks of ``params`` between the position controller and the current loop
    (:class:`Inner`), from the structure (:func:`cas_freq.model.structure.build`).

    ``every`` maps loop names (:data:`LOOPS`) to update periods in steps (None or absent:
    continuous); a sampled loop's filters are discretised by ``method``.
    """
    p = params
    every = every or {}
    n = p.n_runs
    loops = loop_structure.build(p).loops
    commanding = loops[1]  # the loop whose controller commands the current loop
    output_feedback = loops[-1].feedback == "output_angle"
    commander_every = every.get(commanding.name)
    path = filter_chain(commanding.path, n, dt, commander_every, method)
    measurements = dict(current_sensor=filter_chain(analog_sensor(loops[0]), n, dt),
                        angle_sensor=filter_chain(analog_sensor(loops[-1]), n, dt))
    if not p.cascade:
        return Inner(False, output_feedback, path=path, commander_every=commander_every,
                     **measurements)
    kp, ki, _, _, limit = controller(commanding, n)
    _, ff_a = _feedforward(commanding, n)
    return Inner(True, output_feedback, velocity_kp=kp, velocity_ki=ki,
                 velocity_limit=limit, velocity_ff_a=ff_a,
                 velocity_delay=commanding.delay, path=path,
                 sensor=filter_chain(digital_sensor(commanding), n, dt, commander_every, method),
                 commander_every=commander_every, **measurements)


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


# --- the compiled kernel's tables of these blocks (kernel.py) ------------------------------

#: Columns of the kernel's table of the inner blocks (n_runs, columns): flags and the velocity
#: loop, the update period in steps of the controller that commands the current (the velocity
#: controller, or the position controller without one; 0: continuous), 1.0 where a sampled
#: velocity controller integrates by the backward difference, then each filter chain's Phi
#: (row-major), G_a, G_b, C and D.
(CASCADE, OUTPUT, V_KP, V_KI, V_LIMIT, V_FF_A, V_FRACTION, PATH_ORDER, SENSOR_ORDER,
 COMMANDER_EVERY, V_BACKWARD) = range(11)
#: Columns of each analog measurement filter (on the current, on the position loop's angle):
#: its order (0: none), its chain's first column in the table, its states' first column in the
#: state.
I_ORDER, I_AT, I_Z, A_ORDER, A_AT, A_Z = range(11, 17)
PATH = 17  # first column of the path chain (the sensor chain, then the measurements' follow)
#: Columns of the kernel's state of the inner blocks: the velocity controller (integral,
#: error, rest, output left and right, clamped), the path filter's last input, the sensor
#: filter's last input, the current command's left and right limits (held between the
#: updates of a sampled commander), then the path filter's states and as many scratch
#: columns, then the sensor filter's.
S_INT, S_E, S_REST, S_U_LEFT, S_U, S_LIMITED, S_PATH_U, S_SENSOR_U, S_CMD_LEFT, S_CMD = range(10)
#: ... and the measured current's and angle's last inputs (their filters' states follow the
#: sensor filter's).
S_I_U, S_A_U = 10, 11
S_PATH = 12


def chain_columns(m):
    """Columns of a filter chain of order ``m`` in the kernel's table."""
    return m * m + 3 * m + 1


def _put_chain(table, start, chain):
    if chain is None:
        return
    n, m = chain.phi.shape[:2]
    table[:, start:start + m * m] = chain.phi.reshape(n, m * m)
    start += m * m
    for part in (chain.g_a, chain.g_b, chain.c):
        table[:, start:start + m] = part
        start += m
    table[:, start] = chain.d


def kernel_tables(inner, n, dt, position_delay, backward=False):
    """The kernel's tables of ``inner`` (:class:`Inner`) for ``n`` runs (``backward``: a
    sampled velocity controller integrates by the backward difference): the parameters
    (n_runs, columns),
    a zeroed state (n_runs, columns) and the whole steps of the delay between the position
    and the velocity controller (n_runs,) (0 without a velocity loop).

    The delay lines' ring sizes follow from those steps (:func:`delay_line.ring_size`)."""
    chains = (inner.path, inner.sensor, inner.current_sensor, inner.angle_sensor)
    m_path, m_sensor, m_current, m_angle = (0 if c is None else c.order for c in chains)
    table = np.zeros((n, PATH + sum(chain_columns(m) for m in (m_path, m_sensor, m_current,
                                                                 m_angle))))
    table[:, I_ORDER], table[:, A_ORDER] = m_current, m_angle
    table[:, I_AT] = PATH + chain_columns(m_path) + chain_columns(m_sensor)
    table[:, A_AT] = table[:, I_AT] + chain_columns(m_current)
    table[:, I_Z] = S_PATH + 2 * (m_path + m_sensor)
    table[:, A_Z] = table[:, I_Z] + 2 * m_current
    _put_chain(table, int(table[0, I_AT]) if n else 0, inner.current_sensor)
    _put_chain(table, int(table[0, A_AT]) if n else 0, inner.angle_sensor)
    table[:, CASCADE] = inner.cascade
    table[:, OUTPUT] = inner.output_feedback
    table[:, PATH_ORDER], table[:, SENSOR_ORDER] = m_path, m_sensor
    table[:, COMMANDER_EVERY] = inner.commander_every or 0
    table[:, V_BACKWARD] = backward
    _put_chain(table, PATH, inner.path)
    _put_chain(table, PATH + chain_columns(m_path), inner.sensor)
    steps = np.zeros(n, dtype=np.int64)
    if inner.cascade:
        table[:, V_KP], table[:, V_KI] = inner.velocity_kp, inner.velocity_ki
        table[:, V_LIMIT], table[:, V_FF_A] = inner.velocity_limit, inner.velocity_ff_a
        steps, table[:, V_FRACTION] = delay_steps(np.broadcast_to(position_delay, (n,)), dt)
    state = np.zeros((n, S_PATH + 2 * (m_path + m_sensor + m_current + m_angle)))  # + scratch
    return table, state, steps
