"""What the output says of a sampled drive (docs/model.md, section 14): the rates, where the
figures stop, a rate below twice a loop's crossover, and the JSON's ``sampling`` section."""

import numpy as np

from cas_freq.model.sampled import periods


def sampling_notes(params, continuous):
    """What the output says of sampled loops: the rates, where the figures stop, and a rate
    below twice a loop's crossover (the continuous loop's: a sampled loop's own crossover
    lies below its Nyquist frequency by construction)."""
    every = periods(params)
    rates = ", ".join(f"{name.replace('_loop', '')} {rate_text(1.0 / period)}"
                      for name, period in every.items())
    notes = [f"sampled controllers ({rates}; {params.sampling_method} discretisation, "
             "zero-order hold): stability from the discrete-time poles, each loop's figures "
             "exact at its sampling instants and up to its Nyquist frequency pi/T; the "
             "continuous figures beside them ('continuous')"]
    for name, period in every.items():
        crossover = continuous[name]["crossover_rad_s"]
        sampling = 2.0 * np.pi / period
        if crossover is not None and sampling < 2.0 * crossover:
            notes.append(f"{name.replace('_', ' ')} sampled at {rate_text(1.0 / period)} "
                         f"({sampling:.5g} rad/s): below twice its crossover "
                         f"({crossover:.5g} rad/s)")
    return notes


def rate_text(hz):
    """A sampling rate in words: ``25 kHz``, ``500 Hz``."""
    return f"{hz / 1e3:.6g} kHz" if hz >= 1e3 else f"{hz:.6g} Hz"


def sampling_section(params):
    """The sampling section of a sampled analysis: method, each loop's rate and Nyquist
    frequency."""
    every = periods(params)
    return {"method": params.sampling_method,
            "rates_hz": {name: float(rate) for name, rate in params.sample_rates},
            "nyquist_rad_s": {name: np.pi / period for name, period in every.items()}}
