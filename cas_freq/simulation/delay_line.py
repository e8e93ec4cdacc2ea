"""Transport delays as ring buffers of controller-output samples, read back with interpolation.

A controller output ``u`` is pushed once per simulation step ``dt``; the delayed signal
``u(t_k - tau)`` is read from the buffer. With ``tau = (m + f) dt`` (m integer, 0 <= f < 1):

- interpolating line (continuous controllers, first-order hold): the signal is linear between
  samples, and may jump at a sample (a step command passes straight through a PID's
  proportional and derivative terms). Each sample therefore keeps its left and right limits,
  and ``u(t_k - tau) = f u^+[k - m - 1] + (1 - f) u^-[k - m]`` (for f = 0, the left or right
  limit ``u^∓[k - m]`` as asked). This is exact for piecewise-linear signals with jumps on the
  grid, so a delayed jump arrives at exactly ``t + tau`` when tau is a whole number of steps.
- holding line (sampled controllers, zero-order hold): ``u[k - m - 1]`` if f > 0 else ``u[k - m]``
  (right limit; the left limit at a whole-step position is the previous sample).

Samples before t = 0 are 0 (the loop starts at rest). A delay shorter than one step (m = 0) cannot
read the sample not yet computed: it holds the newest sample instead, which adds up to ``dt`` of
delay.
"""

import numpy as np

#: Relative tolerance for deciding that a delay is a whole number of steps.
_WHOLE = 1e-9


def delay_steps(delay_s, dt):
    """A delay in steps: whole part m and fraction f, ``delay_s = (m + f) dt``.

    Parameters
    ----------
    delay_s : numpy.ndarray
        Delay of each run [s], shape (n_runs,), >= 0.
    dt : float
        Sample spacing [s].

    Returns
    -------
    tuple of numpy.ndarray
        m (int64) [steps] and f in [0, 1) [-] (0 within a relative 1e-9 of a whole step).
    """
    steps = np.asarray(delay_s, dtype=float) / dt
    whole = np.floor(steps + _WHOLE)
    frac = steps - whole
    frac[frac < _WHOLE] = 0.0
    return whole.astype(np.int64), frac


def ring_size(m):
    """Slots of a ring buffer for whole delays ``m`` [steps]: the longest plus 3."""
    return int(np.max(m)) + 3


class DelayLine:
    """Delay of ``delay_s`` [s] per run, for samples every ``dt`` [s].

    Parameters
    ----------
    delay_s : numpy.ndarray
        Delay of each run [s], shape (n_runs,), >= 0.
    dt : float
        Sample spacing [s].
    hold : bool
        Zero-order hold (sampled controllers) instead of linear interpolation.
    """

    def __init__(self, delay_s, dt, hold=False):
        self._m, frac = delay_steps(delay_s, dt)
        self.hold = hold
        self._f = frac
        self._size = ring_size(self._m)
        n = self._m.shape[0]
        self._cols = np.arange(n)
        self._zeros = np.zeros(n)
        self._right = np.zeros((self._size, n))
        self._left = self._right if hold else np.zeros((self._size, n))
        # Per slot: the sample was pushed without a jump (left limit = right limit).
        self._smooth = [True] * self._size
        self._latest = -1
        self._uniform = bool(np.all(self._m == self._m[0]) and not frac.any())
        self._m0 = int(self._m[0])
        #: True when reading t_k never uses sample k (every delay is at least one step).
        self.reads_past = bool(self._m.min() >= 1)
        # General path (per-run delays): which runs read the left buffer for each ``left``.
        self._whole = frac == 0
        self._hold_shift = (np.where(frac > 0, 1, 0), np.ones_like(self._m))
        self._near = 1.0 - frac

    @property
    def whole_steps(self):
        """True when every run's delay is a whole number of steps (no interpolation error)."""
        return not self._f.any()

    def push(self, k, right, left=None):
        """Store sample ``k``: the output's right limit at t_k (and its left limit).

        ``left`` None or the same array as ``right`` marks a sample without a jump.
        """
        slot = k % self._size
        self._right[slot] = right
        if not self.hold:
            smooth = left is None or left is right
            self._left[slot] = right if smooth else left
            self._smooth[slot] = smooth
        self._latest = k

    def read(self, k, left=False):
        """The delayed signal at t_k for every run: its right limit, or left limit if asked.

        Parameters
        ----------
        k : int
            Step index of the time read.
        left : bool
            Left limit (the value just before t_k) instead of the right limit.

        Returns
        -------
        numpy.ndarray
            A new array, shape (n_runs,).
        """
        if not self._uniform:
            return self._read_per_run(k, left)
        j = k - self._m0
        if self.hold:
            return self._sample(self._right, min(j - 1 if left else j, self._latest))
        if j > self._latest:
            return self._sample(self._right, self._latest)
        return self._sample(self._left if left else self._right, j)

    def read_limits(self, k):
        """Right and left limits of the delayed signal at t_k: the same array where no run jumps.

        Returns
        -------
        tuple of numpy.ndarray
            (right limit, left limit), as :meth:`read` gives them.
        """
        if not self._uniform or self.hold:
            return self.read(k), self.read(k, left=True)
        j = min(k - self._m0, self._latest)  # a read ahead of the newest sample holds it
        if j < 0:
            zeros = self._zeros.copy()
            return zeros, zeros
        slot = j % self._size
        right = self._right[slot].copy()
        if j < k - self._m0 or self._smooth[slot]:
            return right, right
        return right, self._left[slot].copy()

    def _sample(self, buffer, j):
        """Sample ``j`` of every run (0 before t = 0)."""
        return buffer[j % self._size].copy() if j >= 0 else self._zeros.copy()

    def _samples(self, buffer, j):
        """Sample ``j[r]`` of each run r (0 before t = 0)."""
        return np.where(j >= 0, buffer[j % self._size, self._cols], 0.0)

    def _read_per_run(self, k, left):
        j0 = k - self._m
        latest = self._latest
        if self.hold:
            return self._samples(self._right, np.minimum(j0 - self._hold_shift[left], latest))
        ahead = j0 > latest
        j0 = np.minimum(j0, latest)
        # The sample at j0: right limit where the read is ahead of the newest sample or (for
        # the right limit) the delay is whole; left limit elsewhere (interpolating from it).
        use_left = ~ahead if left else ~ahead & ~self._whole
        near = np.where(use_left, self._samples(self._left, j0), self._samples(self._right, j0))
        far = self._samples(self._right, j0 - 1)
        return np.where(ahead, near, self._near * near + self._f * far)
