r"""The loop structure of an actuator, declared once: its blocks and how they connect.

Every linear representation of the loops is derived from the :class:`Structure` that
:func:`build` declares for a batch of runs. :func:`cas_freq.model.table.table` multiplies it
out into a loop table, and :func:`cas_freq.model.table.walk` evaluates the recurrence below over
it, loop by loop from the inside out, in the arithmetic each consumer needs: the vectorised
frequency responses (:func:`cas_freq.model.loops.responses`, the compiled
:mod:`cas_freq.analysis.response_kernel` reading the same table as coefficient stacks), the
sampled loops (:mod:`cas_freq.model.sampled`), the load and noise inputs
(:mod:`cas_freq.model.disturbance`) and the Padé characteristic polynomials of the stability
verdicts (:func:`cas_freq.analysis.stability.characteristic_polynomials`). None of them
composes the loops by hand.

**The cascade.** The plant has one input, the motor voltage V, and the signals the loops measure
are rational functions of it over a common denominator :math:`\Delta` (the parts of
:mod:`cas_freq.model.parts`):

.. math::
    \frac{i}{V} = \frac{D}{\Delta}, \quad \frac{\theta}{V} = \frac{K_m n_\theta}{\Delta}, \quad
    \frac{\omega}{V} = \frac{s K_m n_\theta}{\Delta}, \quad
    \frac{N\delta}{V} = \frac{K_m n_{out}}{\Delta}, \qquad
    \Delta = Z_e D + K_e K_m s\, n_\theta

Loops are numbered from the inside (0: the current loop). Loop k's forward path
:math:`F_k = a_k e^{-s\tau_k}/b_k` (its controller, the filters after it and its delay) runs from
its error to the command of loop k − 1 (the voltage for k = 0); it measures
:math:`G_k = g_k/(f_k \Delta)` (a plant signal through the sensor filters :math:`g_k/f_k`
[numerators/denominators]). With :math:`A_k = \prod_{j \le k} a_j e^{-s\tau_j}` and
:math:`\tilde F_k = \prod_{j \le k} f_j`, the sums :math:`1 + \sum_{j \le k} \prod_{m \le j} F_m
G_j = E_k / (B_k \tilde F_k \Delta)` follow the recurrence

.. math::
    E_{-1} = \Delta, \qquad E_k = b_k f_k E_{k-1} + c_k, \qquad
    c_k = A_k g_k \tilde F_{k-1}

and every figure is a ratio of these terms:

- loop k broken at its controller's output, the loops inside closed and those outside open
  (the cascade design view, ``X_loop.*``): :math:`L_k = c_k / (b_k f_k E_{k-1})`;
- the same with every other loop closed (loop-at-a-time, ``X_loop.loop_at_a_time.*``):
  :math:`L_k^{aat} = U_k / (E_{k-1} \prod_{m \ge k} b_m f_m)` with
  :math:`U_k = \sum_{j \ge k} c_j \prod_{j < m} b_m f_m` (the outermost loop's two views agree);
- the closed loop :math:`T = N\delta/\theta_{cmd}`: the command enters at the outermost
  controller (its reference path :math:`\rho` over the same denominator, which differs from
  the feedback path for the derivative on the measurement) and, with feed-forward, at any
  controller's output (:math:`\Phi_k`, per unit command):
  :math:`T = \tilde F_{top} K_m n_{out} \sum_k A_{k-1} \varphi_k \prod_{m > k} b_m / E_{top}`
  with :math:`\varphi_k = (\rho_k + \Phi_k\, b^c_k)\, a^{path}_k e^{-s\tau_k}` (:math:`b^c_k` the
  controller's denominator, :math:`a^{path}_k` the filters' numerators), times the shaping
  :math:`W = a^{cmd}/b^{cmd}` of the command before every loop (:attr:`Structure.command`;
  continuous, or at the outermost loop's equivalent s where it is sampled);
- the characteristic polynomial of the whole loop is :math:`E_{top}` with Padé delays, and
  :math:`E_k` that of loops 0..k alone;
- a load torque :math:`M` at the output (:attr:`Plant.load`, :attr:`Plant.coupling`) and a
  noise on a measurement are further inputs over the same terms
  (:mod:`cas_freq.model.disturbance`).

A block is added by declaring it here (:func:`build`) with its equations: the evaluators need no
change.
"""

