"""Measure the figures a list of requirements refers to, for one variant.

Each figure is computed exactly as the command that prints it computes it, so a verdict can be
reproduced by hand: ``analyze`` (exact delays, default range) for loop and closed-loop figures,
``simulate --step`` for ``step.*`` and ``fit.*``, ``sinedwell`` (feed-forward off) for
``sinedwell.bandwidth_rad_s``. Runs shared by several requirements (the same step size, the
same amplitude and grid) are done once.
"""

from cas_freq.fileio import json_ready


def _lookup(data, dotted):
    value = data
    for part in dotted.split("."):
        value = value[part]
    return value


def measure(variants, requirements, known=None):
    """Figures of every variant for each requirement.

    Parameters
    ----------
    variants : sequence of cas_freq.config.LoadedVariant
        The variants (their steps of one size run in one batch).
    requirements : sequence of cas_freq.config.requirement.Requirement
        What to measure.
    known : sequence of dict, optional
        Per variant, results already computed by the same code (so not computed again):
        ``"analyze"``, the ``analyze`` JSON, and ``"steps"``, a list of ``simulate`` JSONs of
        steps; a step of the right size (to 1e-9) is used instead of a new run.

    Returns
    -------
    list of (dict, dict)
        Per variant, ``values``: requirement id -> figure (float, or None when it does not
        exist, e.g. no crossover in range) and ``context``: requirement id -> a short text of
        what was run (for an unstable closed loop: that no figure can be trusted).
    """
    from cas_freq.analysis import analyze, to_dict
    from cas_freq.simulation.run import step_run_dict, step_runs

    known = known or [{} for _ in variants]
    analyses = [item.get("analyze") or to_dict(analyze(loaded))
                for loaded, item in zip(variants, known, strict=True)]
    stable = [index for index, data in enumerate(analyses) if data["stable"]]
    steps = {}
    for size in sorted({r.step for r in requirements if r.kind == "step"}):
        steps[size] = {index: _known_step(known[index], size) for index in stable}
        missing = [index for index, data in steps[size].items() if data is None]
        runs = step_runs([variants[index] for index in missing], size) if missing else []
        steps[size].update(zip(missing, (step_run_dict(run) for run in runs), strict=True))
    out = []
    for index, loaded in enumerate(variants):
        values, context = {}, {}
        dwells = {}
        for requirement in requirements:
            key = requirement.id
            if index not in stable:
                values[key] = None
                context[key] = (f"not assessed: the closed loop is "
                                f"{analyses[index]['stability']}")
            elif requirement.kind == "analyze":
                values[key] = _lookup(analyses[index], requirement.metric)
                context[key] = "linear, exact delays"
            elif requirement.kind == "step":
                data = steps[requirement.step][index]
                values[key] = _lookup(data, requirement.metric)
                context[key] = f"nonlinear step of {data['step']['amplitude_deg']:g} deg"
            else:
                condition = (requirement.amplitude, requirement.frequencies)
                if condition not in dwells:
                    dwells[condition] = _sinedwell_bandwidth(loaded, *condition)
                values[key] = dwells[condition]
                context[key] = _dwell_text(*condition)
        out.append((json_ready(values), context))
    return out


def _known_step(item, size):
    """The ``simulate`` JSON of a step of ``size`` [rad] among ``item["steps"]``, or None."""
    import math

    for data in item.get("steps", ()):
        if math.isclose(math.radians(data["step"]["amplitude_deg"]), size, rel_tol=1e-9):
            return data
    return None


def _sinedwell_bandwidth(loaded, amplitude, frequencies):
    """Sine-dwell bandwidth at one amplitude (as ``cas-freq sinedwell``, feed-forward off)."""
    from cas_freq.simulation.run import (
        DEFAULT_SINEDWELL_FREQUENCIES_RAD_S,
        dwell_parameters,
    )
    from cas_freq.simulation.sinedwell import sine_dwell

    current_rate_hz, position_rate_hz = loaded.params.simulation.rates_hz
    result = sine_dwell(
        dwell_parameters(loaded.params, feedforward=False), [amplitude],
        frequencies or DEFAULT_SINEDWELL_FREQUENCIES_RAD_S,
        current_rate_hz=current_rate_hz, position_rate_hz=position_rate_hz,
    )
    return result.bandwidth_rad_s[0]


def _dwell_text(amplitude, frequencies):
    import math

    grid = "default grid" if frequencies is None else (
        f"{len(frequencies)} frequencies {frequencies[0]:g}..{frequencies[-1]:g} rad/s"
    )
    return f"sine-dwell at {math.degrees(amplitude):g} deg, {grid}"
