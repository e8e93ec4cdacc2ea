"""The ``simulate --profile`` command's data: a profile move, with and without feed-forward.

Each variant's move is simulated twice in one batch: with the position loop's feed-forward as
the config sets it (i_ff = ff_v dtheta_cmd/dt + ff_a d2theta_cmd/dt2, docs/model.md), as the
drive moves in profile position mode, and with ff_v = ff_a = 0, so that what the feed-forward
buys is seen beside it. Each run is cut at its own settling horizon, so its figures are those
it has alone.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import json_ready
from cas_freq.core.output import ANGLE, OutputUnit, output_json, wrong_kind
from cas_freq.core.parameters import LoopParameters, unit_of
from cas_freq.core.units import has_unit, to_si
from cas_freq.simulation.commands import Profile
from cas_freq.simulation.profile_figures import profile_figures
from cas_freq.simulation.simulator import simulate_batch
from cas_freq.studies.run import (
    _batch_key,
    _identity,
    controllers_text,
    limit_activity,
    linear_verdict,
)

#: rad/s -> rpm.
_RPM = 60.0 / (2.0 * math.pi)

#: The limits of a move: (field, SI unit, example), as :func:`make_profile` reads them.
_LIMITS = (("velocity", "rad/s", "2000deg/s"), ("acceleration", "rad/s^2", "1e5deg/s^2"),
           ("deceleration", "rad/s^2", "1e5deg/s^2"))


def _quantity(value, unit, name, example, positive=True):
    """``value`` (a string with a unit, or a number in ``unit``) as a float in ``unit``."""
    what = {"rad": "an angle", "m": "a length", "rad/s": "a positive speed",
            "m/s": "a positive speed"}.get(unit, "a positive acceleration")
    expected = f"expected {what} at the output with a unit such as {example}"
    try:
        number = to_si(value, unit)
        if isinstance(value, str) and not has_unit(value):
            raise ValueError("it has no unit")
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name}: {expected}, got {value!r} ({exc})") from None
    if positive and not number > 0:
        raise ConfigError(f"{name}: must be > 0, got {value!r}; {expected}")
    return number


def make_profile(distance, velocity, acceleration, deceleration=None, names=None, unit=ANGLE):
    """A :class:`Profile` from values with units, as the CLI and the config give them.

    Parameters
    ----------
    distance : str or float
        The move at the output (``"10 deg"``; a number is rad), non-zero, within ±90 deg.
    velocity : str or float
        Velocity limit at the output (``"2000 deg/s"``; a number is rad/s), > 0.
    acceleration, deceleration : str or float
        Acceleration (deceleration, default the acceleration) limit at the output
        (``"1e5 deg/s^2"``; a number is rad/s^2), > 0.
    names : dict, optional
        How each of ``distance``, ``velocity``, ... is named in error messages (default
        ``profile.<name>``; the CLI names its options).
    unit : cas_freq.core.output.OutputUnit
        The output's kind: at a linear output the move is a length (``"5 mm"``, ``"100 mm/s"``,
        ``"2000 mm/s^2"``; numbers in m, m/s, m/s^2) and an angle is refused.

    Raises
    ------
    ConfigError
        (a ValueError) naming the value, what it was and what is accepted.
    """
    names = {key: f"profile.{key}" for key in ("distance", *(k for k, *_ in _LIMITS))} | \
        dict(names or {})

    wrong = wrong_kind(distance, unit, names["distance"]) if isinstance(distance, str) else None
    if wrong:
        raise ConfigError(wrong)
    move = _quantity(distance, unit.si, names["distance"], unit.example, positive=False)
    if not (move != 0 and abs(move) <= unit.largest):
        raise ConfigError(f"{names['distance']}: must be non-zero and within "
                          f"±{unit.largest_text} at the output, got {distance!r}")
    given = {"velocity": velocity, "acceleration": acceleration, "deceleration": deceleration}
    rates = ((f"{unit.si}/s", unit.rate_examples[0]), *[(f"{unit.si}/s^2",
                                                          unit.rate_examples[1])] * 2)
    limits = {key: None if given[key] is None else _quantity(given[key], si, names[key], example)
              for (key, *_), (si, example) in zip(_LIMITS, rates, strict=True)}
    return Profile(move, limits["velocity"], limits["acceleration"], limits["deceleration"])


@dataclasses.dataclass(frozen=True, eq=False)
class ProfileRun:
    """A simulated profile move of one variant.

    Attributes
    ----------
    config, config_path, variant, overrides, output
        Which actuator; ``output`` is what text calls its output (``output_name``, else
        "output").
    move : Profile
        The command at the output.
    ratio : float
        Gear ratio N [-] (the drive's profile limits are N times the fin's).
    ff_v, ff_a : float
        The config's feed-forward gains [``ff_units``] (motor side).
    result : SimulationResult
        The move with the config's feed-forward.
    profile : ProfileFigures
        Its figures (the ``profile.*`` figures of requirements).
    result_without_feedforward : SimulationResult
        The same move with ff_v = ff_a = 0.
    without_feedforward : ProfileFigures
        Its figures.
    linear_stability : str
        Verdict of the linear closed loop (Padé poles), as ``analyze`` gives it.
    ff_units : tuple of str
        The SI units of ``ff_v`` and ``ff_a`` in the config's architecture (A*s/rad and
        A*s^2/rad into the current command; a cascade's ff_v is a velocity command per
        command rate, [-]).
    """

    config: str
    config_path: str
    variant: str
    overrides: tuple
    move: Profile
    ratio: float
    ff_v: float
    ff_a: float
    result: object
    profile: object
    result_without_feedforward: object
    without_feedforward: object
    linear_stability: str = "stable"
    output: str = "output"
    #: How the output is measured and shown (:mod:`cas_freq.core.output`).
    output_unit: OutputUnit = ANGLE
    ff_units: tuple = ("A*s/rad", "A*s^2/rad")


def profile_runs(variants, move, verdicts=None, progress=None):
    """Simulate ``move`` on each variant, with and without feed-forward.

    Parameters
    ----------
    variants : sequence of cas_freq.config.LoadedVariant
        The variants; those with the same controller sampling and time step share a batch.
    move : Profile
        The move at the output (one distance).
    verdicts : dict, optional
        ``id(loaded) -> linear stability verdict`` already known; others are computed.
    progress : callable, optional
        ``progress(steps_done, steps_planned)`` of each batch.

    Returns
    -------
    list of ProfileRun
        In the order of ``variants``.
    """
    if np.ndim(move.distance_rad) != 0:
        raise ValueError("profile_runs: one distance expected")
    verdicts = dict(verdicts or {})
    groups = {}
    for index, loaded in enumerate(variants):
        groups.setdefault(_batch_key(loaded.params), []).append(index)
        if id(loaded) not in verdicts:
            verdicts[id(loaded)] = linear_verdict(loaded.params)
    runs = [None] * len(variants)
    for ((current_rate_hz, position_rate_hz), dt, _), members in groups.items():
        loops = LoopParameters.from_configs([variants[index].params for index in members])
        count = len(members)
        both = loops.take(np.r_[np.arange(count), np.arange(count)])
        both = both.replace(ff_v=np.r_[loops.ff_v, np.zeros(count)],
                            ff_a=np.r_[loops.ff_a, np.zeros(count)])
        batch = simulate_batch(both, move, dt=dt, current_rate_hz=current_rate_hz,
                               position_rate_hz=position_rate_hz, progress=progress)
        for position, index in enumerate(members):
            loaded = variants[index]
            on, off = batch.run(position), batch.run(count + position)
            runs[index] = ProfileRun(
                **_identity(loaded), move=move, ratio=float(loops.ratio[position]),
                ff_v=float(loops.ff_v[position]), ff_a=float(loops.ff_a[position]),
                result=on, profile=profile_figures(on, move),
                result_without_feedforward=off, without_feedforward=profile_figures(off, move),
                linear_stability=verdicts[id(loaded)],
                ff_units=(unit_of("position_loop.ff_v", loaded.params),
                          unit_of("position_loop.ff_a", loaded.params)),
            )
    return runs


def profile_run(loaded, move, progress=None):
    """:func:`profile_runs` of one variant."""
    return profile_runs([loaded], move, progress=progress)[0]


def move_dict(move, ratio=None):
    """The move's limits at the output [deg, deg/s, deg/s^2] and, given the gear ratio, at the
    motor in the drive's default units (rpm, rpm/s), as profile position mode takes them."""
    out = {
        "distance_deg": math.degrees(float(move.distance_rad)),
        "velocity_deg_s": math.degrees(move.velocity_rad_s),
        "acceleration_deg_s2": math.degrees(move.acceleration_rad_s2),
        "deceleration_deg_s2": math.degrees(move.deceleration_rad_s2),
        "peak_rate_deg_s": math.degrees(float(move.peak_rate_rad_s)),
        "move_time_s": move.move_time_s,
        "start_s": move.start_s,
    }
    if ratio is not None:
        out["motor"] = {
            "distance_rev": float(move.distance_rad) * ratio / (2.0 * math.pi),
            "velocity_rpm": move.velocity_rad_s * ratio * _RPM,
            "acceleration_rpm_s": move.acceleration_rad_s2 * ratio * _RPM,
            "deceleration_rpm_s": move.deceleration_rad_s2 * ratio * _RPM,
        }
    return out