import dataclasses

import numpy as np

import cas_freq.model.parts as parts
from cas_freq.core.filters_config import ANALOG_POINTS, COMMAND_POINT, FILTERS
from cas_freq.core.sampling_config import ALPHA
from cas_freq.model.parts import polyadd, polymul

#: The plant signals a loop can measure: name -> meaning [unit per volt].
SIGNALS = {
    "current": "motor current i [A]",
    "motor_velocity": "motor speed omega [rad/s]",
    "motor_angle": "motor angle theta [rad]",
    "output_angle": "output angle on the motor's scale N*delta [rad]",
}


@dataclasses.dataclass(frozen=True)
class Block:
    """A rational transfer function numerator/denominator (polynomials as in
    :mod:`cas_freq.model.parts`: tuples of coefficients, highest power first, each a float or
    an array broadcasting over runs).

    ``minimal`` gives the same function with exact common factors cancelled (an integrator
    whose gain is 0, a derivative filter without a derivative): called, it returns
    (numerator, denominator) stacks of shape (n, width); None where the block has none.
    Characteristic polynomials use it, so no spurious pole appears.

    ``analog``: a filter on a measurement before it is sampled
    (:data:`cas_freq.core.filters_config.ANALOG_POINTS`); continuous even where the controllers are
    sampled (:mod:`cas_freq.model.sampled` puts it in the plant's hold-equivalent).

    ``gains``: a controller's (Kp, Ki, Kd, Tf) as the simulators step it (the PID of
    docs/model.md; a PI's Kd is 0 and Tf 1 [s]), None for a filter.

    ``fir``: a digital block of a sampled loop that is a finite impulse response in the
    samples, its coefficients (c_0, ..., c_m) of z^0 ... z^-m at the loop's period
    (:func:`counts_difference`); the state-space assemblies and the simulators realise it from
    them (:func:`fir_state_space`), and ``numerator``/``denominator`` are the same function in
    s under the loop's discretisation, for the evaluations at the equivalent s. None for a
    block given in s.
    """

    name: str
    numerator: tuple
    denominator: tuple = (1.0,)
    minimal: object = None
    analog: bool = False
    gains: tuple | None = None
    fir: tuple | None = None


@dataclasses.dataclass(frozen=True)
class Loop:
    """One feedback loop of the cascade.

    Attributes
    ----------
    name : str
        Figure prefix (``"current_loop"``), the group of its figures in the JSON
        (:data:`cas_freq.core.figures.LOOPS`).
    symbol : str
        Its loop transfer function's symbol (``"L_i"``), as docs/model.md and every table,
        figure and text name it.
    breaks_at : str
        Where its loop is broken (the controller's output), in words (``"the voltage"``).
    break_symbol : str
        The same signal as a symbol (``"V"``), as legends and titles name it.
    controller : Block
        Acts on the error (command − measurement).
    path : tuple of Block
        Filters in series after the controller.
    delay : float or numpy.ndarray
        Transport delay after the path [s].
    feedback : str
        The plant signal it measures (:data:`SIGNALS`).
    sensor : tuple of Block
        Filters on the measurement.
    reference : tuple or None
        Numerator over the controller's denominator of what acts on the command, where it
        differs from the controller's numerator (the derivative on the measurement).
    feedforward : tuple or None
        Polynomial :math:`\\Phi(s)` of the outermost command added to this controller's output
        (feed-forward of the command's rate and acceleration), None for none.
    signals : (str, str)
        Names of its error and its measured signal (python-control systems).
    limit : float or numpy.ndarray or None
        The clamp of its controller's output, in the unit of the command it gives (v_max [V],
        i_max [A], omega_max [rad/s]); not linear, so only the simulators read it.
    derivative : tuple of Block
        Digital blocks on the input of its controller's derivative term alone (its window,
        :func:`moving_average`): ``controller`` holds them already (its numerator and
        denominator in s); the simulators step them on the derivative's input, the state-space
        assembly realises the controller from its gains and them.
    """

    name: str
    symbol: str
    breaks_at: str
    break_symbol: str
    controller: Block
    path: tuple
    delay: object
    feedback: str
    sensor: tuple = ()
    reference: tuple | None = None
    feedforward: tuple | None = None
    signals: tuple = ("e", "y")
    limit: object = None
    derivative: tuple = ()

    @property
    def label(self):
        """Its name in words (``"current loop"``)."""
        return self.name.replace("_", " ")


