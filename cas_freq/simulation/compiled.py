"""The batch engine of the compiled kernel: the interface of the reference Engine, its state in
numpy arrays between calls to the numba functions of :mod:`cas_freq.simulation.kernel`.

The engine builds the kernel's tables once (:func:`~cas_freq.simulation.kernel.tables`
and, for a batch with a loaded run, :func:`cas_freq.simulation.mechanics.table`), evaluates the
commands a block of steps at a time, and runs the parallel kernel unless another thread is
running it (the workqueue threading layer allows one at a time).
"""

import threading
import weakref

import numba
import numpy as np

import cas_freq.simulation.kernel as kernel
import cas_freq.simulation.mechanics as mech
from cas_freq.simulation.engine import LOAD_SIGNALS, SIGNALS, recorded_rows

#: Command values per kernel call, about (steps x columns) (memory of the command rows).
_BLOCK_VALUES = 2**18
#: Held while a thread runs the parallel kernel: the workqueue threading layer aborts the
#: process if two threads launch parallel kernels at once, so a batch that finds it held
#: (another thread, e.g. a dask worker thread, is simulating) runs serially instead.
_PARALLEL = threading.Lock()


#: The last batch's parameter tables, kept for the next batch of the same parameters (the
#: API's repeated steps of one actuator): (weak reference to its LoopParameters, dt, every,
#: method, the tables the kernel only reads).
_LAST_TABLES = [None]


def _tables(params, dt, every, method):
    """:func:`kernel.tables` of a batch, its read-only tables (the plant's, the loops', the
    filter chains') reused when the same LoopParameters object comes again with the same step
    and sampling (a sixth of a single step's time otherwise); the states always fresh."""
    key = (dt, tuple(sorted((every or {}).items())), method)
    last = _LAST_TABLES[0]
    if last is not None and last[0]() is params and last[1] == key:
        p, loops, chains, shapes = last[2]
        return (p, loops, np.zeros(shapes[0]), np.zeros(shapes[1]), chains,
                np.zeros(shapes[2]), np.zeros(shapes[3]), np.zeros(shapes[3]))
    built = kernel.tables(params, dt, every, method)
    p, loops, s, g, chains, z, ring_right, _ = built
    _LAST_TABLES[0] = (weakref.ref(params), key,
                       (p, loops, chains, (s.shape, g.shape, z.shape, ring_right.shape)))
    return built


