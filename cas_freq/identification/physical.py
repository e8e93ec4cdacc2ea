r"""Least-squares fit of config keys to step recordings through the nonlinear simulator.

The residuals are data less model at every sample from the trigger on, in blocks: the output
angle of each recording and, where used, its motor current. Each block b has its own noise
level :math:`\sigma_b`, estimated from the data as the block's RMS residual, so the fit
maximises the Gaussian likelihood with the variances concentrated out,

.. math::

    -2 \ln L = \sum_b n_b \left(\ln \frac{2\pi\,\mathrm{RSS}_b}{n_b} + 1\right),

by weighted least squares (:func:`scipy.optimize.least_squares`, trust-region reflective within
the keys' bounds) with the weights :math:`1/\sigma_b` updated until they settle. The
Jacobian is central differences of the coordinates (:mod:`~cas_freq.identification.free_keys`:
logarithms of positive keys) by :data:`RELATIVE_STEP`, every perturbed run of every recording
in one simulator batch (:class:`~cas_freq.identification.replay.RecordingReplayer`).

At the estimate, :math:`F = J_w^T J_w` (weighted Jacobian) gives the covariance
:math:`s^2 F^{-1}`, the ~95 % intervals (Student's t; ratios for log keys), the correlation
matrix and the identifiability (:mod:`~cas_freq.identification.identifiability`). The
intervals assume independent residuals; a model that does not fit the data leaves correlated
residuals and intervals that are too narrow: read them with the RMS residual.
"""

import dataclasses
import math

import numpy as np
from scipy import optimize, stats

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import variant_parameters
from cas_freq.identification.free_keys import free_keys, labels
from cas_freq.identification.identifiability import (
    UNBOUNDED,
    identifiability,
    relative_half_width,
    sum_combination,
    verdict,
)
from cas_freq.identification.probe import (
    NOT_IDENTIFIABLE,
    along_sum,
    held_coefficient,
    limit_of,
    probe,
    sum_factors,
)
from cas_freq.identification.replay import RecordingReplayer

#: Central-difference step of the fit coordinates (0.1 % of a positive key).
RELATIVE_STEP = 1e-3

#: The simulator's own resolution, as a fraction of a block's range: the smallest noise level a
#: block is given. A recording the simulator made itself, without noise, leaves a residual of
#: its round-off (~1e-9 of the range); a change of the output below this is not a change, so
#: that keys entering only as a sum, whose Jacobian columns differ by round-off alone, are not
#: told apart by it. A real encoder's quantum is ~1e-3 of a step, far above.
RESOLUTION = 1e-6

#: Reweighting passes at most, and the relative change of every sigma_b that ends them.
MAX_PASSES = 6
SIGMA_SETTLED = 0.01

#: Assumed current noise for the predicted identifiability with current data, as a fraction of
#: the fitted response's peak current (when the recordings have no current column).
ASSUMED_CURRENT_NOISE = 0.01

#: Confidence level of every interval.
LEVEL = 0.95

#: Width of the weak prior that holds each coordinate near its start [coordinate units: ln for
#: a log key, a factor e^6.9 = 1000]: it decides only where the data do not (a direction they
#: leave flat stays at the start instead of wandering), and shifts a determined one by less than
#: ~1e-4 of its interval.
PRIOR_WIDTH = math.log(1e3)


@dataclasses.dataclass(frozen=True, eq=False)
class Block:
    """One block of residuals: a recording's position or current over its fitted samples.

    ``noise`` is the spread (standard deviation) of the same signal before the fitted samples,
    where there are at least 5 such samples and they vary, else None.
    """

    recording: int
    channel: str
    data: np.ndarray
    noise: float | None = None

    def model(self, replay):
        """This block's (n_sets, n) model values from a Replay."""
        signals = replay.position if self.channel == "position" else replay.current
        return signals[self.recording]