@dataclasses.dataclass(frozen=True)
class Plant:
    """The plant as seen by the loops: each measured signal per voltage over one denominator.

    Attributes
    ----------
    denominator : tuple
        :math:`\\Delta` [polynomial].
    signals : dict of str to tuple
        :data:`SIGNALS` name -> numerator polynomial.
    load : dict of str to tuple
        The same signals per load torque M at the output (a force at a linear output) over
        :math:`\\Delta` [per N*m], the voltage held at 0.
    coupling : dict of str to tuple
        Per signal y the polynomial :math:`(n^M_{out} n^V_y - n^V_{out} n^M_y)/\\Delta`
        (exact: the minors of the plant's two inputs), with :math:`n^V` the numerators per
        voltage and :math:`n^M` per load torque, out = ``output_angle``
        (docs/model.md, "Dynamic stiffness").
    """

    denominator: tuple
    signals: dict
    load: dict = dataclasses.field(default_factory=dict)
    coupling: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Structure:
    """The loops of a batch of runs, innermost first, around their plant.

    ``output`` is the plant signal the closed loop T reads (the output angle). ``command``:
    blocks in series on the command before the outermost loop (the reference's shaping, at
    ``position_command``): they multiply T and change no loop.
    """

    plant: Plant
    loops: tuple
    output: str = "output_angle"
    command: tuple = ()

    @property
    def names(self):
        """The loops' figure prefixes, innermost first."""
        return tuple(loop.name for loop in self.loops)

    def loop(self, name):
        """The loop called ``name``."""
        for loop in self.loops:
            if loop.name == name:
                return loop
        raise KeyError(name)


def _rows(polynomial, n):
    return parts.stacked(polynomial, n)


def _where(condition, yes, no):
    """Per-run choice between two coefficient stacks (padded to one width)."""
    width = max(yes.shape[1], no.shape[1])
    yes = np.pad(yes, ((0, 0), (width - yes.shape[1], 0)))
    no = np.pad(no, ((0, 0), (width - no.shape[1], 0)))
    return np.where(np.asarray(condition)[:, None], yes, no)


# --- the blocks ------------------------------------------------------------------------------

def pi_controller(name, kp, ki, n):
    """C = Kp + Ki/s = (Kp s + Ki)/s; without the integrator where Ki = 0."""
    def minimal():
        ki_on = np.broadcast_to(np.asarray(ki) != 0, (n,))
        return (_where(ki_on, _rows((kp, ki), n), _rows((kp,), n)),
                _where(ki_on, _rows((1.0, 0.0), n), _rows((1.0,), n)))

    return Block(name, (kp, ki), (1.0, 0.0), minimal, gains=(kp, ki, 0.0, 1.0))