def _run_part(result, figures):
    return {
        "figures": dataclasses.asdict(figures),
        "limits": {
            "current": limit_activity(result.t, result.current_limited),
            "voltage": limit_activity(result.t, result.voltage_limited),
        },
        "simulation": {"t_end_s": result.t_end_s, "extended": result.extended,
                       "settled": result.settled},
    }


def profile_run_dict(run):
    """JSON-ready dict of a :class:`ProfileRun` (non-finite numbers become None).

    ``profile`` holds the figures with the config's feed-forward (the keys of ``profile.*``
    requirements), ``without_feedforward`` the same move's with ff_v = ff_a = 0.
    """
    on = _run_part(run.result, run.profile)
    off = _run_part(run.result_without_feedforward, run.without_feedforward)
    return json_ready(output_json({
        "config": run.config,
        "config_path": run.config_path,
        "variant": run.variant,
        "overrides": list(run.overrides),
        "move": move_dict(run.move, run.ratio),
        "feedforward": {"ff_v_a_s_rad": run.ff_v, "ff_a_a_s2_rad": run.ff_a,
                        "active": bool(run.ff_v or run.ff_a)},
        "linear_closed_loop": run.linear_stability,
        "profile": on["figures"],
        "limits": on["limits"],
        "without_feedforward": {"profile": off["figures"], "limits": off["limits"],
                                "simulation": off["simulation"]},
        "simulation": {"controllers": controllers_text(run.result), "dt_s": run.result.dt_s,
                       **on["simulation"]},
    }, run.output_unit))


def profile_condition_text(move, unit=ANGLE):
    """``10 deg at 2000 deg/s, 1e+05 deg/s^2`` (and the deceleration when it differs); at a
    linear output (``unit``) in mm, mm/s, mm/s^2."""
    def shown(value):  # [SI] -> the output's unit
        return unit.value(math.degrees(float(value)))

    u = unit.shown
    text = (f"{shown(move.distance_rad):g} {u} at {shown(move.velocity_rad_s):g} {u}/s, "
            f"{shown(move.acceleration_rad_s2):g} {u}/s^2")
    if move.deceleration_rad_s2 != move.acceleration_rad_s2:
        text += f" (deceleration {shown(move.deceleration_rad_s2):g} {u}/s^2)"
    return text
