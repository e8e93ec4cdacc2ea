"""``cas-freq fit [CONFIG] --data FILE...`` for sweep recordings: empirical frequency responses.

Each recording's H1 estimate and coherence (:mod:`cas_freq.identification.frf`) of the output
angle per output command, and with a current column of the current per output command, with a
current_command column of the current per current command (the current loop's T_i), beside
CONFIG's variant evaluated at the same frequencies (exact delays); per response the RMS
differences data vs model where the coherence is >= 0.9, the empirical -3 dB bandwidth against
the model's, and with several recordings how each compares with the first. ``-o DIR`` writes
frf.json and frf.svg.
"""

from cas_freq.cli.common import column_option, refuse_linear, selected_variants, write_and_print
from cas_freq.core.exceptions import CasFreqError, ConfigError
from cas_freq.core.fileio import json_ready
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text

#: Responses estimated: key, input and output attributes of a SweepRecording, label (``{output}``:
#: the config's ``output_label``), unit.
RESPONSES = (
    ("position", "command_rad", "position_rad", "{output} angle / {output} command", "-"),
    ("current", "command_rad", "current_a", "current / {output} command", "A/rad"),
    ("current_loop", "current_command_a", "current_a", "current / current command (T_i)", "-"),
)


def are_sweeps(paths, columns):
    """True if every recording is a sweep, False if every one is a step; a mix is an error
    naming the files of each kind."""
    from cas_freq.identification.sweep import recording_kind

    kinds = {path: recording_kind(path, columns) for path in paths}
    sweeps = [path for path, kind in kinds.items() if kind == "sweep"]
    if sweeps and len(sweeps) < len(kinds):
        steps = [path for path in paths if kinds[path] == "step"]
        raise ConfigError(f"sweep recordings ({', '.join(sweeps)}) and step recordings "
                          f"({', '.join(steps)}) in one call; fit them separately")
    return bool(sweeps)


def _listed(values, digits=6):
    """Floats rounded to ``digits`` significant digits (JSON and figures regenerate alike)."""
    from cas_freq.core.numbers import round_array

    return [float(v) for v in round_array(values, digits)]


def _response(estimate, model):
    """JSON-ready dict of one response: data, model, comparison."""
    from cas_freq.identification import frf

    model_deg = frf.unwrapped_deg(model)
    return {
        "omega_rad_s": _listed(estimate.omega_rad_s),
        "magnitude_db": _listed(frf.db(estimate.response)),
        "phase_deg": _listed(frf.unwrapped_deg(estimate.response, model_deg[0])),
        "coherence": _listed(estimate.coherence),
        "model_magnitude_db": _listed(frf.db(model)),
        "model_phase_deg": _listed(model_deg),
        "comparison": frf.compare(estimate, model),
    }


def analyse(recording, params):
    """The estimates of one recording and the JSON-ready dict of them.

    Returns
    -------
    tuple of (dict of str to Frf, dict)
    """
    from cas_freq.identification import frf

    estimates, responses = {}, {}
    for key, source, target, label, unit in RESPONSES:
        x, y = getattr(recording, source), getattr(recording, target)
        if x is None or y is None:
            continue
        estimate = frf.estimate(x, y, recording.interval_s)
        model = frf.model_responses(params, estimate.omega_rad_s)[key]
        estimates[key] = estimate
        responses[key] = {"label": label.format(output=params.output_label), "unit": unit,
                          **_response(estimate, model)}
    position = estimates["position"]
    value, note = frf.bandwidth(position)
    data = {
        "source": recording.source,
        "samples": recording.samples,
        "grid_samples": int(recording.time_s.size),
        "interval_s": recording.interval_s,
        "resampled": recording.resampled,
        "interval_spread": recording.interval_spread,
        "duration_s": float(recording.time_s[-1] - recording.time_s[0]),
        "nperseg": position.nperseg,
        "averages": position.averages,
        "band_rad_s": [float(position.omega_rad_s[0]), float(position.omega_rad_s[-1])],
        "frequencies": int(position.omega_rad_s.size),
        "bandwidth_rad_s": value,
        "bandwidth_note": note,
        "responses": responses,
    }
    return estimates, data


