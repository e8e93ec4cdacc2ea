"""The results of one variant in the Python API: its frequency responses
(:meth:`cas_freq.api.Actuator.frequency_response`), its analysis
(:meth:`~cas_freq.api.Actuator.analyze`), a step (:meth:`~cas_freq.api.Actuator.simulate`) and
a profile move (:meth:`~cas_freq.api.Actuator.simulate_profile`); each shows its headline
figures in a notebook and draws itself with ``plot()`` (matplotlib imported there)."""

import dataclasses
import types

import numpy as np

import cas_freq.analysis as analysis
from cas_freq.core.summary import Summary, row
from cas_freq.studies.profile_run import profile_run_dict
from cas_freq.studies.run import step_run_dict
from cas_freq.verify.measure import figure

#: The loops a :class:`FrequencyResponse` holds (``ActuatorLoops`` method names).
_LOOPS = ("current_loop", "current_closed_loop", "position_loop", "sensitivity", "closed_loop")


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class FrequencyResponse(Summary):
    """Complex frequency responses of one variant (each an array like ``omega_rad_s``).

    Attributes
    ----------
    omega_rad_s : numpy.ndarray
        Frequencies [rad/s].
    delay_model : str
        ``"exact"`` or ``"pade:N"``.
    current_loop, current_closed_loop : numpy.ndarray of complex
        L_i (broken at the voltage) and T_i = i/i_cmd [-].
    position_loop, sensitivity, closed_loop : numpy.ndarray of complex
        L_p (broken at the current command), S = 1/(1 + L_p) and T = delta/delta_cmd [-].
    output_symbol : str
        The output's symbol in the figure's labels: ``"δ"``, ``"x"`` at a linear output.
    described : tuple of cas_freq.report.data.CurveLoop
        The loops' symbols and break points, innermost first (the loop structure's).
    """

    omega_rad_s: np.ndarray
    delay_model: str
    current_loop: np.ndarray
    current_closed_loop: np.ndarray
    position_loop: np.ndarray
    sensitivity: np.ndarray
    closed_loop: np.ndarray
    output_symbol: str = "δ"
    described: tuple = ()

    def _summary(self):
        w = self.omega_rad_s
        symbols = {loop.name: loop.symbol for loop in self.described}
        shown = (symbols["current_loop"], "T_i", symbols["position_loop"], "S", "T")
        return (f"{', '.join(shown)} at {w.size} frequencies ({self.delay_model} delays)",
                [("lowest frequency", float(w.min()) if w.size else None, "rad/s"),
                 ("highest frequency", float(w.max()) if w.size else None, "rad/s"),
                 ("largest |T|", float(np.abs(self.closed_loop).max()) if w.size else None,
                  "")])

    def plot(self):
        """Bode plot of L_i, L_p and T (magnitude [dB] and phase [deg] axes).

        Returns
        -------
        matplotlib.figure.Figure
        """
        from cas_freq.api.figures import bode_figure

        return bode_figure(self)


class Analysis(analysis.Analysis):
    """What :meth:`Actuator.analyze` returns: a :class:`cas_freq.analysis.Analysis` (every
    figure, ``to_dict()``) that also draws itself (:meth:`plot`)."""

    @classmethod
    def of(cls, analysis):
        """The same figures as ``analysis`` (a :class:`cas_freq.analysis.Analysis`)."""
        return cls(**{field.name: getattr(analysis, field.name)
                      for field in dataclasses.fields(analysis)})

    def plot(self):
        """Bode of L_i, L_p and T: every crossover marked, the margins as bars and in the
        legend, the bandwidth on T (the report's open-loop figure with T added).

        Returns
        -------
        matplotlib.figure.Figure
            Magnitude [dB] and phase [deg] axes against frequency [rad/s]; in a notebook it
            displays itself.
        """
        if self.loaded is None:
            raise ValueError("this analysis holds no variant to plot (loaded=None); "
                             "analyze it with cas_freq.load(...).analyze()")
        from cas_freq.api.figures import analysis_figure

        return analysis_figure(self)