def pid_controller(p, n, window=None):
    """C_p = Kp + Ki/s + Kd s/(Tf s + 1) over s (Tf s + 1) (docs/model.md), without the
    integrator where Ki = 0 and the filter where Kd = 0; with a derivative ``window`` (the
    :func:`moving_average` block A = a/b of a sampled loop) Kp + Ki/s + Kd s A/(Tf s + 1) over
    s (Tf s + 1) b."""
    kp, ki, kd, tf = p.cp_Kp, p.cp_Ki, p.cp_Kd, p.Tf
    if window is not None:
        numerator = polyadd(polymul(polymul(parts.reference_path(p), parts.position_filter(p)),
                                    window.denominator),
                            polymul((kd, 0.0, 0.0), window.numerator))
        return Block("position PID", numerator,
                     polymul(polymul(parts.position_filter(p), (1.0, 0.0)), window.denominator),
                     gains=(kp, ki, kd, tf))

    def minimal():
        has_i = np.broadcast_to(np.asarray(ki) > 0, (n,))
        has_d = np.broadcast_to(np.asarray(kd) > 0, (n,))
        numerator = _where(has_i, _where(has_d, _rows((kp * tf + kd, kp + ki * tf, ki), n),
                                         _rows((kp, ki), n)),
                           _where(has_d, _rows((kp * tf + kd, kp), n), _rows((kp,), n)))
        denominator = _where(has_i,
                             _where(has_d, _rows((tf, 1.0, 0.0), n), _rows((1.0, 0.0), n)),
                             _where(has_d, _rows((tf, 1.0), n), _rows((1.0,), n)))
        return numerator, denominator

    return Block("position PID", parts.position_controller(p),
                 polymul(parts.position_filter(p), (1.0, 0.0)), minimal, gains=(kp, ki, kd, tf))


def filter_block(item):
    """A filter of the config's ``filters:`` list as a block: its type's transfer function,
    1 at s = 0 (:data:`cas_freq.core.filters_config.FILTERS`; docs/model.md, "Filters")."""
    kind = FILTERS[item.kind]
    numerator, denominator = kind.transfer(item)
    return Block(kind.label, numerator, denominator)


def _filters(p, at):
    return tuple(dataclasses.replace(filter_block(item), analog=at in ANALOG_POINTS)
                 for item in getattr(p, "filters", ()) if item.at == at)


def digital_sensor(loop):
    """A loop's sensor blocks after its sampler (all of them for a continuous loop)."""
    return tuple(block for block in loop.sensor if not block.analog)


def analog_sensor(loop):
    """A loop's sensor blocks before its sampler (:attr:`Block.analog`)."""
    return tuple(block for block in loop.sensor if block.analog)


def measured(loop):
    """The name of the signal a loop's sampler reads: its plant signal, or, behind analog
    filters (:func:`analog_sensor`), ``"<loop name>.measured"``."""
    return f"{loop.name}.measured" if analog_sensor(loop) else loop.feedback


def plant(p):
    """The plant's signals per voltage over :math:`\\Delta` (see the module docstring)."""
    d, n_theta, n_out = parts.mechanics(p)
    delta = polyadd(polymul(parts.electrical(p), d),
                    polymul((parts.back_emf_coupling(p), 0.0), n_theta))
    angle = tuple(p.Km * c for c in n_theta)
    load, coupling = _load_terms(p, n_out)
    return Plant(delta, {
        "current": d,
        "motor_velocity": (*angle, 0.0),
        "motor_angle": angle,
        "output_angle": tuple(p.Km * c for c in n_out),
    }, load, coupling)


def _load_terms(p, g):
    r"""The plant's signals per load torque M at the output over :math:`\Delta`, and their
    couplings (:class:`Plant`), from the two-mass equations (docs/model.md, "Dynamic
    stiffness"): with :math:`Q = e/N` (:math:`e = 1/\eta`, the load reflected as the model
    reflects it), :math:`g` the gear's impedance over K_g (``n_out``), :math:`c = 1/K_g` and
    :math:`P_m = J s^2 + \mu_v s`:

    .. math::
        \theta = Q Z_e g, \quad i = -K_e Q s g, \quad
        N\delta = Q Z_e g + c N (Z_e P_m + K_e K_m s);
        \qquad
        \text{coupling: } \theta \to K_m c N, \ \omega \to K_m c N s, \
        N\delta \to 0, \ i \to Q g + c N P_m
    """
    q = 1.0 / (p.eta * p.ratio)
    c = parts.compliance(p) if len(g) > 1 else 0.0
    cn = c * p.ratio
    z_e = parts.electrical(p)
    angle = tuple(q * x for x in polymul(z_e, g))
    motor = polyadd(polymul(z_e, (p.J, p.mu_v, 0.0)), (parts.back_emf_coupling(p), 0.0))
    output = polyadd(angle, tuple(cn * x for x in motor))
    load = {
        "current": tuple(-p.Ke * q * x for x in (*g, 0.0)),
        "motor_velocity": (*angle, 0.0),
        "motor_angle": angle,
        "output_angle": output,
    }
    coupling_angle = (p.Km * cn,)
    coupling = {
        "current": polyadd(tuple(q * x for x in g), (cn * p.J, cn * p.mu_v, 0.0)),
        "motor_velocity": (*coupling_angle, 0.0),
        "motor_angle": coupling_angle,
        "output_angle": (0.0,),
    }
    return load, coupling