@dataclasses.dataclass(frozen=True, eq=False)
class PhysicalFit:
    """A fitted model.

    Attributes
    ----------
    name : str
        The model's name.
    free : list of FreeKey
        Free keys, in order.
    estimate, start : numpy.ndarray
        Fitted and start values [SI].
    interval : numpy.ndarray
        (n_keys, 2) ~95 % interval [SI].
    standard_error : numpy.ndarray
        Standard error of each coordinate (relative for log keys).
    correlation : numpy.ndarray
        Correlation matrix of the estimates (coordinates).
    channels : tuple of str
        The data fitted: ``("position",)`` or ``("position", "current")``.
    sigma : dict
        (recording, channel) -> noise level estimated from the residual [rad or A].
    rms : dict
        channel -> {"fit": , "start": } RMS residual over every recording [rad] or [A].
    n_samples : int
        Residuals fitted.
    log_likelihood : float
        ln L at the estimate, the variances concentrated out.
    identifiability : dict
        ``"fitted"``: the Identifiability of the data fitted; ``"position"``: of the position
        alone (where current was fitted too); ``"with_current"``: with current added (measured
        if fitted, else predicted with :data:`ASSUMED_CURRENT_NOISE`).
    fitted_response, start_response : Replay
        The simulated recordings at the estimate and at the start.
    converged : bool
        Whether the optimiser met its tolerance (else it stopped at its evaluation limit).
    evaluations : int
        Simulator batches run.
    assumed_current_noise_a : float or None
        The current noise assumed for the predicted identifiability [A].
    masks : list of numpy.ndarray
        Per recording, the samples fitted (bool): from the trigger on for a step, from the
        command's first move on for another command.
    noise_ratio : dict
        (recording, channel) -> the fit's RMS residual over the spread of the samples before
        the fitted window (its noise, where there are at least 5 such samples and they vary):
        about 1 when the model follows the data to their noise; well above 1, the model does
        not (or the fit stopped in a local minimum: try other starts).
    at_bound : tuple
        Per key ``"lower"`` or ``"upper"`` where the estimate is at the search bound
        (:data:`~cas_freq.identification.free_keys.SEARCH_FACTOR` from the start, or the key's
        range), else None: the data pull it further than the fit may go.
    probes : dict
        ``"keys"``: per key, and ``"combinations"``: combination text ->, the
        :class:`~cas_freq.identification.probe.Probe` of its interval's ends simulated (the
        intervals and verdicts of the fitted data are the probed ones).
    """

    name: str
    free: list
    estimate: np.ndarray
    start: np.ndarray
    interval: np.ndarray
    standard_error: np.ndarray
    correlation: np.ndarray
    channels: tuple
    sigma: dict
    rms: dict
    n_samples: int
    log_likelihood: float
    identifiability: dict
    fitted_response: object
    start_response: object
    converged: bool
    evaluations: int
    assumed_current_noise_a: float | None
    masks: list
    noise_ratio: dict
    at_bound: tuple
    probes: dict

    @property
    def n_parameters(self):
        """Free keys plus one noise variance per block (what an information criterion counts)."""
        return len(self.free) + len(self.sigma)

    def criteria(self):
        """AIC, AICc and BIC of the fit [-]."""
        k, n = self.n_parameters, self.n_samples
        aic = -2.0 * self.log_likelihood + 2.0 * k
        aicc = aic + 2.0 * k * (k + 1) / (n - k - 1) if n > k + 1 else math.inf
        bic = -2.0 * self.log_likelihood + k * math.log(n)
        return {"aic": aic, "aicc": aicc, "bic": bic}


def _blocks(recordings, channels, masks):
    """The residual blocks of the recordings (their samples in ``masks``)."""
    blocks = []
    for index, (r, mask) in enumerate(zip(recordings, masks, strict=True)):
        before = r.time_s < r.time_s[mask][0]
        for channel in ("position", "current"):
            if channel not in channels:
                continue
            signal = r.position_rad if channel == "position" else r.current_a
            spread = float(np.std(signal[before])) if np.count_nonzero(before) >= 5 else 0.0
            blocks.append(Block(index, channel, signal[mask], spread or None))
    return blocks


def _resolution(block):
    """The smallest noise level a block is given [rad or A]: :data:`RESOLUTION` of its range."""
    return RESOLUTION * float(np.ptp(block.data)) or 1e-300


def _first_sigma(block):
    """A first noise level: the spread before the fitted samples, else 1 % of the block's
    range."""
    return block.noise or 0.01 * float(np.ptp(block.data)) or 1.0