class CompiledEngine:
    """State of a batch of runs, advanced by the compiled kernel (the interface of Engine).

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    commands : CommandSet
        Commands of every run.
    dt : float
        Step [s].
    every : dict, optional
        Loop name (:data:`~cas_freq.simulation.architecture.LOOPS`) -> update period of its
        sampled controller in steps; None or absent for a continuous one.
    method : {"backward", "tustin"}
        The sampled controllers' and filters' discretisation.
    """

    def __init__(self, params, commands, dt, every=None, method="backward"):
        n = params.n_runs
        self.dt = dt
        self.commands = commands
        # the loop table from the declared structure; every argument of the kernels has the
        # same type whatever the architecture, so that one compilation serves them all
        (self.p, self.loops, self.s, self.g, self.chains, self.z, *self.rings) = _tables(
            params, dt, every, method)
        # the loaded plant's table (mechanics.py), and 5 states where some run is loaded (an
        # unloaded run's row says so: the kernel steps it with the 3-state plant)
        self.loaded = loaded = bool(np.any(params.loaded))
        self.q = mech.table(params, dt) if loaded else np.zeros((n, mech.COLUMNS))
        #: Names of the signals of :meth:`sample` and :meth:`advance`.
        self.signals = SIGNALS + LOAD_SIGNALS if loaded else SIGNALS
        self.x = np.zeros((n, mech.NX if loaded else 3))
        self.k = 0
        self.record = kernel.record_mask(None, loaded)
        self.active = np.ones(n, dtype=np.bool_)
        #: After this time [s] the commands hold their values (CommandSet.held_from).
        self.held_from = commands.held_from()

    def record_only(self, names):
        """Record only the signals ``names`` (and theta; theta and omega in a loaded batch)
        from now on; the other rows of the recordings are not written."""
        self.record = kernel.record_mask(names, self.loaded)

    def stop(self, runs):
        """Advance the runs where ``runs`` (bool, n_runs) is True no further: their states and
        recordings stay as they are."""
        self.active &= ~np.asarray(runs, dtype=bool)

    def _rows(self, times):
        """Fin command rows at ``times``: right and left limits, each (len(t), 3, columns);
        one array for both where the command gives the same arrays for both (a sine away from
        its start: the kernel only reads them)."""
        right, left = self.commands.fin_limits(times)
        rows = []
        for limit in (right, left):
            if rows and all(a is b for a, b in zip(limit, right, strict=True)):
                return rows[0], rows[0]
            row = np.empty((times.shape[0], 3, limit[0].shape[1]))
            row[:, 0], row[:, 1], row[:, 2] = limit
            rows.append(row)
        return tuple(rows)

    def _args(self):
        return (self.p, self.loops, self.s, self.g, self.x, self.chains, self.z, *self.rings)

    def start(self):
        """Controller outputs at t = 0, then the sample at 0 (as Engine.start)."""
        right, left = self._rows(np.zeros(1))
        kernel.start_batch(*self._args(), right, left, self.dt)
        return tuple(np.array(value) for value in self.sample())

    def sample(self):
        """The recorded signals at the present step, in the order of :attr:`signals`."""
        return kernel.sample(self.loops, self.s, self.g, self.x, self.loaded)

    def recorded_rows(self, n_steps, record_every=1):
        """How many samples the next ``n_steps`` steps record."""
        return recorded_rows(self.k + 1, n_steps, record_every)

    def advance(self, n_steps, record_every=1):
        """Advance ``n_steps`` steps; record every ``record_every``-th sample (Engine.advance).

        Returns
        -------
        tuple of (numpy.ndarray, dict of str to numpy.ndarray)
            Times of the recorded samples [s] and each signal of :attr:`signals`, shape
            (n_runs, n_samples).
        """
        rows = self.recorded_rows(n_steps, record_every)
        names = kernel.FLOAT_SIGNALS + (LOAD_SIGNALS if self.loaded else ())
        # each run's samples contiguous (the kernel writes them run by run)
        floats = np.empty((len(names), self.x.shape[0], rows))
        flags = np.empty((2, self.x.shape[0], rows), dtype=np.bool_)
        t = self.advance_into(n_steps, record_every, floats, flags, 0)
        out = dict(zip(names, floats, strict=True))
        out["current_limited"], out["voltage_limited"] = flags
        return t, {name: out[name] for name in self.signals}

    def advance_into(self, n_steps, record_every, floats, flags, offset):
        """Advance ``n_steps`` steps, writing the recorded samples into ``floats`` (the float
        signals of :attr:`signals` in order, n_runs, capacity) and ``flags`` (2, n_runs,
        capacity) from column ``offset`` on; returns their times [s]."""
        first = self.k + 1
        base = -(-first // record_every)  # the first recorded step is base * record_every
        rows = recorded_rows(first, n_steps, record_every)
        n = self.x.shape[0]
        q = self.q
        block = max(64, _BLOCK_VALUES // (1 if n == 1 else self.commands.columns))
        parallel = n > 1 and numba.get_num_threads() > 1 and _PARALLEL.acquire(blocking=False)
        advance = kernel.advance_parallel if parallel else kernel.advance_serial
        try:
            for start in range(first, first + n_steps, block):
                stop = min(start + block, first + n_steps)
                if start * self.dt > self.held_from:  # one row holds for every step of the call
                    times = np.array([start * self.dt])
                else:
                    times = np.arange(start, stop) * self.dt
                right, left = self._rows(times)
                # the kernel writes sample j of this call at column j - (base - offset)
                advance(*self._args(), right, left, start - 1, record_every, base - offset,
                        floats, flags, self.dt, q, self.record, self.active, stop - start)
                self.k = stop - 1
        finally:
            if parallel:
                _PARALLEL.release()
        if self.loaded:
            kernel.rigid_fin(self.p, q, floats, slice(offset, offset + rows))
        return np.arange(base, base + rows) * record_every * self.dt


def threads():
    """Threads the kernel runs on (numba's, ``NUMBA_NUM_THREADS``)."""
    return numba.get_num_threads()
