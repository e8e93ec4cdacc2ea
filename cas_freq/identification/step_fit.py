r"""The report's second-order-plus-delay fit (:mod:`cas_freq.simulation.second_order`) of one
or several step recordings.

Each recording is fitted on its own (its samples from the trigger on, in units of its step), and
several recordings also together: one (ωn, ζ, td) for all runs at once, the least-squares fit of
the pooled unit-step samples (each run strided as its own fit is). The pooled fit's intervals
come from the same :math:`s^2 (J^T J)^{-1}` as each run's (docs/model.md), with the residual
variance of all runs pooled; the spread between the runs' own estimates (their standard
deviation) shows whether the runs differ by more than their intervals allow.
"""

import dataclasses

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.simulation.second_order import (
    MAX_FIT_POINTS,
    fit_second_order,
    fit_second_order_batch,
    second_order_step,
)
from cas_freq.simulation.step_figures import step_figures

#: Largest relative disagreement between a recording's commanded step and ``--step``.
STEP_TOLERANCE = 0.01

#: The fitted figures whose spread between runs is reported.
SPREAD_KEYS = ("wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s")


@dataclasses.dataclass(frozen=True, eq=False)
class RunFit:
    """The fit of one recording.

    Attributes
    ----------
    recording : Recording
        The data.
    step_rad : float
        Step size used [rad] (from the command column or the given one).
    step_source : str
        ``"command"`` or ``"given"``.
    figures : StepFigures
        Step figures of the data from the trigger on (rise, overshoot, settling).
    fit : SecondOrderFit
        (ωn, ζ, td) with ~95 % intervals; ``rms_residual`` [rad].
    model_rad : numpy.ndarray
        The fitted model at every sample of the recording [rad] (0 before the trigger).
    """

    recording: object
    step_rad: float
    step_source: str
    figures: object
    fit: object
    model_rad: np.ndarray

    @property
    def residual_rad(self):
        """Data less model at every sample [rad]."""
        return self.recording.position_rad - self.model_rad


@dataclasses.dataclass(frozen=True, eq=False)
class RecordingFits:
    """Fits of one or several recordings.

    Attributes
    ----------
    runs : list of RunFit
        One per recording, in order.
    joint : SecondOrderFit or None
        The one (ωn, ζ, td) of all runs at once (several recordings only); its
        ``rms_residual`` is a fraction of the step (the runs' steps may differ).
    spread : dict or None
        For each of :data:`SPREAD_KEYS`: mean, sample standard deviation, min and max of the
        runs' estimates (several recordings only).
    """

    runs: list
    joint: object
    spread: dict | None


def step_size(recording, given=None):
    """(step [rad], source) of a recording: its command's step, checked against ``given``.

    Raises
    ------
    ConfigError
        Without a command column and without ``given``, or when the two differ by more than
        :data:`STEP_TOLERANCE` of the given step.
    """
    measured = recording.step_rad
    if measured is None:
        if given is None:
            raise ConfigError(f"{recording.source}: no command column to take the step size "
                              "from; give it with --step (e.g. --step 10deg)")
        return float(given), "given"
    if given is not None and abs(measured - given) > STEP_TOLERANCE * abs(given):
        raise ConfigError(f"{recording.source}: the command column steps by "
                          f"{np.degrees(measured):.6g} deg but --step is "
                          f"{np.degrees(given):.6g} deg (more than "
                          f"{100 * STEP_TOLERANCE:g} % apart)")
    if measured == 0.0:
        raise ConfigError(f"{recording.source}: the command steps by 0")
    return float(measured), "command"


def _after(signal, recording):
    """``signal`` from the trigger on, or None."""
    return None if signal is None else signal[recording.after]


def fit_recordings(recordings, step_rad=None):
    """Second-order-plus-delay fit of each recording and, for several, of all at once.

    Parameters
    ----------
    recordings : sequence of Recording
        Step recordings (:func:`~cas_freq.identification.read_recording`).
    step_rad : float, optional
        The commanded step [rad] where a recording has no command column (checked against the
        command where it has one).

    Returns
    -------
    RecordingFits
    """
    recordings = list(recordings)
    steps = [step_size(recording, step_rad) for recording in recordings]
    times = [r.time_s[r.after] for r in recordings]
    responses = [r.position_rad[r.after] for r in recordings]
    try:
        fits = fit_second_order_batch(times, responses, [step for step, _ in steps])
        figures = [step_figures(t, y, step, current=_after(r.current_a, r),
                                voltage=_after(r.voltage_v, r))
                   for r, t, y, (step, _) in zip(recordings, times, responses, steps,
                                                 strict=True)]
    except ValueError as exc:
        raise ConfigError(f"{recordings[0].source}: {exc}") from None
    runs = [
        RunFit(recording=r, step_rad=step, step_source=source, figures=figure, fit=fit,
               model_rad=second_order_step(r.time_s, fit.wn_rad_s, fit.zeta, fit.td_s, step))
        for r, (step, source), figure, fit in zip(recordings, steps, figures, fits, strict=True)
    ]
    if len(runs) < 2:
        return RecordingFits(runs=runs, joint=None, spread=None)
    # each run strided as its own fit is (at most MAX_FIT_POINTS samples), then pooled
    strides = [max(1, -(-t.size // MAX_FIT_POINTS)) for t in times]
    pooled_t = np.concatenate([t[::k] for t, k in zip(times, strides, strict=True)])
    pooled_unit = np.concatenate([y[::k] / step for y, k, (step, _) in
                                  zip(responses, strides, steps, strict=True)])
    joint = fit_second_order(pooled_t, pooled_unit, 1.0, max_points=pooled_t.size)
    spread = {}
    for key in SPREAD_KEYS:
        values = np.array([getattr(run.fit, key) for run in runs])
        spread[key] = {"mean": float(values.mean()), "std": float(values.std(ddof=1)),
                       "min": float(values.min()), "max": float(values.max())}
    return RecordingFits(runs=runs, joint=joint, spread=spread)
