r"""The plant's hold-equivalent: what a sampled controller's held output does to the signals
its loops measure, exact at the sampling instants (docs/model.md, section 14).

The controller's output is held (zero-order hold) and reaches the motor after the current
loop's delay :math:`\tau_c = mT + \varepsilon` (:math:`0 \le \varepsilon < T`). From the plant's
modes :math:`p_i` (eigenvalues of the state matrix of
:func:`cas_freq.model.parts.plant_matrices`), with :math:`\lambda_i = e^{p_i T}`:

.. math::
    P_y(z) = z^{-m} \sum_i \frac{w_{y,i}\,(g_{1,i} + g_{0,i} z^{-1})}{z - \lambda_i},
    \quad g_{1,i} = \int_0^{T-\varepsilon} e^{p_i \eta}\, d\eta, \quad
    g_{0,i} = e^{p_i (T - \varepsilon)} \int_0^{\varepsilon} e^{p_i \eta}\, d\eta

(:math:`w_{y,i}` the mode's residue in the measured signal y per volt). A measurement behind
analog filters (before its sampler) is the plant's modes through the filter plus the filter's
own modes, held exactly by matrix exponentials (:class:`AnalogPart`).
"""

import dataclasses
import types

import numpy as np

import cas_freq.model.parts as parts
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import ANALOG_POINTS, Filter
from cas_freq.core.threads import expm
from cas_freq.model.structure import SIGNALS, build, chain_state_space, filter_block, measured

#: A delay within this fraction of a whole number of periods counts as that number.
WHOLE = 1e-9

#: Plant fields of the hold-equivalent (those of :func:`cas_freq.model.parts.plant_matrices`).
PLANT_FIELDS = ("R", "L", "Ke", "Km", "J", "mu_v", "J_L", "b_L", "K_h", "K_g", "c_g", "ratio",
                "eta")

#: Above this condition number of its eigenvectors a plant's modes are not trusted.
_MODAL_CONDITION = 1e10


def _phi(x):
    """(e^x - 1)/x, 1 at x = 0."""
    small = np.abs(x) < 1e-12
    safe = np.where(small, 1.0, x)
    return np.where(small, 1.0 + 0.5 * x, np.expm1(safe) / safe)


@dataclasses.dataclass(frozen=True, eq=False)
class PlantModes:
    """The plant of every run as modes: poles (N, n) [rad/s] and, per measured signal, the
    residues (N, n) per volt; ``shape`` is the runs' shape in the parameters. ``filtered``:
    the measurements through analog filters (:func:`cas_freq.model.structure.measured` name
    -> :class:`AnalogPart`)."""

    poles: np.ndarray
    residues: dict
    shape: tuple
    filtered: dict = dataclasses.field(default_factory=dict)

    def pick(self, runs):
        """The modes of the runs ``runs`` (indices into a batch's runs)."""
        if not self.shape:
            return self
        return PlantModes(self.poles[runs], {k: v[runs] for k, v in self.residues.items()},
                          np.shape(runs), {k: v.pick(runs) for k, v in self.filtered.items()})


@dataclasses.dataclass(frozen=True, eq=False)
class AnalogPart:
    r"""A measurement through analog filters F (realisation :math:`A_f, B_f, C_f, D_f` of
    :func:`cas_freq.model.structure.chain_state_space`) split into the plant's modes and the
    filter's (:func:`plant_modes`):

    .. math::
        F(s) \sum_i \frac{w_i}{s - p_i} = \sum_i \frac{w_i F(p_i)}{s - p_i}
        + C_f (sI - A_f)^{-1} b_H, \qquad b_H = -\sum_i w_i (p_i I - A_f)^{-1} B_f

    (from :math:`F(s) - F(p) = (p - s)\, C_f (sI - A_f)^{-1} (pI - A_f)^{-1} B_f`). The first
    part takes the plant's modal formula with residues ``residues`` = :math:`w_i F(p_i)` (N, n);
    the second is held exactly by the filter's own discretisation (any filter, a double pole
    included): ``a`` :math:`A_f` (N, m, m), ``b`` :math:`b_H` (N, m), ``c`` :math:`C_f` (N, m).
    """

    residues: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray

    def pick(self, runs):
        """The runs ``runs``."""
        return AnalogPart(*(getattr(self, k)[runs] for k in ("residues", "a", "b", "c")))