class _Problem:
    """The residual function and its Jacobian, with a count of simulator batches."""

    def __init__(self, replayer, free, blocks):
        self.replayer, self.free, self.blocks = replayer, free, blocks
        self.sigma = np.ones(len(blocks))
        self.batches = 0
        self.x0 = np.array([f.coordinate(f.start) for f in free])

    def values(self, x):
        """Key -> value [SI] arrays of one or several coordinate vectors (rows of ``x``)."""
        x = np.atleast_2d(x)
        return {f.key: np.array([f.value(c) for c in x[:, j]]) for j, f in enumerate(self.free)}

    def replay(self, x):
        """The Replay of the coordinate vectors ``x`` (rows)."""
        self.batches += 1
        return self.replayer.replay(self.values(x))

    def stacked(self, replay, row=0, blocks=None, sigma=None):
        """Weighted residuals (model less data) / sigma of one parameter set, of ``blocks``
        with their ``sigma`` (default: the fitted blocks and their current sigma)."""
        if blocks is None:
            blocks, sigma = self.blocks, self.sigma
        return np.concatenate([(b.model(replay)[row] - b.data) / s
                               for b, s in zip(blocks, sigma, strict=True)])

    def residuals(self, x):
        """Weighted residuals, then the prior's rows."""
        return np.concatenate([self.stacked(self.replay(x)), (x - self.x0) / PRIOR_WIDTH])

    def jacobian_with_prior(self, x):
        """The Jacobian of :meth:`residuals`."""
        return np.vstack([self.jacobian(x), np.eye(len(x)) / PRIOR_WIDTH])

    def jacobian(self, x, blocks=None, sigma=None):
        """d(weighted residual)/d(coordinate) by central differences (one-sided at a bound),
        of ``blocks`` with their ``sigma`` (default the fitted ones)."""
        steps = []
        for j, f in enumerate(self.free):
            h = RELATIVE_STEP
            low, high = x[j] - h, x[j] + h
            if low < f.lower:
                low = x[j]
            if high > f.upper:
                high = x[j]
            steps.append((low, high))
        rows = []
        for j, (low, high) in enumerate(steps):
            for value in (low, high):
                row = np.array(x, dtype=float)
                row[j] = value
                rows.append(row)
        replay = self.replay(np.array(rows))
        columns = []
        for j, (low, high) in enumerate(steps):
            down = self.stacked(replay, 2 * j, blocks, sigma)
            up = self.stacked(replay, 2 * j + 1, blocks, sigma)
            columns.append((up - down) / (high - low))
        return np.column_stack(columns)


