"""``cas-freq fit [CONFIG] --data FILE...``: the second-order fit of bench step recordings.

Each recording's step figures and (wn, zeta, td) with ~95 % intervals, RMS residual and
closed-form bandwidth; with several, the joint fit and the spread between runs; beside them, the
step figures and fit of CONFIG's base variant simulated for the same step
(:func:`cas_freq.studies.run.step_batch`). ``-o DIR`` writes fit.json and fit.svg.
"""

import dataclasses
import math

from cas_freq.cli.common import column_option, refuse_linear, selected_variants, write_and_print
from cas_freq.core.figures import FIGURES
from cas_freq.core.fileio import json_ready
from cas_freq.core.output import angle
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text


def _fit_dict(fit, unit_step=False):
    """JSON-ready fields of a SecondOrderFit; ``rms_residual`` [rad], or of the step if
    ``unit_step``."""
    data = dataclasses.asdict(fit)
    rms = data.pop("rms_residual")
    data["rms_residual_of_step" if unit_step else "rms_residual_rad"] = rms
    return data


def results(fits, model_runs, config):
    """The JSON-ready dict of the fits (and of the config's simulated steps)."""
    import numpy as np

    recordings = []
    for run in fits.runs:
        r = run.recording
        fit = _fit_dict(run.fit)
        fit["rms_residual_of_step"] = run.fit.rms_residual / abs(run.step_rad)
        recordings.append({
            "source": r.source,
            "samples": int(np.count_nonzero(r.after)),
            "pre_trigger_samples": int(np.count_nonzero(~r.after)),
            "trigger_s": r.trigger_s,
            "position_offset_deg": math.degrees(r.position_offset_rad),
            "command_offset_deg": math.degrees(r.command_offset_rad),
            "step_deg": math.degrees(run.step_rad),
            "step_from": run.step_source,
            "step": dataclasses.asdict(run.figures),
            "fit": fit,
        })
    model = []
    for item in model_runs:
        model.append({"config": item.config, "config_path": item.config_path,
                      "variant": item.variant, "step": dataclasses.asdict(item.step),
                      "fit": _fit_dict(item.fit)})
    return json_ready({
        "model": "second-order",
        "recordings": recordings,
        "joint": None if fits.joint is None else _fit_dict(fits.joint, unit_step=True),
        "spread": fits.spread,
        "config_simulated": model,
        "config_path": config,
    })


def _ms(value, unit=" ms"):
    """A time [s] in ms; one below 1e-9 s is 0; None is '—'."""
    if value is None:
        return "—"
    return f"{0.0 if abs(value) < 1e-9 else value * 1e3:.4g}{unit}"


def _g(value, unit="", spec=".4g"):
    """A figure with its unit; None (absent in the JSON: NaN or unbounded) is '—'."""
    return "—" if value is None else f"{value:{spec}}{unit}"


def _interval(pair, show=_g):
    """'[low, high]' of a 95 % interval; '[—]' when the JSON has none (unbounded)."""
    low, high = pair
    return "[—]" if low is None or high is None else f"[{show(low)}, {show(high)}]"


def fit_notes(f):
    """Why a fit's figures are absent or not to be trusted, from its JSON fields (each a
    line); empty for a converged fit with bounded intervals."""
    notes = []
    if not f.get("success", True):
        notes.append("not converged: the figures are the optimiser's last iterate")
    if any(None in f[key] for key in ("wn_ci_rad_s", "zeta_ci", "td_ci_s")):
        notes.append("intervals unbounded ([—]): the data do not determine wn, zeta and td "
                     "apart (a singular or ill-conditioned fit)")
    if any(f[key] is None for key in ("wn_rad_s", "zeta", "td_s",
                                      "bandwidth_closed_form_rad_s")):
        notes.append("a figure shown — is not a finite number (null in the JSON)")
    return notes


def fit_lines(f, indent="    "):
    """Text lines of a fit dict."""
    wn, zeta, td, bandwidth = (FIGURES[f"fit.{name}"] for name in (
        "wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s"))
    return [
        f"{indent}{wn.label} {_g(f['wn_rad_s'], ' ' + wn.shown_unit)} "
        f"{_interval(f['wn_ci_rad_s'])}",
        f"{indent}{zeta.label} {_g(f['zeta'])} {_interval(f['zeta_ci'])}",
        f"{indent}{td.label} {_ms(f['td_s'])} {_interval(f['td_ci_s'], lambda v: _ms(v, ''))}",
        f"{indent}{bandwidth.label} "
        f"{_g(f['bandwidth_closed_form_rad_s'], ' ' + bandwidth.shown_unit)}",
        *(f"{indent}{note}" for note in fit_notes(f)),
    ]