def build(p):
    """The loop structure of the runs ``p``.

    The report's EPOS4 drive (docs/model.md): a PID position loop around a PI current loop.
    With a velocity loop (``p.cascade``): a P/PI position loop commanding the motor speed,
    a PI velocity loop commanding the current, a PI current loop. Filters at the current
    command sit after the controller that commands the current, those at the velocity command
    after the position controller of a cascade; those on the velocity
    feedback (and the first-order feedback filter) on the velocity loop's measurement, those at
    the position command on the command before every loop (:attr:`Structure.command`). The
    position loop measures the motor angle, or the output angle on the motor's scale with
    ``p.feedback_output``. Filters on the measured current (``current_feedback``) and angle
    (``position_feedback``) are those loops' sensors (analog blocks, :attr:`Block.analog`).

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters or types.SimpleNamespace
        Parameters broadcasting over runs (arrays (n,), columns (n, 1) or scalars).

    Returns
    -------
    Structure
    """
    n = _runs(p)
    current = Loop(
        "current_loop", "L_i", "the voltage", "V",
        pi_controller("current PI", p.ci_Kp, p.ci_Ki, n), (), p.tau_c, "current",
        _filters(p, "current_feedback"), signals=("e_i", "i"), limit=getattr(p, "v_max", None),
    )
    at_current_command = _filters(p, "current_command")
    position_feedback = ("output_angle" if getattr(p, "feedback_output", False)
                         else "motor_angle")
    # the position loop's error and what it measures: the output (delta) on an output encoder
    position_signals = ("e", "delta" if position_feedback == "output_angle" else "theta")
    if not getattr(p, "cascade", False):
        window = _derivative_window(p)
        controller = pid_controller(p, n, window)
        reference = None
        if np.any(p.derivative_on_measurement):
            # the command sees Kp + Ki/s: (Kp s + Ki)(Tf s + 1) over s (Tf s + 1) (times the
            # window's denominator)
            measured = polymul(parts.reference_path(p), parts.position_filter(p))
            if window is not None:
                measured = polymul(measured, window.denominator)
            reference = tuple(np.where(p.derivative_on_measurement, m, c) for m, c in zip(
                *_padded(measured, controller.numerator), strict=True))
        position = Loop(
            "position_loop", "L_p", "the current command", "i_cmd", controller,
            at_current_command, p.tau_p, position_feedback,
            _filters(p, "position_feedback"), reference=reference,
            feedforward=(p.ff_a, p.ff_v, 0.0), signals=position_signals,
            limit=getattr(p, "i_max", None), derivative=() if window is None else (window,),
        )
        return Structure(plant(p), (current, position), command=_filters(p, COMMAND_POINT))
    sensor = _filters(p, "velocity_feedback")
    tau_vf = np.asarray(p.tau_vf)
    velocity_feedback = "motor_angle" if getattr(p, "velocity_from_encoder", False) else (
        "motor_velocity")
    rate = dict(getattr(p, "sample_rates", ())).get("velocity_loop")
    if velocity_feedback == "motor_angle" and rate:
        # the speed the drive estimates from the encoder's counts at the velocity loop's
        # rate: their difference over m periods through the low-pass (docs/model.md §14)
        difference = counts_difference(getattr(p, "velocity_window", 1), 1.0 / rate,
                                       getattr(p, "sampling_method", "backward"))
        sensor = (difference,
                  Block("velocity filter", (1.0,), (p.tau_vf, 1.0)), *sensor)
    elif velocity_feedback == "motor_angle":
        # run continuously (the cost of sampling): the difference's limit, s
        sensor = (Block("velocity estimate", (1.0, 0.0), (p.tau_vf, 1.0)), *sensor)
    elif np.any(tau_vf > 0):
        sensor = (Block("velocity filter", (1.0,), (p.tau_vf, 1.0)), *sensor)
    velocity = Loop(
        "velocity_loop", "L_v", "the current command", "i_cmd",
        pi_controller("velocity PI", p.cv_Kp, p.cv_Ki, n), at_current_command, p.tau_v,
        velocity_feedback, sensor, feedforward=(p.ff_a, 0.0, 0.0), signals=("e_v", "omega"),
        limit=getattr(p, "i_max", None),
    )
    position = Loop(
        "position_loop", "L_p", "the velocity command", "ω_cmd",
        pi_controller("position PI", p.cp_Kp, p.cp_Ki, n), _filters(p, "velocity_command"),
        p.tau_p, position_feedback,
        _filters(p, "position_feedback"), feedforward=(p.ff_v, 0.0), signals=position_signals,
        limit=getattr(p, "omega_max", None),
    )
    return Structure(plant(p), (current, velocity, position),
                     command=_filters(p, COMMAND_POINT))


