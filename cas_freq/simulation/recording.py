"""The memory a batch records its signals into: :class:`RecordingBuffers` (kept between a
study's batches) and the batch's recording (:class:`Recording`) that the engines write into
(split from :mod:`~cas_freq.simulation.simulator`, which uses them)."""

import math

import numpy as np

from cas_freq.simulation.engine import FLAG_SIGNALS


class RecordingBuffers:
    """Memory that successive batches record into, kept between them (a study's chunks).

    A batch of 32 runs over the extended 0.2 s horizon records about 75 MB. Fresh memory for
    every chunk costs the operating system's page faults and zeroing, and the horizon's
    extension a copy into a buffer twice as large; kept here, the next chunk writes into
    memory already mapped, sized from the start for the longest horizon seen. A result's
    signals are views into this memory, valid until the next batch that records into the same
    buffers: take what is needed (figures, copies) before starting it.
    """

    def __init__(self):
        self._blocks = {}  # dtype -> the largest flat block handed out
        self.capacity = 0  # most columns a batch has recorded

    def array(self, shape, dtype):
        """A C-contiguous array of ``shape`` in the kept block of ``dtype`` (grown if needed)."""
        dtype = np.dtype(dtype)
        size = math.prod(shape)
        block = self._blocks.get(dtype)
        if block is None or block.size < size:
            block = self._blocks[dtype] = np.empty(size, dtype=dtype)
        return block[:size].reshape(shape)


class Recording:
    """The recorded signals of a batch, in buffers the compiled kernel writes into directly.

    Floats (n_float_signals, n_runs, capacity) and flags (2, n_runs, capacity); ``size``
    columns filled. A horizon extension grows the buffers (doubling, so every sample is copied
    at most about once more). With :class:`RecordingBuffers`, the buffers come from there,
    sized for the longest horizon that they have recorded.
    """

    def __init__(self, names, n_runs, capacity, buffers=None, limit=None):
        self.names = names
        self.limit = limit  # most columns the batch can record (its horizon's cap)
        self.floats_names = [name for name in names if name not in FLAG_SIGNALS]
        self.buffers = buffers
        if buffers is not None:
            capacity = buffers.capacity = max(capacity, buffers.capacity)
        self.floats = self._array((len(self.floats_names), n_runs, capacity), float)
        self.flags = self._array((len(FLAG_SIGNALS), n_runs, capacity), bool)
        self.times = []
        self.size = 0

    def _array(self, shape, dtype):
        if self.buffers is None:
            return np.empty(shape, dtype=dtype)
        return self.buffers.array(shape, dtype)

    def reserve(self, capacity):
        """Make room for ``capacity`` columns in all."""
        if capacity <= self.floats.shape[2]:
            return
        doubled = 2 * self.floats.shape[2]
        capacity = max(capacity, doubled if self.limit is None else min(doubled, self.limit))
        for attr in ("floats", "flags"):
            old = getattr(self, attr)
            new = np.empty(old.shape[:2] + (capacity,), dtype=old.dtype)
            new[:, :, :self.size] = old[:, :, :self.size]
            setattr(self, attr, new)
        if self.buffers is not None:
            self.buffers.capacity = max(self.buffers.capacity, capacity)

    def append(self, t, signals):
        """Copy in the samples at times ``t`` [s], ``signals`` name -> (n_runs, len(t))."""
        count = len(t)
        self.reserve(self.size + count)
        end = self.size + count
        for row, name in enumerate(self.floats_names):
            self.floats[row, :, self.size:end] = signals[name]
        for row, name in enumerate(FLAG_SIGNALS):
            self.flags[row, :, self.size:end] = signals[name]
        self.times.append(np.asarray(t, dtype=float))
        self.size = end

    def advance(self, engine, steps, record_every):
        """Advance ``engine`` by ``steps``, its samples written here (the compiled kernel
        writes them itself, the reference engine copies them in)."""
        rows = engine.recorded_rows(steps, record_every)
        self.reserve(self.size + rows)
        self.times.append(engine.advance_into(steps, record_every, self.floats, self.flags,
                                              self.size))
        self.size += rows

    def blank(self, runs, start, names):
        """NaN (False for the flags) in the signals ``names`` of ``runs`` (bool, n_runs) from
        column ``start`` on: the samples of runs that stopped."""
        if not runs.any() or start >= self.size:
            return
        for row, name in enumerate(self.floats_names):
            if name in names:
                self.floats[row, runs, start:self.size] = np.nan
        for row, name in enumerate(FLAG_SIGNALS):
            if name in names:
                self.flags[row, runs, start:self.size] = False

    def signals(self):
        """(times [s], name -> (n_runs, size) views) of everything recorded."""
        if len(self.times) > 1:
            self.times = [np.concatenate(self.times)]
        out = {name: self.floats[row, :, :self.size]
               for row, name in enumerate(self.floats_names)}
        out.update({name: self.flags[row, :, :self.size] for row, name in enumerate(FLAG_SIGNALS)})
        return self.times[0], {name: out[name] for name in self.names}