def with_analog_filters(a, b, rows, chains):
    r"""The plant (A, B) with analog measurement filters in series on its signals (the sampled
    loops' state space, :mod:`cas_freq.model.state_space`).

    A filter chain :math:`(A_f, B_f, C_f, D_f)` on the signal :math:`y = C_y x`:
    :math:`A \to \begin{pmatrix} A & 0 \\ B_f C_y & A_f \end{pmatrix}`,
    :math:`B \to (B, 0)`, the filtered signal's row :math:`(D_f C_y, C_f)` (the plant is
    strictly proper: no direct term from V).

    Parameters
    ----------
    a, b : numpy.ndarray
        (n, s, s), (n, s, 1).
    rows : numpy.ndarray
        (n, r, s) output rows of the plant's signals.
    chains : list of (int, tuple)
        The row of the signal filtered and the chain's (A_f, B_f, C_f, D_f) of
        :func:`cas_freq.model.structure.chain_state_space`.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        A, B and the rows (the plant's, then one per chain in order), augmented.
    """
    for row, (af, bf, cf, df) in chains:
        n, states, order = a.shape[0], a.shape[-1], af.shape[-1]
        c_y = rows[:, row]
        big = np.zeros((n, states + order, states + order))
        big[:, :states, :states] = a
        big[:, states:, :states] = bf[:, :, None] * c_y[:, None, :]
        big[:, states:, states:] = af
        a = big
        b = np.concatenate([b, np.zeros((n, order, b.shape[-1]))], axis=1)
        rows = np.concatenate([np.pad(rows, ((0, 0), (0, 0), (0, order))),
                               np.concatenate([df[:, None] * c_y, cf], axis=1)[:, None]], axis=1)
    return a, b, rows