def _fir_block(name, taps, gain, period, method):
    r"""The digital block :math:`g \sum_k c_k z^{-k}` (:attr:`Block.fir`; ``taps`` the
    :math:`c_k`, ``gain`` g) of a loop of ``period`` [s] discretised by ``method``.

    In s it is the same function under the generalised bilinear transform of weight
    :math:`lpha` (:data:`~cas_freq.core.sampling_config.ALPHA`),
    :math:`z^{-1} = (1 - lpha sT)/(1 + (1 - lpha) sT)`: with :math:`x = sT` and M the
    last tap, :math:`g \sum_k c_k (1 - lpha x)^k (1 + (1-lpha) x)^{M-k} /
    (1 + (1-lpha) x)^M`, exact at the loop's equivalent s.
    """
    alpha = ALPHA[method]
    last = len(taps) - 1

    def power(root, k):  # (1 + root x)^k, lowest power first, last + 1 coefficients
        out = np.zeros(last + 1)
        out[0] = 1.0
        for _ in range(k):
            out[1:] = out[1:] + root * out[:-1]
        return out

    numerator = sum(tap * np.convolve(power(-alpha, k), power(1.0 - alpha, last - k))[:last + 1]
                    for k, tap in enumerate(taps))
    scale = period ** np.arange(last + 1)  # x^j = T^j s^j
    numerator = np.trim_zeros(numerator * scale * gain, "b")
    denominator = np.trim_zeros(power(1.0 - alpha, last) * scale, "b")
    return Block(name, tuple(numerator[::-1]), tuple(denominator[::-1]),
                 fir=tuple(gain * np.asarray(taps, dtype=float)))


def _padded(*polynomials):
    """The polynomials with leading zeros to a common width."""
    width = max(len(q) for q in polynomials)
    return tuple((0.0,) * (width - len(q)) + tuple(q) for q in polynomials)


def _derivative_window(p):
    """The PID's derivative window (:func:`moving_average`) of a sampled position loop over
    ``p.derivative_window`` > 1 periods, else None (one period, or continuous: its limit)."""
    window = getattr(p, "derivative_window", 1)
    rate = dict(getattr(p, "sample_rates", ())).get("position_loop")
    if window == 1 or not rate:
        return None
    return moving_average(window, 1.0 / rate, getattr(p, "sampling_method", "backward"))


def counts_difference(window, period, method):
    """The counts' difference over ``window`` periods of ``period`` [s], per second:
    :math:`(1 - z^{-m})/(m T)` (:func:`_fir_block`; s itself for m = 1 with the backward
    difference)."""
    m = int(window)
    taps = np.zeros(m + 1)
    taps[0], taps[m] = 1.0, -1.0
    return _fir_block(f"counts difference over {m} period{'s' if m > 1 else ''}", taps,
                      1.0 / (m * period), period, method)


