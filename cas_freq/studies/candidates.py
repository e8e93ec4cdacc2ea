"""Candidate structures fitted to the same recordings and ranked side by side (``cas-freq fit
--candidates FILE``, ``Actuator.rank_candidates``; docs/identification.md).

For every candidate (:mod:`cas_freq.identification.candidates`): its estimates with 95 %
intervals and identifiability, the RMS residual, AICc and BIC (which charge its free
parameters), whether its values are plausible (within the ranges a datasheet or the report
gives), its simulated step at the bench's amplitude (rise, overshoot, settling) and that step's
second-order-plus-delay fit (ωn, ζ, td), beside the recording's own and the config's
``reference:`` (the bench as the report gives it). The ranking puts the plausible, determined
candidates first, each group by AICc.
"""

import dataclasses
import math
import time

import numpy as np

from cas_freq.config.loader import load_variant, parse_set_option
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import json_ready
from cas_freq.identification import read_recording
from cas_freq.identification.candidates import plausibility, read_candidates
from cas_freq.identification.fit_summary import comparison, fit_dict, fitted_channels
from cas_freq.identification.physical import fit_physical
from cas_freq.identification.probe import NOT_IDENTIFIABLE
from cas_freq.identification.step_fit import step_size
from cas_freq.simulation.second_order import fit_second_order
from cas_freq.simulation.step_figures import step_figures
from cas_freq.studies.run import step_runs

#: Identifiability verdicts that flag a candidate: the data do not determine one of its keys.
FLAGGED = (NOT_IDENTIFIABLE, "not determined")

#: A residual this many times the pre-trigger noise is a misfit (as ``fit --params`` says).
MISFIT = 2.0

#: The verdict of a candidate whose values are all within their plausible ranges.
PLAUSIBLE = "plausible"


@dataclasses.dataclass(frozen=True, eq=False)
class Ranking:
    """Candidates fitted to recordings, ranked.

    Attributes
    ----------
    data : dict
        JSON-ready: the recordings, the bench's and the recording's step figures, the ranking
        (one row per candidate, best first) and each candidate's fit.
    recordings : list of Recording
    fits : list of PhysicalFit
        In the ranking's order.
    best : str or None
        The best plausible, determined candidate (None if there is none).
    output : str
        What the labels call the output.
    """

    data: dict
    recordings: list
    fits: list
    best: str | None
    output: str = "output"


def _step_dict(figures, fit):
    """The step figures and second-order fit that the ranking shows, in ms, % and rad/s."""
    return {
        "rise_time_ms": 1e3 * figures.rise_time_s,
        "overshoot_pct": figures.overshoot_pct,
        "settling_time_ms": 1e3 * figures.settling_time_s,
        "wn_rad_s": fit.wn_rad_s, "zeta": fit.zeta, "td_ms": 1e3 * fit.td_s,
    }


def _recording_step(recording, step):
    """The step figures and second-order fit of a recording's own samples from the trigger."""
    after = recording.time_s >= 0
    t, delta = recording.time_s[after], recording.position_rad[after]
    return _step_dict(step_figures(t, delta, step), fit_second_order(t, delta, step))


def _reference(params):
    """The config's ``reference:`` step figures and fit (the bench as the report gives it),
    or None."""
    ref = getattr(params, "reference", None)
    if ref is None or ref.rise_time is None:
        return None
    fit = ref.fit
    return {
        "source": ref.source,
        "step_deg": None if ref.step_amplitude is None else math.degrees(ref.step_amplitude),
        "rise_time_ms": 1e3 * ref.rise_time,
        "overshoot_pct": ref.overshoot_pct,
        "settling_time_ms": None if ref.settling_time is None else 1e3 * ref.settling_time,
        "wn_rad_s": None if fit is None else fit.wn,
        "zeta": None if fit is None else fit.zeta,
        "td_ms": None if fit is None or fit.td is None else 1e3 * fit.td,
    }


def _about(path):
    """The first comment line of a recording (how a stand-in says what it is), or ""."""
    try:
        with open(path, encoding="utf-8") as handle:
            first = handle.readline().strip()
    except OSError:
        return ""
    return first.lstrip("#").strip() if first.startswith("#") else ""


def rank(rows):
    """The ranking: plausible and determined candidates first, each group by AICc."""
    return sorted(rows, key=lambda row: (row["plausibility"] != PLAUSIBLE, row["flagged"],
                                         row["aicc"]))


