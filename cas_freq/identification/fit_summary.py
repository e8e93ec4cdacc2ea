"""What a physical fit found, as plain data: each fitted key's estimate, interval and
identifiability, the fit's residuals and information criteria, and the comparison of
alternative models fitted to the same recordings (``cas-freq fit --params``, ``--candidates``).
"""

import math

from cas_freq.core.exceptions import CasFreqError
from cas_freq.identification.free_keys import labels

#: Akaike differences and what they say (Burnham & Anderson's rule of thumb).
SUPPORT = ((2.0, "as well supported"), (10.0, "less supported"), (math.inf, "not supported"))


def fitted_channels(option, recordings):
    """The channels fitted: the option's, or position and current where every file has it."""
    if option is None:
        every = all(r.current_a is not None for r in recordings)
        return ("position", "current") if every else ("position",)
    names = tuple(dict.fromkeys(part.strip() for part in option.split(",")))
    if "position" not in names or not set(names) <= {"position", "current"}:
        raise CasFreqError(f"--channels {option}: expected position or position,current")
    return names


def _key_rows(fit):
    """JSON of each key: start, estimate, interval, standard error, verdicts."""
    verdicts = fit.identifiability["fitted"].keys
    rows = []
    for index, free in enumerate(fit.free):
        low, high = fit.interval[index]
        v = verdicts[index]
        rows.append({
            "key": free.key, "unit": free.unit, "start": fit.start[index],
            "estimate": fit.estimate[index], "ci95": [low, high],
            "coordinate": "log" if free.log else "linear",
            "half_width": v.half_width, "half_width_others_known": v.conditional_half_width,
            "verdict": v.verdict, "at_bound": fit.at_bound[index],
            "probe": _probe_dict(fit.probes["keys"][index]),
        })
    return rows


def _probe_dict(probe):
    """JSON of a Probe: the chi^2 change the interval claims at its ends, the one simulated
    there, and how much each side was widened (null: unbounded, nothing moves the output)."""
    return {"chi2_claimed": probe.predicted, "chi2_at_ends": list(probe.moved),
            "widened_by": list(probe.factor)}


def _identifiability_dict(found):
    """JSON of an Identifiability."""
    def combination(c):
        return {"combination": c.text, "value": c.value, "unit": c.unit,
                "half_width": c.half_width, "verdict": c.verdict,
                "exponents": list(c.exponents),
                "sum_coefficients": None if c.coefficients is None else list(c.coefficients)}

    return {
        "keys": [{"key": k.key, "half_width": k.half_width,
                  "half_width_others_known": k.conditional_half_width, "verdict": k.verdict}
                 for k in found.keys],
        "determined": [combination(c) for c in found.determined],
        "not_well_determined": [combination(c) for c in found.undetermined],
        "condition_number": found.condition,
    }


def fit_dict(fit, seconds):
    """JSON-ready dict of one PhysicalFit."""
    ident = {name: _identifiability_dict(found) for name, found in fit.identifiability.items()}
    return {
        "name": fit.name,
        "keys": _key_rows(fit),
        "correlation": {"labels": labels(fit.free), "matrix": fit.correlation.tolist()},
        "channels": list(fit.channels),
        "rms_residual": {"position_deg": {k: math.degrees(v) for k, v in
                                          fit.rms["position"].items()},
                         **({"current_a": fit.rms["current"]} if "current" in fit.rms else {})},
        "samples": fit.n_samples,
        "parameters_counted": fit.n_parameters,
        "log_likelihood": fit.log_likelihood,
        "residual_over_noise": [
            {"recording": index, "channel": channel, "ratio": ratio}
            for (index, channel), ratio in sorted(fit.noise_ratio.items())],
        **fit.criteria(),
        "identifiability": ident,
        "assumed_current_noise_a": fit.assumed_current_noise_a,
        "converged": fit.converged,
        "simulator_batches": fit.evaluations,
        "seconds": seconds,
    }


def comparison(fits):
    """Rows of the model comparison, best (lowest AICc) first, with differences and support."""
    rows = [{"name": f.name, "free_keys": len(f.free), "parameters_counted": f.n_parameters,
             "rms_position_deg": math.degrees(f.rms["position"]["fit"]), **f.criteria()}
            for f in fits]
    best_aicc = min(row["aicc"] for row in rows)
    best_bic = min(row["bic"] for row in rows)
    for row in rows:
        row["delta_aicc"] = row["aicc"] - best_aicc
        row["delta_bic"] = row["bic"] - best_bic
        row["support"] = ("best" if row["aicc"] == best_aicc else
                          next(text for limit, text in SUPPORT if row["delta_aicc"] <= limit))
    return sorted(rows, key=lambda row: row["aicc"])


__all__ = ["SUPPORT", "comparison", "fit_dict", "fitted_channels"]
