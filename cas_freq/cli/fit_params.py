"""``cas-freq fit [CONFIG] --data FILE... --params KEYS``: config keys fitted to step recordings
through the nonlinear simulator (:mod:`cas_freq.identification.physical`), with intervals,
correlations and identifiability; several ``--params`` are alternative models compared by an
information criterion. ``-o FILE.yaml`` writes the config with the fitted variant (of the best
model); ``-o DIR`` writes fit.json, fit.svg and config.yaml.
"""

import math
import time
from pathlib import Path

from cas_freq.cli.common import (
    column_option,
    refuse_linear,
    selected_variants,
    write_and_print,
    wrote,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file, json_ready, write_text_atomic
from cas_freq.core.output import angle
from cas_freq.identification import read_recording
from cas_freq.identification.fit_summary import comparison, fit_dict, fitted_channels
from cas_freq.identification.free_keys import parse_model_spec
from cas_freq.identification.identifiability import UNBOUNDED
from cas_freq.identification.physical import fit_physical
from cas_freq.identification.probe import NOT_IDENTIFIABLE
from cas_freq.identification.step_fit import step_size
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text

#: A residual this many times the pre-trigger noise is reported as a misfit.
MISFIT = 2.0

def _number(value, unit=""):
    text = "—" if value is None or not math.isfinite(value) else f"{value:.4g}"
    return f"{text} {unit}".rstrip() if text != "—" else text


def _half(h):
    """A log half-width as ±x % (or a factor)."""
    if h is None or not math.isfinite(h) or h > UNBOUNDED:
        return "unbounded: beyond ×/÷ 100"
    if h < 0.2:
        return f"±{100 * (math.exp(h) - 1):.2g} %"
    return f"×/÷ {math.exp(h):.3g}"


def _ident_lines(found, title, indent="  "):
    lines = [f"{indent}{title}"]
    for c in found["determined"]:
        lines.append(f"{indent}  well determined: {c['combination']} = {c['value']:.5g} "
                     f"{c['unit']} ({_half(c['half_width'])})")
    for c in found["not_well_determined"]:
        lines.append(f"{indent}  {c['verdict']}: {c['combination']} ({_half(c['half_width'])})")
    sums = [c for c in found["determined"] if c["sum_coefficients"] is not None]
    for index, k in enumerate(found["keys"]):
        if k["verdict"] == NOT_IDENTIFIABLE:
            only = [c["combination"] for c in sums if c["sum_coefficients"][index]]
            why = (f"trading it for the others at a constant {only[0]} does not change the "
                   "simulated output" if only else "changing it does not change the simulated "
                   "output")
            lines.append(f"{indent}  {k['key']}: not identifiable ({why})")
            continue
        lines.append(f"{indent}  {k['key']}: {k['verdict']} ({_half(k['half_width'])}; "
                     f"{_half(k['half_width_others_known'])} if the others were known)")
    return lines


def table(data):
    """Text of the result dict."""
    blocks = [f"{data['config_path']} / {data['variant']}: {len(data['recordings'])} "
              f"recording(s), {data['models'][0]['samples']} samples from the triggers"]
    for model in data["models"]:
        rms = model["rms_residual"]
        lines = [f"model {model['name']!r}: {len(model['keys'])} free keys, fitted to "
                 f"{' and '.join(model['channels'])} ({model['simulator_batches']} simulator "
                 f"batches, {model['seconds']:.2g} s"
                 f"{'' if model['converged'] else ', NOT converged: evaluation limit'})"]
        for row in model["keys"]:
            low, high = row["ci95"]
            interval = "—" if low is None else f"[{low:.4g}, {high:.4g}]"
            bound = f", at its {row['at_bound']} search bound" if row["at_bound"] else ""
            lines.append(f"  {row['key']:<24} {row['start']:<10.4g} -> {row['estimate']:.5g} "
                         f"{row['unit']}  95 % {interval}  {row['verdict']}{bound}")
            widened = [f for f in row["probe"]["widened_by"] if f is not None and f != 1.0]
            if widened and row["verdict"] != NOT_IDENTIFIABLE and low is not None:
                lines.append(f"  {'':<24} (its first interval's ends did not move the output: "
                             f"widened up to x{max(widened):.3g} to what does)")
        pos = rms["position_deg"]
        lines.append(f"  rms residual: position {pos['fit']:.3g} deg (start {pos['start']:.3g})"
                     + (f", current {rms['current_a']['fit']:.3g} A (start "
                        f"{rms['current_a']['start']:.3g})" if "current_a" in rms else ""))
        worst = max((item["ratio"] for item in model["residual_over_noise"]), default=None)
        if worst is not None and worst > MISFIT:
            lines.append(f"  MISFIT: a residual is {worst:.3g}x the noise before the trigger: "
                         "the model does not follow the data (or the fit stopped in a local "
                         "minimum: try other starts, KEY=START); the intervals are too narrow")
        labels = model["correlation"]["labels"]
        lines.append("  correlation: " + "  ".join(f"{name:>8}" for name in labels))
        for name, row in zip(labels, model["correlation"]["matrix"], strict=True):
            cells = "  ".join("      —" if v is None else f"{v:8.3f}" for v in row)
            lines.append(f"  {name:>11}  {cells}")
        ident = model["identifiability"]
        fitted_to = " and ".join(model["channels"])
        lines += _ident_lines(ident["fitted"], f"identifiability from the {fitted_to} data:")
        if "position" in ident:
            lines += _ident_lines(ident["position"], "from the position alone it would be:")
        if model["assumed_current_noise_a"] is not None:
            lines += _ident_lines(
                ident["with_current"], "with current recorded too (predicted, assuming "
                f"{model['assumed_current_noise_a']:.3g} A RMS current noise):")
        blocks.append("\n".join(lines))
    if len(data["models"]) > 1:
        lines = ["comparison (same data; AICc and BIC of the Gaussian likelihood, one noise "
                 "variance per recording and signal counted)",
                 f"  {'model':<16} {'keys':>4} {'rms deg':>8} {'dAICc':>9} {'dBIC':>9}  support"]
        for row in data["comparison"]:
            lines.append(f"  {row['name']:<16} {row['free_keys']:>4} "
                         f"{row['rms_position_deg']:>8.4g} {row['delta_aicc']:>9.4g} "
                         f"{row['delta_bic']:>9.4g}  {row['support']}")
        blocks.append("\n".join(lines))
    if data["written"]:
        blocks.append(f"variant {data['new_variant']!r} (model {data['best']!r}) written to "
                      f"{data['written']}")
    return "\n\n".join(blocks)


def run_params(args):
    """Fit each ``--params`` model, compare, print, write ``-o``."""
    from cas_freq.identification.fitted_config import fitted_config_text

    output = args.output
    as_file = output is not None and Path(output).suffix.lower() in (".yaml", ".yml")
    if output is not None and not as_file:
        check_output_dir(output, "-o")
    elif as_file:
        check_output_file(output, "-o")
    specs = [parse_model_spec(text, number) for number, text in enumerate(args.params, 1)]
    names = [spec.name for spec in specs]
    if len(set(names)) != len(names):
        raise CasFreqError(f"--params: two models are named alike ({', '.join(names)}); name "
                           "them, e.g. --params 'coulomb: motor.Km,...'")
    columns = column_option(args)
    loaded = selected_variants(args.target, [args.variant] if args.variant else [],
                               args.overrides)[0]

    refuse_linear(loaded, "fit")
    if as_file and Path(output).resolve() == Path(loaded.source).resolve():
        raise CasFreqError(f"-o {output}: is the input config; inputs are never modified")
    recordings = [read_recording(path, columns) for path in args.data]
    given = None if args.step is None else angle(args.step, "--step")
    steps = [step_size(r, given)[0] for r in recordings]
    channels = fitted_channels(args.channels, recordings)
    fits, models = [], []
    for spec in specs:
        start = time.perf_counter()
        fit = fit_physical(loaded, recordings, steps, spec, channels)
        fits.append(fit)
        models.append(fit_dict(fit, time.perf_counter() - start))
    rows = comparison(fits)
    best = next(f for f in fits if f.name == rows[0]["name"])
    data = {"config_path": loaded.source, "variant": loaded.variant,
            "overrides": [f"{k}={v}" for k, v in loaded.overrides],
            "recordings": [r.source for r in recordings],
            "steps_deg": [math.degrees(s) for s in steps], "models": models,
            "comparison": rows, "best": best.name, "new_variant": args.name, "written": None}
    text = None
    if output is not None:
        text = fitted_config_text(loaded, best, args.name, args.data)
        data["written"] = str(output if as_file else Path(output) / "config.yaml")
    data = json_ready(data)
    if as_file:
        write_text_atomic(output, text)
        wrote(output)

    def files():
        from cas_freq.plots.common import svg_text
        from cas_freq.plots.recordings import physical_fit_figure

        figure = physical_fit_figure(recordings, fits, best.name, loaded.params.output_label)
        return {"fit.json": json_text(data), "config.yaml": text, "fit.svg": svg_text(figure)}

    return write_and_print(args, data, None if as_file else files, table)