def moving_average(window, period, method):
    r"""The mean of the last ``window`` samples, :math:`A_m(z) = (1/m) \sum_{k<m} z^{-k}`
    (:func:`_fir_block`): before a difference over one period, the difference over m."""
    m = int(window)
    return _fir_block(f"mean of {m} samples", np.ones(m), 1.0 / m, period, method)


def fir_state_space(block, n):
    """A digital FIR block (:attr:`Block.fir`) in discrete state space per run: the last m
    inputs as states (x_1 the latest), (A (n, m, m), B (n, m), C (n, m), D (n,))."""
    taps = np.asarray(block.fir, dtype=float)
    m = taps.size - 1
    a = np.zeros((n, m, m))
    a[:, 1:, :-1] = np.eye(m - 1)
    b = np.zeros((n, m))
    b[:, 0] = 1.0
    return a, b, np.broadcast_to(taps[1:], (n, m)).copy(), np.full(n, taps[0])


# --- the filters in state space (the simulator and the sampled plant) ---------------------

def block_state_space(block, n):
    """A (scaled) realisation (A, B, C, D) per run of a proper block of degree 1 or 2.

    Degree 2, denominator a2 s^2 + a1 s + a0 (a0, a2 > 0): w0 = sqrt(a0/a2), the states
    x1 = w0^2/den u and x2 = (w0 s/den) u (x1' = w0 x2, x2' = -w0 x1 - 2 zeta w0 x2 + w0 u).
    """
    num = [_per_run_values(c, n) for c in block.numerator]
    den = [_per_run_values(c, n) for c in block.denominator]
    order = len(den) - 1
    num = [np.zeros(n)] * (order + 1 - len(num)) + num
    lead = den[0]
    num = [c / lead for c in num]
    den = [c / lead for c in den]
    d = num[0]
    rest = [num[i] - d * den[i] for i in range(1, order + 1)]  # remainder over den (monic)
    if order == 1:
        a = -den[1][:, None, None]
        b = np.ones((n, 1))
        c = rest[0][:, None]
        return a, b, c, d
    if order == 2:
        w0 = np.sqrt(den[2])
        two_zeta_w0 = den[1]
        a = np.zeros((n, 2, 2))
        a[:, 0, 1] = w0
        a[:, 1, 0] = -w0
        a[:, 1, 1] = -two_zeta_w0
        b = np.zeros((n, 2))
        b[:, 1] = w0
        c = np.stack([rest[1] / (w0 * w0), rest[0] / w0], axis=1)
        return a, b, c, d
    raise ValueError(f"{block.name}: order {order} (the simulator steps orders 1 and 2)")


def series_state_space(first, second):
    """The state space of ``second`` after ``first`` (per run)."""
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    n, m1, m2 = a1.shape[0], a1.shape[1], a2.shape[1]
    a = np.zeros((n, m1 + m2, m1 + m2))
    a[:, :m1, :m1] = a1
    a[:, m1:, m1:] = a2
    a[:, m1:, :m1] = b2[:, :, None] * c1[:, None, :]
    b = np.concatenate([b1, b2 * d1[:, None]], axis=1)
    c = np.concatenate([d2[:, None] * c1, c2], axis=1)
    return a, b, c, d1 * d2


def chain_state_space(blocks, n):
    """Blocks in series (:func:`block_state_space` each, then :func:`series_state_space`):
    (A (n, m, m), B (n, m), C (n, m), D (n,))."""
    space = block_state_space(blocks[0], n)
    for block in blocks[1:]:
        space = series_state_space(space, block_state_space(block, n))
    return space


def _per_run_values(value, n):
    return np.broadcast_to(np.asarray(value, dtype=float), (n,)).astype(float)


def total_delay(p):
    """The largest sum of the loops' delays over the runs [s] (sets how finely a frequency grid
    must sample the phase)."""
    return float(np.max(sum(np.asarray(loop.delay, dtype=float) for loop in build(p).loops)))


def _runs(p):
    n = getattr(p, "n_runs", None)
    if n is not None:
        return n
    shapes = [np.shape(getattr(p, name)) for name in ("R", "ci_Kp", "cp_Kp", "J", "Km")]
    return max((shape[0] for shape in shapes if shape), default=1)
