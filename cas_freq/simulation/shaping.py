r"""The command shaped before every loop (filters ``at: position_command``, docs/model.md
"Filters at any point"), as both engines read it.

The filters sit on the trajectory the drive is given, outside every loop, so they are applied
to the commands themselves: :class:`ShapedCommands` reads a
:class:`~cas_freq.simulation.engine.CommandSet` and gives the angle, rate and acceleration of
the shaped command in its place, evaluated step after step (the filters have a state). Both
engines take it as they take any command; the feed-forward reads the shaped rate and
acceleration.

**Continuous outermost loop.** The chain :math:`(A, B, C, D)` (a scaled realisation,
:func:`cas_freq.model.structure.chain_state_space`) is stepped exactly for an input linear over
the step (:class:`~cas_freq.simulation.architecture.FilterChain`), and at each step

.. math::
    y = C z + D u, \qquad \dot y = CA z + CB u + D \dot u, \qquad
    \ddot y = CA^2 z + CAB u + CB \dot u + D \ddot u

for the right and the left limits of the command u (a step passes through the direct term at
once; the rate of a shaped step is that of the shaped angle, not the step's Dirac).

**Sampled outermost loop.** The chain is digital, discretised at that loop's period by its
method (:func:`~cas_freq.simulation.architecture.filter_chain`), updated at its sampling
instants and held in between; it filters the angle, the rate and the acceleration of the
command alike (the drive's set-point filter on each of its three set-points), which is the
frequency domain's :math:`W(z)\,T` with the feed-forward.
"""

import numpy as np

from cas_freq.model.structure import chain_state_space
from cas_freq.simulation.architecture import filter_chain
from cas_freq.simulation.engine import CommandSet


def _shared(array):
    """The array's first run (a leading axis of 1) where every run has the same values."""
    return array[:1] if np.all(array == array[:1]) else array


class ShapedCommands:
    """The commands of every run through the filters ``blocks`` (the structure's
    :attr:`~cas_freq.model.structure.Structure.command`), evaluated at the steps 0, 1, 2, ...
    in order; what the engines read of a :class:`~cas_freq.simulation.engine.CommandSet`.

    Parameters
    ----------
    commands : cas_freq.simulation.engine.CommandSet
        The commands as given.
    blocks : tuple of cas_freq.model.structure.Block
        The filters in series, numbers per run.
    dt : float
        Step [s].
    every : int or None
        The outermost loop's update period in steps where it is sampled, else None.
    method : str
        The sampled loops' discretisation.
    """

    motor_limits = CommandSet.motor_limits

    def __init__(self, commands, blocks, dt, every=None, method="backward"):
        self.commands = commands
        self.ratio = commands.ratio
        n = self.ratio.shape[0]
        self.dt = dt
        self.every = every
        chain = filter_chain(blocks, n, dt, every, method)
        self.phi, self.g_a, self.g_b = (_shared(m) for m in (chain.phi, chain.g_a, chain.g_b))
        self.c, self.d = _shared(chain.c), _shared(chain.d)
        if every is None:  # the rows of the rate and the acceleration (module notes)
            a, b, c, _ = (_shared(m) for m in chain_state_space(blocks, n))
            ca = np.einsum("ri,rij->rj", c, a)
            self.ca, self.caa = ca, np.einsum("ri,rij->rj", ca, a)
            self.cb, self.cab = (np.einsum("ri,ri->r", row, b) for row in (c, ca))
        per_run = [self.phi, self.g_a, self.g_b, self.c, self.d]
        if every is None:
            per_run += [self.ca, self.caa, self.cb, self.cab]
        # n_runs columns where any number of the filters differs between runs
        self._columns = max(commands.columns, *(m.shape[0] for m in per_run))
        self._next = 0
        self._last = None

    @property
    def columns(self):
        """Columns of :meth:`fin_limits`: those of the commands, or n_runs where the filters'
        numbers differ between runs."""
        return self._columns

    def held_from(self):
        """A shaped command never holds its value exactly: inf."""
        return np.inf

    def fin_limits(self, t):
        """Right and left limits of the shaped (angle [rad], rate [rad/s], acceleration
        [rad/s^2]) at the steps ``t`` [s], each (len(t), columns): the next steps in order
        (the first call at t = 0), or the last ones again."""
        k = np.rint(np.asarray(t, dtype=float) / self.dt).astype(np.int64)
        if self._last is not None and np.array_equal(k, self._last[0]):
            return self._last[1]
        if k.size and k[0] == 0:
            self._next = 0
        if not np.array_equal(k, np.arange(self._next, self._next + k.size)):
            raise ValueError(f"a shaped command is evaluated step after step from t = 0; "
                             f"asked for steps {k[:3]}... after step {self._next - 1}")
        shape = (k.size, self._columns)
        right, left = (tuple(np.broadcast_to(part, shape) for part in limit)
                       for limit in self.commands.fin_limits(np.asarray(t, dtype=float)))
        out = self._held(k, right) if self.every else self._continuous(k, right, left)
        self._next += k.size
        self._last = (k, out)
        return out

    def _continuous(self, k, right, left):
        """The exactly stepped chain and its derivatives (module notes)."""
        m = self.phi.shape[1]
        if k[0] == 0:
            self.z = np.zeros((self._columns, m))
            self.u = right[0][0]
        z = np.empty((k.size, self._columns, m))
        for j in range(k.size):
            if k[j]:
                self.z = (np.einsum("rij,rj->ri", self.phi, self.z) + self.g_a * self.u[:, None]
                          + self.g_b * left[0][j][:, None])
            self.u = right[0][j]
            z[j] = self.z
        out = []
        for u, rate, acc in (right, left):
            y = np.einsum("ri,tri->tr", self.c, z)
            y_rate = np.einsum("ri,tri->tr", self.ca, z)
            y_acc = np.einsum("ri,tri->tr", self.caa, z)
            out.append((y + self.d * u, y_rate + self.cb * u + self.d * rate,
                        y_acc + self.cab * u + self.cb * rate + self.d * acc))
        return tuple(out)

    def _held(self, k, right):
        """The digital chain on each set-point, updated every ``every`` steps and held."""
        m = self.phi.shape[1]
        if k[0] == 0:
            self.z = np.zeros((3, self._columns, m))
            self.u = np.stack([part[0] for part in right])
            self.y = self.d * self.u
        out = np.empty((3, k.size, self._columns))
        for j in range(k.size):
            if k[j] and k[j] % self.every == 0:
                u = np.stack([part[j] for part in right])
                self.z = (np.einsum("rij,crj->cri", self.phi, self.z)
                          + self.g_a * self.u[:, :, None])
                self.u = u
                self.y = np.einsum("ri,cri->cr", self.c, self.z) + self.d * u
            out[:, j] = self.y
        held = tuple(out)
        return held, held