def fit_physical(loaded, recordings, steps_rad, spec, channels=("position",), max_batches=400):
    """Fit the free keys of ``spec`` to the recordings.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant (with any ``--set``) the keys start from and the rest is taken from.
    recordings : sequence of Recording
    steps_rad : sequence of float
        Each recording's step [rad].
    spec : ModelSpec
        The free keys (:func:`~cas_freq.identification.free_keys.parse_model_spec`).
    channels : tuple of str
        ``("position",)`` or ``("position", "current")`` (every recording needs a current
        column).
    max_batches : int
        Most simulator batches (evaluations and Jacobians) of the whole fit.

    Returns
    -------
    PhysicalFit

    Raises
    ------
    ConfigError
        For a key that cannot be fitted, or current asked of a recording without it.
    """
    recordings = list(recordings)
    if "current" in channels:
        missing = [r.source for r in recordings if r.current_a is None]
        if missing:
            raise ConfigError(f"{missing[0]}: no current column, so current cannot be fitted; "
                              "fit the position alone (--channels position)")
    free = free_keys(spec, variant_parameters(loaded.params, {}), loaded.variant, loaded.params)
    replayer = RecordingReplayer(loaded.params, recordings, steps_rad)
    blocks = _blocks(recordings, channels, replayer.masks)
    problem = _Problem(replayer, free, blocks)
    problem.sigma = np.array([_first_sigma(b) for b in blocks])
    x0 = problem.x0
    lower = np.array([f.lower for f in free])
    upper = np.array([f.upper for f in free])
    x, converged = x0, False
    for _ in range(MAX_PASSES):
        budget = max(1, (max_batches - problem.batches) // 2)
        solution = optimize.least_squares(
            problem.residuals, x, jac=problem.jacobian_with_prior, bounds=(lower, upper),
            method="trf", x_scale=1.0, xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=budget)
        x, converged = solution.x, solution.status > 0
        fitted = problem.replay(x)
        new = np.array([max(math.sqrt(np.mean((b.model(fitted)[0] - b.data) ** 2)),
                            _resolution(b)) for b in blocks])
        settled = np.all(np.abs(new / problem.sigma - 1.0) < SIGMA_SETTLED)
        problem.sigma = new
        if settled or problem.batches >= max_batches:
            break
    return _result(spec, free, problem, x, x0, fitted, channels, converged)


def _rms(blocks, replay, channel):
    """RMS of data less model over every block of ``channel`` (None if none)."""
    chosen = [b for b in blocks if b.channel == channel]
    if not chosen:
        return None
    return math.sqrt(np.mean(np.concatenate([(b.model(replay)[0] - b.data) ** 2
                                             for b in chosen])))


def _result(spec, free, problem, x, x0, fitted, channels, converged):
    """The PhysicalFit at the estimate ``x``."""
    blocks = problem.blocks
    weighted = problem.jacobian(x)
    n, p = weighted.shape
    residual = problem.stacked(fitted)
    # at least 1: a block's sigma is its RMS residual, or the simulator's resolution above it
    s2 = max(float(residual @ residual) / max(n - p, 1), 1.0)
    q = float(stats.t.ppf(0.5 + LEVEL / 2, max(n - p, 1)))
    found = {"fitted": identifiability(weighted.T @ weighted, free, x, s2, q)}
    assumed = None
    position = [(b, s) for b, s in zip(blocks, problem.sigma, strict=True)
                if b.channel == "position"]
    if "current" in channels:
        other = tuple(zip(*position, strict=True))  # the position alone
        name = "position"
    else:
        # predicted: current blocks of the simulated response with an assumed noise
        peak = max(float(np.max(np.abs(c[0]))) for c in fitted.current)
        assumed = ASSUMED_CURRENT_NOISE * peak
        extra = [Block(b.recording, "current", np.zeros(b.data.size)) for b, _ in position]
        other = (blocks + extra, np.concatenate([problem.sigma, np.full(len(extra), assumed)]))
        name = "with_current"
    rows = problem.jacobian(x, *other)
    found[name] = identifiability(rows.T @ rows, free, x, s2, q)
    covariance = found["fitted"].covariance
    error = np.sqrt(np.diag(covariance))
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(error, error)
    found["fitted"], interval, probes = _probed(problem, x, fitted, found["fitted"], s2, q)
    found[name] = _probed(problem, x, fitted, found[name], s2, q, *other)[0]
    if "current" in channels:
        found["with_current"] = found["fitted"]
    rss = {(b.recording, b.channel): float(np.sum((b.model(fitted)[0] - b.data) ** 2))
           for b in blocks}
    log_likelihood = -0.5 * sum(b.data.size * (math.log(2 * math.pi * rss[(b.recording,
                                b.channel)] / b.data.size) + 1.0) for b in blocks)
    start = problem.replay(x0)
    return PhysicalFit(
        name=spec.name, free=free,
        estimate=np.array([f.value(c) for f, c in zip(free, x, strict=True)]),
        start=np.array([f.start for f in free]), interval=interval, standard_error=error,
        correlation=correlation, channels=tuple(channels),
        sigma={(b.recording, b.channel): math.sqrt(rss[(b.recording, b.channel)]
                                                   / b.data.size) for b in blocks},
        rms={channel: {"fit": _rms(blocks, fitted, channel), "start": _rms(blocks, start, channel)}
             for channel in channels},
        n_samples=n, log_likelihood=log_likelihood, identifiability=found,
        fitted_response=fitted, start_response=start, converged=converged,
        evaluations=problem.batches, assumed_current_noise_a=assumed,
        masks=problem.replayer.masks,
        noise_ratio=_noise_ratios(blocks, rss),
        at_bound=tuple(_bound(f, c) for f, c in zip(free, x, strict=True)),
        probes=probes,
    )


def _probed(problem, x, fitted, found, s2, q, blocks=None, sigma=None):
    """(Identifiability, key intervals, probes) with every interval of ``found`` checked by
    simulating its ends (:func:`~cas_freq.identification.probe.probe`): a side that does not
    move the output is widened to what does, and what nothing moves is not identifiable.
    ``blocks`` and their ``sigma``: the data ``found`` is of (default the fitted ones)."""
    free = problem.free
    base = problem.stacked(fitted, 0, blocks, sigma)

    def moves(rows):
        try:
            replay = problem.replay(rows)
        except ConfigError:  # a row the config refuses (a drivetrain out of range): no model
            if len(rows) == 1:  # there, so no interval reaches it: an infinite move
                return np.full((1, base.size), math.inf)
            return np.vstack([moves(row[None, :]) for row in rows])
        return np.array([(problem.stacked(replay, k, blocks, sigma) - base) / math.sqrt(s2)
                         for k in range(len(rows))])

    def change(rows):
        return np.sum(moves(rows) ** 2, axis=1)

    combinations = found.determined + found.undetermined
    p = len(free)
    directions = np.vstack([np.eye(p), *([c.exponents] for c in combinations)])
    halves = [q * math.sqrt(found.covariance[j, j]) for j in range(p)]
    halves += [c.half_width for c in combinations]
    limits = [limit_of(f, c) for f, c in zip(free, x, strict=True)]
    limits += [UNBOUNDED] * len(combinations)
    bounds = (np.array([f.lower for f in free]), np.array([f.upper for f in free]))
    probes = probe(change, x, found.covariance, directions, halves, limits, bounds, q)
    for index, c in enumerate(combinations):
        if c.coefficients is not None and c.half_width <= UNBOUNDED:
            combinations[index] = _probed_sum(moves, free, x, c, halves, probes, q)
    keys, interval = [], []
    for j, (f, item, checked) in enumerate(zip(free, found.keys, probes[:p], strict=True)):
        low, high = (halves[j] * factor for factor in checked.factor)
        bounded = max(low, high) <= limits[j]
        interval.append((f.value(x[j] - low) if bounded else math.nan,
                         f.value(x[j] + high) if bounded else math.nan))
        keys.append(_reverdict(item, relative_half_width(max(low, high), f, x[j]), checked))
    kept = {}
    for c, checked in zip(combinations, probes[p:], strict=True):
        kept[c.text] = (_reverdict(c, c.half_width * max(checked.factor), checked), checked)
    determined = [c for c, _ in kept.values() if c.verdict == "well determined"]
    undetermined = [c for c, _ in kept.values() if c.verdict != "well determined"]
    found = dataclasses.replace(found, keys=keys, determined=determined,
                                undetermined=undetermined)
    return found, np.array(interval), {"keys": probes[:p], "combinations": {
        text: checked for text, (_, checked) in kept.items()}}


def _probed_sum(moves, free, x, combination, halves, probes, q):
    """The sum ``combination`` with its coefficients measured where the output held still,
    each of its keys' probe in ``probes`` widened by what moving it along the sum did."""
    coefficients = np.array(combination.coefficients)
    group = np.flatnonzero(coefficients)
    for j in group:  # each key of the sum, the sum held
        points = along_sum(x, combination.coefficients, j, halves[j])
        factors, held = sum_factors(moves, points, q * q)
        probes[j] = dataclasses.replace(probes[j], factor=tuple(
            max(a, b) for a, b in zip(probes[j].factor, factors, strict=True)))
        measured = (held_coefficient(x, combination.coefficients, j, held)
                    if j != group[0] else None)
        if measured is not None and measured > 0:
            coefficients[j] = measured  # where the sum held, rather than F's estimate
    values = np.array([f.value(c) for f, c in zip(free, x, strict=True)])
    return sum_combination(coefficients, free, labels(free), values, combination.half_width)


def _reverdict(item, half_width, checked):
    """A KeyVerdict or Combination with its probed half-width and verdict."""
    if not checked.widened:
        return item
    if not checked.identifiable:
        return dataclasses.replace(item, half_width=math.inf, verdict=NOT_IDENTIFIABLE)
    return dataclasses.replace(item, half_width=half_width, verdict=verdict(half_width))


def _noise_ratios(blocks, rss):
    """RMS residual over the pre-window spread, per block that has such a spread."""
    return {(b.recording, b.channel): math.sqrt(rss[(b.recording, b.channel)] / b.data.size)
            / b.noise for b in blocks if b.noise}


def _bound(free, coordinate, tolerance=1e-6):
    """``"lower"``/``"upper"`` where the coordinate sits at its bound, else None."""
    if coordinate <= free.lower + tolerance:
        return "lower"
    if coordinate >= free.upper - tolerance:
        return "upper"
    return None


__all__ = ["ASSUMED_CURRENT_NOISE", "LEVEL", "PhysicalFit", "RELATIVE_STEP", "fit_physical"]
