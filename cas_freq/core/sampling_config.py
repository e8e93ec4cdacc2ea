"""The declared sampling of the controllers (``sampling:``): which loops are sampled, at which
rates, and how their controllers are discretised.

One declaration, two spellings (docs/config.md): the ``sampling:`` section (a rate per loop,
``method: backward | tustin``) and the older ``simulation.controllers: sampled`` with
``simulation.current_loop_rate`` and ``position_loop_rate``. The config schema
(:mod:`cas_freq.config.schema`) reconciles the two and checks the rules here; the loop
parameters carry the result as the static ``sample_rates`` and ``sampling_method``
(:class:`cas_freq.core.parameters.LoopParameters`), checked by the same rules.

The rules (:func:`sampling_problem`), each refusal one line naming the key, the value and what
is accepted:

- a rate only for a loop the architecture has (``velocity_loop`` needs a ``velocity_loop``
  section);
- when any loop is sampled the current loop is sampled too (a continuous current loop inside a
  sampled loop is not modelled);
- an inner loop is sampled at least as fast as the next outer sampled loop, and its rate is an
  integer multiple of that loop's rate (multirate must be exact: :data:`RATIO_TOLERANCE`).

The bound of each rate (1..1e9 Hz) is the parameter table's (:data:`cas_freq.core.parameters.
PARAMETERS`, ``sampling.<loop>``), checked where the value is converted.

This module imports only :mod:`cas_freq.core.exceptions`.
"""

import math

from cas_freq.core.exceptions import ConfigError

__all__ = [
    "DEFAULT_METHOD",
    "LOOPS",
    "METHODS",
    "RATIO_TOLERANCE",
    "check_static",
    "conflict_problem",
    "rate_ratio",
    "rates_text",
    "sample_rates",
    "sampling_problem",
]

#: The loops that can be sampled, innermost first (the order of ``sample_rates``).
LOOPS = ("current_loop", "velocity_loop", "position_loop")
#: How a sampled controller is discretised, and the weight alpha of the generalised bilinear
#: transform s -> (z - 1)/(T (alpha z + 1 - alpha)) each is: s -> (1 - z^-1)/T (backward
#: difference, alpha 1) or (2/T)(z - 1)/(z + 1) (Tustin, alpha 1/2).
ALPHA = {"backward": 1.0, "tustin": 0.5}
METHODS = tuple(ALPHA)
#: ``sampling.method`` when not given.
DEFAULT_METHOD = "backward"
#: Largest relative distance of a rate ratio from an integer still taken as that integer: a
#: rate converted from a unit (``2.5 kHz``) may be a few ulps (~1e-16) off; 1e-9 leaves room for
#: a rate written with nine or more significant digits (``2777.77777778 Hz``).
RATIO_TOLERANCE = 1e-9

#: The older spelling's key of each loop's rate (``simulation.controllers: sampled``).
_OLD_KEYS = {"current_loop": "simulation.current_loop_rate",
             "position_loop": "simulation.position_loop_rate"}


def _hz(rate):
    return f"{rate:g} Hz"


def sample_rates(rates):
    """The sampled loops of a mapping loop name -> rate [Hz] or None, as the static
    ``sample_rates`` holds them: ((loop name, rate [Hz]), ...), innermost first; () when
    nothing is sampled."""
    return tuple((name, float(rates[name])) for name in LOOPS if rates.get(name) is not None)


def rate_ratio(inner_hz, outer_hz):
    """The integer N with inner = N * outer [Hz], or None if the ratio is not an integer (to
    :data:`RATIO_TOLERANCE`)."""
    ratio = inner_hz / outer_hz
    whole = round(ratio)
    return whole if whole >= 1 and abs(ratio - whole) <= RATIO_TOLERANCE * ratio else None


def rates_text(pairs):
    """The rates of ``pairs`` (``sample_rates``) for text: ``"25000 Hz and 2500 Hz"``."""
    return " and ".join(_hz(rate) for _, rate in pairs)


