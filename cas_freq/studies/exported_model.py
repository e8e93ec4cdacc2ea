r"""The actuator as the outer loop's designer uses it: ``cas-freq export-model`` and
``Actuator.export_model`` (docs/model.md §15).

One :class:`ExportedModel` holds

- the linear closed loop T = δ/δ_cmd with both delays Padé of a chosen order, as state-space
  matrices (A, B, C, D) and as zeros, poles and gain (python-control reads either:
  ``control.ss(A, B, C, D)``, ``control.zpk(zeros, poles, gain)``; a transfer function's
  polynomial coefficients are not exported: for the tens of states of a Padé model they lose
  all accuracy, docs/model.md §6); with sampled controllers the discrete-time T of
  :func:`cas_freq.analysis.systems.linear_model` with its period ``dt`` (z-plane poles and zeros);
- how far that model is from the exact-delay loop: max |T_N(jω) − T(jω)| on the analysis grid,
  the model's own ω_BW beside ``analyze``'s, and max |y_N(t) − y(t)| of its unit step against
  the tool's linear step (the report's, Padé order :data:`~cas_freq.model.DEFAULT_PADE_ORDER`);
- the amplitude-dependent gain and phase from the nonlinear loop's sine-dwell (amplitude ×
  frequency, :func:`cas_freq.studies.run.sinedwell_run`, the ``sinedwell`` command's grid
  by default) and, per amplitude, a second-order-plus-delay fit to the nonlinear step of that
  amplitude (ωn, ζ, td, its closed-form bandwidth) with the rate limit of the envelope;
- the rate and torque envelope (:mod:`cas_freq.analysis.rate_envelope`).

:meth:`ExportedModel.to_dict` is the JSON the command writes.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import json_ready
from cas_freq.core.output import output_json, output_unit
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import DEFAULT_PADE_ORDER, ActuatorLoops
from cas_freq.model.delay import MAX_PADE_ORDER
from cas_freq.model.structure import total_delay

#: The JSON's format name (a reader checks it).
FORMAT = "cas-freq actuator model 1"
#: Default Padé order of the exported T.
DEFAULT_EXPORT_PADE = 6

#: How to load the file in python-control (docs/howtos.md shows the same).
LOADER = (
    "import json, numpy as np, control\n"
    "m = json.load(open(PATH))['linear']\n"
    "T = control.ss(m['A'], m['B'], m['C'], m['D'], m['dt'] or 0)\n"
    "# zeros/poles/gain: T = gain * prod(s - z) / prod(s - p); control.zpk(...) multiplies\n"
    "# them out into polynomials, accurate at low Pade orders only: prefer the matrices"
)


@dataclasses.dataclass(frozen=True, eq=False)
class ExportedModel:
    """The exported actuator (module notes); :meth:`to_dict` is ``export-model``'s JSON.

    Attributes
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant.
    pade_order : int
        Padé order of both delays of the linear model (unused with sampled controllers).
    system : control.StateSpace
        T = δ/δ_cmd [-] (output per output command, SI), continuous or discrete (``dt``).
    accuracy : dict
        ``closed_loop_max_error``, ``bandwidth_rad_s`` (the model's), ``bandwidth_exact_rad_s``
        (``analyze``'s), ``step_max_error`` and ``step_reference``.
    dwell : cas_freq.studies.run.SineDwellRun
        Sine-dwell and nonlinear steps per amplitude.
    envelope : cas_freq.analysis.rate_envelope.RateEnvelope
    feedforward : bool
        Whether the feed-forward acted on the sine-dwell and the sine limits.
    stability : str
        ``"stable"``, ``"marginal"`` or ``"unstable"``: the linear closed loop's verdict.
    """

    loaded: object
    pade_order: int
    system: object
    accuracy: dict
    dwell: object
    envelope: object
    feedforward: bool = False
    #: The linear closed loop's verdict, as ``analyze`` gives it.
    stability: str = "stable"

    def to_dict(self):
        """JSON-ready dict (non-finite numbers become None)."""
        unit = output_unit(self.loaded.params)
        sys = self.system
        dt = sys.dt if sys.isdtime(strict=True) else None
        zeros, poles, gain = _zpk(sys)
        rate = "m_s" if unit.linear else "rad_s"
        linear = {
            "signal": f"T = output / output command [{unit.si}/{unit.si}]",
            "sampled": dt is not None,
            "dt": dt,
            "pade_order": None if dt is not None else self.pade_order,
            "delays": ("whole samples and the hold's fractional delay, exact (sampled "
                       "controllers)" if dt is not None else
                       f"Padé of order {self.pade_order}, both delays"),
            "A": np.asarray(sys.A).tolist(), "B": np.asarray(sys.B).tolist(),
            "C": np.asarray(sys.C).tolist(), "D": np.asarray(sys.D).tolist(),
            "zeros": [[z.real, z.imag] for z in zeros],
            "poles": [[p.real, p.imag] for p in poles],
            "gain": gain,
        }
        result = self.dwell.result
        table = None
        low_order = []
        if result is not None:
            table = {
                "amplitudes_deg": np.degrees(result.amplitudes_rad).tolist(),
                "frequencies_rad_s": result.frequencies_rad_s.tolist(),
                "magnitude_db": result.magnitude_db.tolist(),
                "phase_deg": result.phase_deg.tolist(),
                "limit_hit": result.limit_hit.tolist(),
                "bandwidth_rad_s": list(result.bandwidth_rad_s),
                "feedforward": self.feedforward,
            }
        for run in self.dwell.steps:
            fit = run.fit
            low_order.append({
                "amplitude_deg": run.step.amplitude_deg,
                "model": "wn^2 exp(-td s) / (s^2 + 2 zeta wn s + wn^2), rate-limited",
                "wn_rad_s": fit.wn_rad_s, "zeta": fit.zeta, "td_s": fit.td_s,
                "bandwidth_rad_s": fit.bandwidth_closed_form_rad_s,
                "fit_success": bool(fit.success),
                "fitted_to": "the nonlinear step of this amplitude",
                f"rate_limit_{rate}": self.envelope.no_load_rate_rad_s,
            })
        data = {
            "format": FORMAT,
            "config": self.loaded.params.name,
            "config_path": str(self.loaded.source),
            "variant": self.loaded.variant,
            "overrides": [f"{key}={value}" for key, value in self.loaded.overrides],
            "output": self.loaded.params.output_label,
            "output_unit": unit.si,
            "stability": self.stability,
            "linear": linear,
            "accuracy": self.accuracy,
            "sine_dwell": (table if table is not None else
                           {"not_computed": self.dwell.not_computed}),
            "low_order": low_order,
            "envelope": self.envelope.to_dict(unit),
            "loader": LOADER,
        }
        return json_ready(output_json(data, unit))


def _zpk(sys):
    """Zeros, poles (finite, complex) and the gain k of T = k prod(s - z) / prod(s - p)."""
    import control

    poles = _conjugate_pairs(np.asarray(control.poles(sys), complex))
    zeros = np.asarray(control.zeros(sys), complex)
    zeros = _conjugate_pairs(zeros[np.isfinite(zeros)])
    # the gain from the response at a point away from the poles and zeros
    s0 = (0.5 + 0.5j) if sys.isdtime(strict=True) else 1e-3j
    value = complex(np.squeeze(sys(s0)))
    gain = value * np.prod(s0 - poles) / np.prod(s0 - zeros)
    return zeros, poles, float(gain.real)


def _conjugate_pairs(roots):
    """The roots of a real polynomial with each complex pair made exactly conjugate (the
    eigenvalue solver leaves them conjugate to ~1e-12 only) and the real ones exactly real."""
    scale = np.maximum(np.abs(roots), 1.0)
    real = np.abs(roots.imag) <= 1e-9 * scale
    upper = roots[~real & (roots.imag > 0)]
    upper = upper[np.argsort(upper.real)]
    pairs = np.column_stack([upper, upper.conj()]).ravel()
    return np.concatenate([np.sort(roots[real].real).astype(complex), pairs])


def model_bandwidth(sys, omega):
    """ω_BW [rad/s] of ``sys`` (|T| 3.0103 dB below |T(0)|, docs/model.md §7: below 1 with a
    load spring and no integral action): the first grid crossing, refined by bisection on the
    system's own response; None without one."""
    from scipy.optimize import brentq

    zero = 1.0 if sys.isdtime(strict=True) else 0.0
    level = abs(complex(np.squeeze(sys(zero)))) * math.sqrt(0.5)

    def magnitude(w):
        if sys.isdtime(strict=True):
            return abs(complex(np.squeeze(sys(np.exp(1j * w * sys.dt))))) - level
        return abs(complex(np.squeeze(sys(1j * w)))) - level

    values = np.array([magnitude(w) for w in omega])
    below = np.flatnonzero(values < 0)
    if not below.size or below[0] == 0:
        return None
    k = below[0]
    return float(brentq(magnitude, omega[k - 1], omega[k], xtol=1e-12, rtol=1e-12))


def export_model(loaded, pade_order=DEFAULT_EXPORT_PADE, amplitudes_rad=None,
                 frequencies_rad_s=None, feedforward=False, progress=None):
    """The exported model of one variant (module notes).

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant.
    pade_order : int
        Padé order of both delays of the linear T, 1..MAX_PADE_ORDER.
    amplitudes_rad : sequence of float, optional
        Sine-dwell and step amplitudes at the output [rad or m]; default those of
        ``cas-freq sinedwell`` (0.5°, 2°, 10°; 0.1, 0.5, 2 mm at a linear output).
    frequencies_rad_s : sequence of float, optional
        Sine-dwell frequencies [rad/s]; default the ``sinedwell`` grid (16 points over
        0.1..5 × the linear ω_BW).
    feedforward : bool
        Let the feed-forward act on the sine-dwell and the sine limits (default off, as T).
    progress : callable, optional
        ``progress(done, planned)`` of the sine-dwell.

    Returns
    -------
    ExportedModel
    """
    from cas_freq.analysis import analyze
    from cas_freq.analysis.rate_envelope import rate_envelope
    from cas_freq.analysis.systems import linear_model
    from cas_freq.simulation.sinedwell import dwell_frequencies
    from cas_freq.studies.run import sinedwell_run

    if not (isinstance(pade_order, int) and 1 <= pade_order <= MAX_PADE_ORDER):
        raise CasFreqError(f"pade: must be an integer 1..{MAX_PADE_ORDER}, got {pade_order!r}")
    unit = output_unit(loaded.params)
    if amplitudes_rad is None:
        amplitudes_rad = ([1e-4, 5e-4, 2e-3] if unit.linear
                          else [math.radians(a) for a in (0.5, 2.0, 10.0)])
    analysis = analyze(loaded)
    params = LoopParameters.from_config(loaded.params)
    system = linear_model(params, pade_order).closed_loop
    accuracy = _accuracy(params, system, analysis, pade_order)
    dwell = sinedwell_run(loaded, amplitudes_rad, frequencies_rad_s, feedforward=feedforward,
                          progress=progress, analysis=analysis)
    omega = np.asarray(dwell.frequencies_rad_s if dwell.result is not None
                       else (dwell_frequencies(analysis) if analysis.stable else ()), float)
    envelope = rate_envelope(loaded.params, params, omega, feedforward=feedforward)
    return ExportedModel(loaded, pade_order, system, accuracy, dwell, envelope, feedforward,
                         analysis.stability.verdict)


def _held_step(system, t):
    """Unit step of a discrete-time ``system`` read at times ``t`` [s], each output sample held
    until the next (as the report draws a sampled loop's linear step)."""
    import control

    k = np.floor(t / system.dt + 1e-9).astype(int)
    samples = np.squeeze(control.step_response(system, T=np.arange(k.max() + 1) * system.dt)
                         .outputs)
    return np.atleast_1d(samples)[k]


def _accuracy(params, system, analysis, pade_order):
    """How far the exported model is from the exact-delay loop and from the tool's linear
    step (the :class:`ExportedModel` ``accuracy``)."""
    import control

    from cas_freq.analysis.frequency import DEFAULT_POINTS_PER_DECADE, frequency_grid
    from cas_freq.analysis.systems import linear_model

    low, high = analysis.frequency_range_rad_s
    omega = frequency_grid(low, high, DEFAULT_POINTS_PER_DECADE, total_delay(params))
    exact = ActuatorLoops(params).closed_loop(1j * omega)
    if system.isdtime(strict=True):
        nyquist = math.pi / system.dt
        omega, exact = omega[omega < nyquist], exact[omega < nyquist]
        model = np.squeeze(system(np.exp(1j * omega * system.dt)))
    else:
        model = np.squeeze(system(1j * omega))
    error = float(np.max(np.abs(model - exact))) if omega.size else None
    closed = analysis.closed_loop
    bandwidth = None
    if closed is not None and closed.bandwidth_rad_s is not None:
        bandwidth = model_bandwidth(system, omega)
    out = {"closed_loop_max_error": error,
           "closed_loop_error_range_rad_s": [float(omega[0]), float(omega[-1])]
           if omega.size else None,
           "bandwidth_rad_s": bandwidth,
           "bandwidth_exact_rad_s": None if closed is None else closed.bandwidth_rad_s,
           "step_max_error": None, "step_reference": None, "step_horizon_s": None,
           "step_points": None}
    if analysis.stable and bandwidth is not None:
        # a unit step over 20 time constants of the bandwidth, 2000 points
        t = np.linspace(0.0, 20.0 * 2.0 * math.pi / bandwidth, 2001)
        tool_system = linear_model(params, DEFAULT_PADE_ORDER).closed_loop
        if system.isdtime(strict=True):  # the output samples, each held until the next
            ours = _held_step(system, t)
            tool = _held_step(tool_system, t)
        else:
            ours = np.squeeze(control.step_response(system, T=t).outputs)
            tool = np.squeeze(control.step_response(tool_system, T=t).outputs)
        out["step_max_error"] = float(np.max(np.abs(ours - tool)))
        out["step_reference"] = (f"the tool's linear unit step (Padé order {DEFAULT_PADE_ORDER},"
                                 f" the report's) at {t.size} points over 0..{t[-1]:.4g} s")
        out["step_horizon_s"] = float(t[-1])
        out["step_points"] = int(t.size)
    return out