def plant_modes(p):
    """:class:`PlantModes` of the runs of ``p`` (each distinct plant decomposed once), with
    the measurements behind analog filters (:class:`AnalogPart`).

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters (scalars or arrays that broadcast over runs).

    Raises
    ------
    ConfigError
        For a plant whose poles are (nearly) repeated (its modes are not a basis), or an analog
        filter with a pole at one of the plant's.
    """
    analog = [item for item in getattr(p, "filters", ()) if item.at in ANALOG_POINTS]
    values = [np.asarray(getattr(p, name), dtype=float) for name in PLANT_FIELDS]
    values += [np.nan_to_num(np.asarray(getattr(item, name), dtype=float))
               for item in analog for name in Filter.NUMBERS]
    shape = np.broadcast_shapes(*(v.shape for v in values))
    flat = np.column_stack([np.broadcast_to(v, shape).reshape(-1) for v in values]) \
        if shape else np.array([[float(v) for v in values]])
    distinct, inverse = np.unique(flat, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    q = types.SimpleNamespace(**dict(zip(PLANT_FIELDS, distinct.T, strict=False)))
    a, b = parts.plant_matrices(q)
    poles, vectors = np.linalg.eig(a)
    if np.any(np.linalg.cond(vectors) > _MODAL_CONDITION):
        raise ConfigError("sampling: the plant has (nearly) repeated poles; its sampled "
                          "responses need distinct poles (change a drivetrain value slightly)")
    inputs = np.linalg.solve(vectors, b[:, :, :1].astype(complex))[..., 0]
    states = a.shape[-1]
    rows = np.zeros((distinct.shape[0], len(SIGNALS), states))
    rows[:, 0, 0] = rows[:, 1, 1] = rows[:, 2, 2] = 1.0
    rows[:, 3] = np.stack([parts.fin_output(states, r) for r in q.ratio])
    residues = (rows @ vectors) * inputs[:, None, :]  # (U, signals, states)
    filtered = {}
    if analog:
        structure = build(p)
        columns = iter(distinct[:, len(PLANT_FIELDS):].T)
        chains = {}
        for item in analog:  # the analog filters of the distinct runs, by the loop they are on
            numbers = {number: next(columns) for number in Filter.NUMBERS}
            chains.setdefault(ANALOG_POINTS[item.at], []).append(
                filter_block(types.SimpleNamespace(kind=item.kind, **numbers)))
        for name, chain in chains.items():
            loop = structure.loop(name)
            part = _analog_part(poles, residues[:, list(SIGNALS).index(loop.feedback)],
                                chain_state_space(chain, distinct.shape[0]), name)
            filtered[measured(loop)] = part.pick(inverse)
    return PlantModes(poles[inverse],
                      {name: residues[:, k][inverse] for k, name in enumerate(SIGNALS)},
                      shape, filtered)


def _analog_part(poles, residues, chain, name):
    """:class:`AnalogPart` of the filter ``chain`` (A_f, B_f, C_f, D_f) on a signal of modes
    ``poles`` and ``residues`` (U, n)."""
    af, bf, cf, df = chain
    order = af.shape[-1]
    shifted = poles[:, :, None, None] * np.eye(order) - af[:, None]  # p_i I - A_f
    if np.any(np.linalg.cond(shifted) > _MODAL_CONDITION):
        raise ConfigError(f"sampling: an analog filter on {name}'s measurement has a pole at "
                          "one of the plant's; change its frequency slightly")
    solved = np.linalg.solve(shifted, np.broadcast_to(bf[:, None, :, None].astype(complex),
                                                      (*shifted.shape[:-1], 1)))[..., 0]
    gains = np.einsum("um,unm->un", cf, solved) + df[:, None]  # F(p_i)
    b_h = -np.einsum("un,unm->um", residues, solved)
    return AnalogPart(residues * gains, af, b_h, cf)


def _analog_hold(part, shape, fraction, period, lead):
    r"""The polynomials of the filter part's hold-equivalent per run: with
    :math:`\Phi = e^{A_f T}`, :math:`G_1 = \int_0^{T-\varepsilon} e^{A_f\eta} d\eta`,
    :math:`G_0 = e^{A_f (T-\varepsilon)} \int_0^{\varepsilon} e^{A_f\eta} d\eta`,
    :math:`C_f (zI - \Phi)^{-1} (G_1 + G_0 z^{-1}) b_H` (the shift :math:`z^{-m}` apart) is
    :math:`\sum_{k<m} z^{-1-k} (\alpha_k + \beta_k z^{-1}) / \sum_{k \le m} c_k z^{-k}`,
    adj and det of :math:`zI - \Phi` by Faddeev-LeVerrier (exact for a repeated pole).

    ``shape``: the runs' shape of ``part`` (:attr:`PlantModes.shape`); ``fraction``: the
    delay's fractional part [s]; ``lead``: the shape both broadcast to.

    Returns (alpha, beta, c) of shapes (*lead, m), (*lead, m), (*lead, m + 1).
    """
    order = part.a.shape[-1]
    a = np.broadcast_to(part.a.reshape((*shape, order, order)),
                        (*lead, order, order)).reshape(-1, order, order)
    rest = np.broadcast_to(period - fraction, lead).reshape(-1)
    first = np.broadcast_to(fraction, lead).reshape(-1)

    def integral(h):  # (e^{A h}, int_0^h e^{A eta} d eta)
        m = np.zeros((a.shape[0], 2 * order, 2 * order))
        m[:, :order, :order] = a * h[:, None, None]
        m[:, :order, order:] = np.eye(order) * h[:, None, None]
        e = expm(m)
        return e[:, :order, :order], e[:, :order, order:]

    phi_rest, g1 = integral(rest)
    phi_first, g_first = integral(first)
    phi = phi_rest @ phi_first
    g0 = phi_rest @ g_first
    b = np.broadcast_to(part.b.reshape((*shape, order)), (*lead, order)).reshape(-1, order)
    c = np.broadcast_to(part.c.reshape((*shape, order)), (*lead, order)).reshape(-1, order)
    adjugate = np.broadcast_to(np.eye(order), phi.shape)
    coefficients = [np.ones(a.shape[0])]
    alpha, beta = [], []
    for k in range(1, order + 1):
        alpha.append(np.einsum("rm,rmn,rn->r", c, adjugate @ g1, b))
        beta.append(np.einsum("rm,rmn,rn->r", c, adjugate @ g0, b))
        product_ = phi @ adjugate
        coefficients.append(-np.trace(product_, axis1=1, axis2=2) / k)
        adjugate = product_ + coefficients[-1][:, None, None] * np.eye(order)
    return (np.stack(alpha, -1).reshape((*lead, order)),
            np.stack(beta, -1).reshape((*lead, order)),
            np.stack(coefficients, -1).reshape((*lead, order + 1)))


def hold_equivalent(modes, tau, period, omega):
    r"""The plant's hold-equivalent :math:`P_y(e^{j\omega T})` per measured signal.

    Parameters
    ----------
    modes : PlantModes
    tau : float or numpy.ndarray
        Delay between the held controller output and the motor [s] (broadcasting over the
        runs as the parameters do).
    period : float
        T [s].
    omega : numpy.ndarray
        Frequencies [rad/s], broadcasting with the runs' shape (leading axes allowed).

    Returns
    -------
    dict of str to numpy.ndarray
        Signal name -> complex response [unit per volt].
    """
    states = modes.poles.shape[1]
    p = modes.poles.reshape((*modes.shape, states))
    tau = np.asarray(tau, dtype=float)[..., None]
    whole = np.floor(tau / period + WHOLE)
    fraction = tau - whole * period
    fraction = np.where(fraction < WHOLE * period, 0.0, fraction)
    g1 = (period - fraction) * _phi(p * (period - fraction))
    g0 = np.exp(p * (period - fraction)) * fraction * _phi(p * fraction)
    lam = np.expm1(p * period)
    z_minus_1 = np.expm1(1j * omega * period)
    z_inverse = np.exp(-1j * omega * period)
    kernels = [(g1[..., i] + g0[..., i] * z_inverse) / (z_minus_1 - lam[..., i])
               for i in range(states)]
    shift = z_inverse ** whole[..., 0]
    out = {}
    for name, residue in modes.residues.items():
        residue = residue.reshape((*modes.shape, states))
        out[name] = shift * sum(residue[..., i] * kernel for i, kernel in enumerate(kernels))
    lead = np.broadcast_shapes(modes.shape, fraction.shape[:-1])
    for name, part in modes.filtered.items():  # the plant's modes, then the filter's
        residue = part.residues.reshape((*modes.shape, states))
        plant_part = sum(residue[..., i] * kernel for i, kernel in enumerate(kernels))
        alpha, beta, c = _analog_hold(part, modes.shape, fraction[..., 0], period, lead)
        order = alpha.shape[-1]
        numerator = sum(z_inverse ** (1 + k) * (alpha[..., k] + beta[..., k] * z_inverse)
                        for k in range(order))
        denominator = sum(c[..., k] * z_inverse ** k for k in range(order + 1))
        out[name] = shift * (plant_part + numerator / denominator)
    return out