def rank_candidates(base, candidates_path, recording_paths, columns=None, step=None,
                    channels=None):
    """Fit every candidate of a candidates file to the recordings and rank them.

    Parameters
    ----------
    base : cas_freq.config.LoadedVariant
        The variant (with its overrides) every candidate starts from.
    candidates_path : str or Path
        The candidates file (:func:`~cas_freq.identification.candidates.read_candidates`).
    recording_paths : sequence of str or Path
        Step recordings (CSV, :func:`~cas_freq.identification.read_recording`).
    columns : dict, optional
        ``role -> header cell`` naming recording columns outright.
    step : float, optional
        The commanded step [rad] for recordings without a command column (and checked
        against the command within 1 %).
    channels : str, optional
        ``"position"`` or ``"position,current"`` (default: position, and current where every
        recording has it).

    Returns
    -------
    Ranking

    Raises
    ------
    ConfigError
        For a bad candidates file or recording, or a linear output (a recording is read as
        angles).
    """
    if base.params.linear:
        raise ConfigError(f"--candidates: {base.params.name} has a linear output "
                          "(gear.screw_lead); recordings are read as angles (deg or rad), so "
                          "this version does not fit them for a linear output")
    candidates = read_candidates(candidates_path, base.params)
    recordings = [read_recording(path, columns) for path in recording_paths]
    steps = [step_size(r, step)[0] for r in recordings]
    fitted_to = fitted_channels(channels, recordings)
    reference = _reference(base.params)
    amplitude = (math.radians(reference["step_deg"]) if reference and reference["step_deg"]
                 else steps[0])

    def variant(overrides):
        extra = tuple(parse_set_option(text) for text in overrides)
        return load_variant(base.source, base.variant, (*base.overrides, *extra))

    results = {}
    for candidate in candidates:
        start = time.perf_counter()
        fit = fit_physical(variant(candidate.overrides), recordings, steps, candidate.spec,
                           fitted_to)
        fitted = [f"{free.key}={float(value)!r}"
                  for free, value in zip(fit.free, fit.estimate, strict=True)]
        run = step_runs([variant([*candidate.overrides, *fitted])], amplitude)[0]
        results[candidate.name] = (candidate, fit, fit_dict(fit, time.perf_counter() - start),
                                   run)
    rows = comparison([fit for _, fit, _, _ in results.values()])
    for row in rows:
        candidate, fit, model, run = results[row["name"]]
        verdict, reasons = plausibility(candidate, fit)
        unknown = [k["key"] for k in model["keys"] if k["verdict"] in FLAGGED]
        row.update({
            "source": candidate.source, "set": list(candidate.overrides),
            "plausibility": verdict, "implausible": reasons, "flagged": bool(unknown),
            "not_determined": unknown, "step": _step_dict(run.step, run.fit),
            "residual_over_noise": max((item["ratio"] for item in model["residual_over_noise"]),
                                       default=None),
            "linear_stability": run.linear_stability,
        })
    rows = rank(rows)
    for number, row in enumerate(rows, 1):
        row["rank"] = number
    best = next((row["name"] for row in rows
                 if row["plausibility"] == PLAUSIBLE and not row["flagged"]), None)
    data = json_ready({
        "config_path": base.source, "variant": base.variant,
        "overrides": [f"{k}={v}" for k, v in base.overrides],
        "candidates_file": str(candidates_path),
        "recordings": [{"source": r.source, "about": _about(r.source)} for r in recordings],
        "steps_deg": [math.degrees(s) for s in steps],
        "step_deg": math.degrees(amplitude),
        "recording_step": _recording_step(recordings[0], steps[0]),
        "reference": reference, "ranking": rows, "best_plausible": best,
        "models": [results[row["name"]][2] for row in rows],
    })
    return Ranking(data, recordings, [results[row["name"]][1] for row in rows], best,
                   base.params.output_label)


def _cell(value, digits=3):
    return "—" if value is None or not np.isfinite(value) else f"{value:.{digits}g}"


def _step_cells(step):
    return (f"{_cell(step['rise_time_ms'])} ms {_cell(step['overshoot_pct'])} % "
            f"{_cell(step['settling_time_ms'])} ms | wn {_cell(step['wn_rad_s'])} "
            f"zeta {_cell(step['zeta'], 2)} td {_cell(step['td_ms'], 2)} ms")


def ranking_text(data):
    """Text of a ranking (``data``: :attr:`Ranking.data`)."""
    lines = [f"{data['config_path']} / {data['variant']}: {len(data['ranking'])} candidate "
             f"structures fitted to {len(data['recordings'])} recording(s) "
             f"({data['candidates_file']})"]
    for r in data["recordings"]:
        lines.append(f"  {r['source']}" + (f": {r['about']}" if r["about"] else ""))
    lines += ["", f"  {'#':>2} {'candidate':<22} {'keys':>4} {'rms deg':>8} {'dAICc':>8} "
              f"{'dBIC':>8}  verdict"]
    for row in data["ranking"]:
        flag = ("; FLAGGED: not determined " + ", ".join(row["not_determined"])
                if row["flagged"] else "")
        lines.append(f"  {row['rank']:>2} {row['name']:<22} {row['free_keys']:>4} "
                     f"{row['rms_position_deg']:>8.4g} {row['delta_aicc']:>8.4g} "
                     f"{row['delta_bic']:>8.4g}  {row['plausibility']}{flag}")
    lines += ["", f"  {data['step_deg']:g} deg step: rise, overshoot, settling | second-order "
              "fit"]
    if data["reference"]:
        lines.append(f"  {'bench (reference:)':<24} {_step_cells(data['reference'])}")
    lines.append(f"  {'recording':<24} {_step_cells(data['recording_step'])}")
    for row in data["ranking"]:
        lines.append(f"  {row['name']:<24} {_step_cells(row['step'])}")
    for row, model in zip(data["ranking"], data["models"], strict=True):
        lines += ["", f"  {row['rank']}. {row['name']} ({row['source']})"
                  + (f"; set {', '.join(row['set'])}" if row["set"] else "")]
        for key in model["keys"]:
            low, high = key["ci95"]
            interval = "—" if low is None else f"[{low:.4g}, {high:.4g}]"
            lines.append(f"     {key['key']:<26} {key['estimate']:.5g} {key['unit']}  95 % "
                         f"{interval}  {key['verdict']}")
        ratio = row["residual_over_noise"]
        if ratio is not None and ratio > MISFIT:
            lines.append(f"     MISFIT: its residual is {ratio:.3g}x the noise before the "
                         "trigger: it does not follow the recording's shape")
        lines += [f"     not plausible: {reason}" for reason in row["implausible"]]
        if row["linear_stability"] != "stable":
            lines.append(f"     its linear closed loop is {row['linear_stability']}")
    lines += ["", "  best plausible, determined candidate: "
              f"{data['best_plausible'] or 'none'}"]
    return "\n".join(lines)


__all__ = ["Ranking", "rank", "rank_candidates", "ranking_text"]