def _traces(run):
    """A simulated run's output and command: ((angle, command) [deg], (None, None)) at a
    rotary output, ((None, None), (position, command) [mm]) at a linear one."""
    r, unit = run.result, run.output_unit
    if unit.linear:
        return (None, None), (unit.from_si(r.delta), unit.from_si(r.command))
    return (np.degrees(r.delta), np.degrees(r.command)), (None, None)


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class StepResponse(Summary):
    """A simulated nonlinear output step.

    Attributes
    ----------
    time_s : numpy.ndarray
        Sample times [s].
    output_angle_deg, command_deg : numpy.ndarray or None
        Output angle and its command [deg] (None at a linear output).
    current_a, voltage_v : numpy.ndarray
        Motor current [A] and terminal voltage [V].
    step : cas_freq.simulation.step_figures.StepFigures
        Rise time, overshoot, settling times, peak, largest current and voltage.
    fit : cas_freq.simulation.second_order.SecondOrderFit
        The second-order-plus-delay fit (docs/model.md §7): wn, zeta, td with 95 % intervals,
        bandwidth.
    run : cas_freq.studies.run.StepRun
        Everything ``cas-freq simulate`` has (limit flags, simulation settings, ...).
    output_mm, command_mm : numpy.ndarray or None
        At a linear output (``gear.screw_lead``): its position and command [mm] (else None).
    """

    time_s: np.ndarray
    output_angle_deg: np.ndarray | None
    command_deg: np.ndarray | None
    current_a: np.ndarray
    voltage_v: np.ndarray
    step: object
    fit: object
    run: object
    output_mm: np.ndarray | None = None
    command_mm: np.ndarray | None = None

    @classmethod
    def of(cls, run):
        """The view of a :class:`cas_freq.studies.run.StepRun`."""
        angles, lengths = _traces(run)
        return cls(run.result.t, *angles, run.result.i, run.result.V, run.step, run.fit, run,
                   *lengths)

    def _summary(self):
        step, fit = self.step, self.fit
        rows = [(f"step.{name}", getattr(step, name))
                for name in ("rise_time_s", "overshoot_pct", "settling_time_s",
                             "max_current_a", "max_voltage_v", "current_limited")]
        rows += [(f"fit.{name}", getattr(fit, name))
                 for name in ("wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s")]
        size = self.run.output_unit.symbol(step.amplitude_deg)
        return f"{size} step of the {self.run.output} (nonlinear)", rows

    def to_dict(self):
        """JSON-ready dict: the JSON of ``cas-freq simulate --step ... --json``."""
        return step_run_dict(self.run)

    def plot(self):
        """Output angle with its command [deg], and motor current [A], against time [ms].

        Returns
        -------
        matplotlib.figure.Figure
        """
        from cas_freq.api.figures import step_figure

        return step_figure(self)


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class ProfileResponse(Summary):
    """A simulated profile move of the output (the config's feed-forward acting).

    Attributes
    ----------
    time_s : numpy.ndarray
        Sample times [s].
    output_angle_deg, command_deg : numpy.ndarray or None
        Output angle and profile command [deg] (None at a linear output).
    current_a, voltage_v : numpy.ndarray
        Motor current [A] and terminal voltage [V].
    profile : cas_freq.simulation.profile_figures.ProfileFigures
        Tracking error, overshoot, settling and arrival times, largest current and voltage.
    without_feedforward : cas_freq.simulation.profile_figures.ProfileFigures
        The same figures of the move with ff_v = ff_a = 0.
    run : cas_freq.studies.profile_run.ProfileRun
        Both runs and everything ``cas-freq simulate --profile`` has.
    output_mm, command_mm : numpy.ndarray or None
        At a linear output (``gear.screw_lead``): its position and command [mm] (else None).
    """

    time_s: np.ndarray
    output_angle_deg: np.ndarray | None
    command_deg: np.ndarray | None
    current_a: np.ndarray
    voltage_v: np.ndarray
    profile: object
    without_feedforward: object
    run: object
    output_mm: np.ndarray | None = None
    command_mm: np.ndarray | None = None

    @classmethod
    def of(cls, run):
        """The view of a :class:`cas_freq.studies.profile_run.ProfileRun`."""
        angles, lengths = _traces(run)
        return cls(run.result.t, *angles, run.result.i, run.result.V, run.profile,
                   run.without_feedforward, run, *lengths)

    def _summary(self):
        unit = self.run.output_unit
        names = ("tracking_error_max_deg", "tracking_error_rms_deg", "overshoot_pct",
                 "settling_time_s", "max_current_a", "max_voltage_v")
        keys = [f"profile.{unit.key(name)}" for name in names]  # the _mm twins if linear

        def value(figures, key):  # a figure of either run, in mm at a linear output
            if not unit.linear:
                return getattr(figures, key.partition(".")[2])
            return figure(types.SimpleNamespace(profile=figures), key)

        rows = [(key, value(self.profile, key)) for key in keys]
        rows += [(f"{label} (without feed-forward)", number, shown) for label, number, shown in
                 (row((key, value(self.without_feedforward, key))) for key in keys[:3])]
        rate = (f"{self.profile.peak_rate_deg_s:g}°/s" if not unit.linear else
                f"{unit.value(self.profile.peak_rate_deg_s):g} mm/s")
        return (f"{unit.symbol(self.profile.distance_deg)} move at {rate} "
                "peak rate (with the config's feed-forward)", rows)

    def to_dict(self):
        """JSON-ready dict: the JSON of ``cas-freq simulate --profile ... --json``."""
        return profile_run_dict(self.run)

    def plot(self):
        """Command and output angle [deg], and tracking error [deg], with and without
        feed-forward, against time [ms].

        Returns
        -------
        matplotlib.figure.Figure
        """
        from cas_freq.api.figures import profile_figure

        return profile_figure(self.run)