def results(recordings, loaded):
    """The JSON-ready dict of every recording's responses (and the estimates, for the
    figure)."""
    from cas_freq.identification import frf

    analysed = [analyse(recording, loaded.params) for recording in recordings]
    first = analysed[0][0]
    spread = []
    for recording, (estimates, _) in zip(recordings[1:], analysed[1:], strict=True):
        spread.append({"source": recording.source, "against": recordings[0].source,
                       **frf.between(first["position"], estimates["position"])})
    data = json_ready({
        "kind": "sweep",
        "coherence_threshold": frf.COHERENT,
        "model": {"config_path": str(loaded.source), "variant": loaded.variant,
                  "delays": "exact", "feedforward": False,
                  "bandwidth_rad_s": frf.model_bandwidth(loaded.params)},
        "recordings": [item[1] for item in analysed],
        "between_recordings": spread,
    })
    return [item[0] for item in analysed], data


def _diff(comparison):
    """'0.201 dB, 1.31 deg (max 1.03 dB, 6.2 deg)' or '—'."""
    if comparison["rms_db"] is None:
        return "— (no coherent frequencies)"
    return (f"{comparison['rms_db']:.3g} dB, {comparison['rms_deg']:.3g} deg "
            f"(max {comparison['max_db']:.3g} dB, {comparison['max_deg']:.3g} deg)")


def table(data):
    """The text output of :func:`results`' dict."""
    model = data["model"]
    threshold = data["coherence_threshold"]
    blocks = []
    for rec in data["recordings"]:
        if rec["resampled"]:
            sampling = (f"irregular (intervals within ±{100 * rec['interval_spread']:.3g} % of "
                        f"their median {rec['interval_s'] * 1e6:.4g} us), resampled to "
                        f"{rec['grid_samples']} samples at {1e-3 / rec['interval_s']:.4g} kHz")
        else:
            sampling = f"uniform at {1e-3 / rec['interval_s']:.4g} kHz"
        lo, hi = rec["band_rad_s"]
        lines = [
            f"{rec['source']}: {rec['samples']} samples over {rec['duration_s']:.4g} s, "
            f"{sampling}",
            f"  Welch: {rec['averages']} averages of {rec['nperseg']} samples (Hann, 50 % "
            "overlap)",
            f"  band {lo:.4g} .. {hi:.4g} rad/s ({rec['frequencies']} frequencies where the "
            "command has power)",
            f"  data vs model, RMS over the frequencies with coherence >= {threshold:g}:",
        ]
        for response in rec["responses"].values():
            comparison = response["comparison"]
            count = len(response["omega_rad_s"])
            lines.append(f"    {response['label']:<34} {comparison['coherent']:>4}/{count:<4} "
                         f"{_diff(comparison)}")
        bandwidth = (f"{rec['bandwidth_rad_s']:.4g} rad/s" if rec["bandwidth_rad_s"] is not None
                     else f"— ({rec['bandwidth_note']})")
        model_bw = model["bandwidth_rad_s"]
        lines.append(f"  -3 dB bandwidth: data {bandwidth}, model "
                     f"{'—' if model_bw is None else f'{model_bw:.4g} rad/s'}")
        blocks.append("\n".join(lines))
    if data["between_recordings"]:
        position = data["recordings"][0]["responses"]["position"]["label"]
        lines = [f"{position} of each recording against the first's (coherent "
                 "frequencies both share)"]
        for item in data["between_recordings"]:
            shown = ("— (no shared coherent frequencies)" if item["rms_db"] is None else
                     f"{item['rms_db']:.3g} dB, {item['rms_deg']:.3g} deg RMS over "
                     f"{item['shared']} frequencies")
            lines.append(f"  {item['source']}: {shown}")
        blocks.append("\n".join(lines))
    blocks.append(f"model {model['config_path']} / {model['variant']}: exact delays, T without "
                  "the feed-forward (docs/model.md), T_i of the current loop")
    return "\n\n".join(blocks)


def run_sweep(args):
    """Read the sweep recordings, estimate, compare with the model, print, write ``-o``."""
    from cas_freq.identification.sweep import read_sweep

    if args.step is not None:
        raise CasFreqError("--step is for step recordings; the recordings are sweeps (their "
                           "command oscillates)")
    if args.output is not None:
        check_output_dir(args.output, "-o")

    columns = column_option(args)
    loaded = selected_variants(args.target, [args.variant] if args.variant else [], [])[0]

    refuse_linear(loaded, "fit")
    recordings = [read_sweep(path, columns) for path in args.data]
    _, data = results(recordings, loaded)

    def files():
        from cas_freq.plots.common import svg_text
        from cas_freq.plots.frf import frf_figure

        return {"frf.json": json_text(data), "frf.svg": svg_text(frf_figure(data))}

    return write_and_print(args, data, files, table)


__all__ = ["are_sweeps", "results", "run_sweep", "table"]