def sampling_problem(rates, cascade):
    """What is wrong with a sampling declaration, or None.

    Parameters
    ----------
    rates : mapping of str to float or None
        Loop name (:data:`LOOPS`) -> sample rate [Hz] (> 0, already within its bound), None or
        absent for a continuous loop.
    cascade : bool
        Whether the architecture has a velocity loop.

    Returns
    -------
    str or None
        One line naming the key (``sampling.<loop>``), its value and what is accepted.
    """
    if not cascade and rates.get("velocity_loop") is not None:
        return (f"sampling.velocity_loop: the config has no velocity_loop section, got "
                f"{_hz(rates['velocity_loop'])}; accepted: sampling.current_loop and "
                "sampling.position_loop (the loops the config has)")
    pairs = sample_rates(rates)
    if pairs and pairs[0][0] != "current_loop":
        name, rate = pairs[0]
        return (f"sampling.current_loop: absent (continuous) while sampling.{name} is "
                f"{_hz(rate)}; accepted: a current-loop rate whenever any loop is sampled (a "
                "continuous current loop inside a sampled loop is not modelled)")
    for (inner, inner_hz), (outer, outer_hz) in zip(pairs[:-1], pairs[1:], strict=True):
        if outer_hz > inner_hz:
            return (f"sampling.{outer}: {_hz(outer_hz)} is faster than sampling.{inner} "
                    f"({_hz(inner_hz)}) inside it; accepted: at most {_hz(inner_hz)} (an inner "
                    "loop is never sampled slower than the loop around it)")
        if rate_ratio(inner_hz, outer_hz) is None:
            below = math.floor(inner_hz / outer_hz)
            return (f"sampling.{outer}: {_hz(outer_hz)} is not sampling.{inner} "
                    f"({_hz(inner_hz)}) divided by an integer (ratio {inner_hz / outer_hz:.6g}); "
                    f"accepted: {_hz(inner_hz)}/N, e.g. {_hz(inner_hz / below)} (N = {below}) or "
                    f"{_hz(inner_hz / (below + 1))} (N = {below + 1}): multirate must be exact")
    loops = ("current_loop", "velocity_loop", "position_loop") if cascade else (
        "current_loop", "position_loop")
    missing = [name for name in loops if rates.get(name) is None]
    if pairs and missing:
        return (f"sampling.{missing[0]}: absent (continuous) while "
                f"{', '.join(f'sampling.{name}' for name, _ in pairs)} are sampled; accepted: a "
                f"rate for every loop once one is sampled (a continuous loop is faster than any "
                "sampled loop, so it cannot sit outside one, and a continuous loop inside a "
                "sampled one is not modelled)")
    return None


def conflict_problem(declared, old):
    """What is wrong when both spellings are given, or None.

    Parameters
    ----------
    declared : mapping of str to float or None
        The rates of the ``sampling:`` section (at least one given).
    old : mapping of str to float or None
        The rates of ``simulation.controllers: sampled`` (current and position loops).

    Returns
    -------
    str or None
        None when both spellings declare the same rates for the current and position loops
        (the loops the older spelling speaks of), else one line naming the first loop that
        differs.
    """
    for name, old_key in _OLD_KEYS.items():
        new, before = declared.get(name), old.get(name)
        same = (new is None) == (before is None) and (
            new is None or math.isclose(new, before, rel_tol=1e-12))
        if not same:
            given = "absent (continuous)" if new is None else _hz(new)
            other = "null (continuous)" if before is None else _hz(before)
            return (f"sampling.{name}: {given}, but {old_key} is {other} "
                    "(simulation.controllers: sampled, the older spelling of the same "
                    "declaration); accepted: the same rates in both spellings, or one spelling "
                    "only (drop simulation.controllers: sampled)")
    return None


def check_static(pairs, method, cascade):
    """The static ``sample_rates`` and ``sampling_method`` of loop parameters, checked.

    Parameters
    ----------
    pairs : sequence of (str, float)
        (loop name, rate [Hz]) of the sampled loops, innermost first; empty: continuous.
    method : str
        One of :data:`METHODS`.
    cascade : bool
        Whether the loop parameters have a velocity loop.

    Returns
    -------
    tuple
        ``pairs`` as a tuple of (str, float) tuples.

    Raises
    ------
    ConfigError
        For pairs that are not (loop name, finite rate > 0), out of order or repeated, or that
        break a rule of :func:`sampling_problem`; for an unknown method.
    """
    head = "simulation parameters:"
    if method not in METHODS:
        raise ConfigError(f"{head} sampling_method: must be one of {', '.join(METHODS)}, got "
                          f"{method!r}")
    try:
        pairs = tuple((name, float(rate)) for name, rate in pairs)
    except (TypeError, ValueError):
        raise ConfigError(f"{head} sample_rates: must be (loop name, rate [Hz]) pairs, got "
                          f"{pairs!r}") from None
    names = [name for name, _ in pairs]
    if not all(name in LOOPS for name in names):
        raise ConfigError(f"{head} sample_rates: loop names must be among {', '.join(LOOPS)}, "
                          f"got {', '.join(map(repr, names))}")
    if names != [name for name in LOOPS if name in names]:
        raise ConfigError(f"{head} sample_rates: one pair per loop, innermost first "
                          f"({', '.join(LOOPS)}), got {', '.join(names)}")
    bad = [(name, rate) for name, rate in pairs if not (math.isfinite(rate) and rate > 0)]
    if bad:
        raise ConfigError(f"{head} sample_rates: {bad[0][0]}: must be a finite rate > 0 Hz, "
                          f"got {bad[0][1]!r}")
    problem = sampling_problem(dict(pairs), cascade)
    if problem:
        raise ConfigError(f"{head} {problem}")
    return pairs