def step_lines(s, indent="  "):
    """Text lines of step figures (labels, units and factors of the figure table)."""
    lines = []
    for name in ("rise_time_s", "overshoot_pct", "settling_time_s", "settling_time_5pct_s"):
        figure = FIGURES[f"step.{name}"]
        value = s[name]
        if value is not None and abs(value) < 1e-9 and figure.unit == "s":
            value = 0.0  # a time below 1e-9 s is 0
        lines.append(f"{indent}{figure.label:<19} "
                     f"{_g(figure.shown(value), ' ' + figure.shown_unit)}")
    return lines


def rms_line(f, key, indent="    ", rad_key=None):
    """'rms residual 1.2 % of the step (0.12 deg)'; '—' where the JSON has none."""
    share = f[key]
    text = f"{indent}rms residual {_g(None if share is None else 100 * share, ' %', '.3g')} " \
        "of the step"
    if rad_key is not None:
        rad = f[rad_key]
        text += f" ({_g(None if rad is None else math.degrees(rad), ' deg', '.3g')})"
    return text


def table(data):
    """The text output of :func:`results`' dict."""
    blocks = []
    for rec in data["recordings"]:
        offset = (f", pre-trigger offset {rec['position_offset_deg']:.4g} deg removed"
                  if rec["pre_trigger_samples"] else ", no pre-trigger samples")
        f = rec["fit"]
        blocks.append("\n".join([
            f"{rec['source']}: step of {rec['step_deg']:.4g} deg (from the "
            f"{'command column' if rec['step_from'] == 'command' else '--step option'}), "
            f"{rec['samples']} samples from the trigger{offset}",
            *step_lines(rec["step"]),
            "  second-order-plus-delay fit (docs/model.md §7)",
            *fit_lines(f),
            rms_line(f, "rms_residual_of_step", rad_key="rms_residual_rad"),
        ]))
    if data["joint"] is not None:
        f, spread = data["joint"], data["spread"]
        lines = [f"joint fit of {len(data['recordings'])} recordings (one wn, zeta, td)",
                 *fit_lines(f, "  "),
                 rms_line(f, "rms_residual_of_step", "  "),
                 "spread between the runs' own fits (standard deviation; min .. max)"]
        for key, label, scale, unit in (("wn_rad_s", "wn", 1.0, " rad/s"),
                                        ("zeta", "zeta", 1.0, ""),
                                        ("td_s", "td", 1e3, " ms"),
                                        ("bandwidth_closed_form_rad_s", "bandwidth", 1.0,
                                         " rad/s")):
            s = {name: None if value is None else value * scale
                 for name, value in spread[key].items()}
            lines.append(f"  {label} {_g(s['std'], unit, '.3g')}; {_g(s['min'])} .. "
                         f"{_g(s['max'], unit)}")
        blocks.append("\n".join(lines))
    for model in data["config_simulated"]:
        blocks.append("\n".join([
            f"model {model['config']} / {model['variant']} ({model['config_path']}), simulated "
            f"step of {model['step']['amplitude_deg']:.4g} deg (nonlinear, with its limits)",
            *step_lines(model["step"]),
            "  its own second-order fit",
            *fit_lines(model["fit"]),
        ]))
    return "\n\n".join(blocks)


def run_recordings(args):
    """Read the recordings, fit them, simulate the config's step, print, write ``-o``."""
    from cas_freq.identification import fit_recordings, read_recording

    if args.output is not None:
        check_output_dir(args.output, "-o")
    columns = column_option(args)
    step = None if args.step is None else angle(args.step, "--step")

    loaded = selected_variants(args.target, [args.variant] if args.variant else [], [])[0]

    refuse_linear(loaded, "fit")
    recordings = [read_recording(path, columns) for path in args.data]
    fits = fit_recordings(recordings, step)
    from cas_freq.studies.run import step_batch

    sizes = list(dict.fromkeys(round(run.step_rad, 12) for run in fits.runs))
    model_runs = step_batch([(loaded, size) for size in sizes])
    data = results(fits, model_runs, loaded.source)

    def files():
        from cas_freq.plots.common import svg_text
        from cas_freq.plots.recordings import recording_fit_figure

        return {"fit.json": json_text(data), "fit.svg": svg_text(
            recording_fit_figure(fits, loaded.params.output_label))}

    return write_and_print(args, data, files, table)
