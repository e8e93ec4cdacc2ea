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
        steps = np.asarray(delay_s, dtype=float) / dt
        whole = np.floor(steps + _WHOLE)
        frac = steps - whole
        frac[frac < _WHOLE] = 0.0
        self.hold = hold
        self._m = whole.astype(np.int64)
        self._f = frac
        self._size = int(self._m.max()) + 3
        n = steps.shape[0]
        self._cols = np.arange(n)
        self._right = np.zeros((self._size, n))
        self._left = self._right if hold else np.zeros((self._size, n))
        self._latest = -1
        self._uniform = bool(np.all(self._m == self._m[0]) and not frac.any())

    @property
    def whole_steps(self):
        """True when every run's delay is a whole number of steps (no interpolation error)."""
        return not self._f.any()

    def push(self, k, right, left=None):
        """Store sample ``k``: the output's right limit at t_k (and its left limit)."""
        slot = k % self._size
        self._right[slot] = right
        if not self.hold:
            self._left[slot] = right if left is None else left
        self._latest = k

    def _row(self, buffer, j):
        if np.ndim(j) == 0:
            return buffer[j % self._size] if j >= 0 else np.zeros(self._cols.shape[0])
        return np.where(j >= 0, buffer[j % self._size, self._cols], 0.0)

    def read(self, k, left=False):
        """The delayed signal at t_k for every run: its right limit, or left limit if asked.

        Parameters
        ----------
        k : int
            Step index of the time read.
        left : bool
            Left limit (the value just before t_k) instead of the right limit.
        """
        latest = self._latest
        if self._uniform:
            j = k - int(self._m[0])
            if self.hold:
                return self._row(self._right, min(j - 1 if left else j, latest)).copy()
            if j > latest:
                return self._row(self._right, latest).copy()
            return self._row(self._left if left else self._right, j).copy()
        j0 = k - self._m
        if self.hold:
            shift = np.where(self._f > 0, 1, 1 if left else 0)
            return self._row(self._right, np.minimum(j0 - shift, latest))
        ahead = j0 > latest
        j0 = np.minimum(j0, latest)
        whole = self._f == 0
        near = self._row(self._left if left else self._right, j0)
        near = np.where(whole | ahead, near, self._row(self._left, j0))
        near = np.where(ahead, self._row(self._right, j0), near)
        far = self._row(self._right, j0 - 1)
        return np.where(ahead, near, (1.0 - self._f) * near + self._f * far)
