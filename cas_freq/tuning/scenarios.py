"""The conditions every candidate is checked in: the nominal model, a tolerance set, load cases.

A tune is nominal (one scenario), or robust over a tolerance set (``--tolerance KEY=TOL``, as
``montecarlo`` takes them): ``montecarlo:N`` draws N samples
(:func:`cas_freq.studies.montecarlo.draw`, seeded); ``corners`` takes every corner of the
tolerance box (each key at -TOL and +TOL, 2^k scenarios). With ``load_cases`` each of those is
taken again at every hinge stiffness of the config's ``load_envelope`` grid. Scenario 0 is
always the nominal model (the variant, at the first load case when there are load cases): the
objective is its figure.

A toleranced key keeps its tolerance relative to the candidate's value when the key is also
free (a toleranced gain is the tuned gain times the drawn factor); otherwise it is the drawn
value.
"""

import dataclasses
import itertools

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import base_values


@dataclasses.dataclass(frozen=True, eq=False)
class Scenarios:
    """The scenarios of a tune.

    Attributes
    ----------
    factors : dict of str to numpy.ndarray
        Key -> (count,) multiplier of the candidate's (free key) or variant's value.
    offsets : dict of str to numpy.ndarray
        Key -> (count,) value added [SI] (tolerances on keys whose value is 0).
    count : int
        Scenarios per candidate (scenario 0: nominal).
    counted : numpy.ndarray of bool
        (count,) the scenarios the yield counts (every one but the nominal for montecarlo,
        whose samples already hold the nominal spread; every one otherwise).
    target : float
        The fraction of counted scenarios that must pass every requirement.
    label : str
        What the set is, for the output.
    """

    factors: dict
    offsets: dict
    count: int
    counted: np.ndarray
    target: float
    label: str

    def changes(self, free_values, base):
        """Key -> (n * count,) values [SI] of every candidate in every scenario.

        Parameters
        ----------
        free_values : dict of str to numpy.ndarray
            Free key -> (n,) candidate values [SI].
        base : dict of str to float
            The variant's values (:func:`cas_freq.core.parameters.base_values`).
        """
        n = len(next(iter(free_values.values())))
        changes = {key: np.repeat(values, self.count) for key, values in free_values.items()}
        for key in set(self.factors) | set(self.offsets):
            factor = np.tile(self.factors.get(key, np.ones(self.count)), n)
            offset = np.tile(self.offsets.get(key, np.zeros(self.count)), n)
            value = changes[key] if key in changes else np.full(n * self.count, base[key])
            changes[key] = value * factor + offset
        return changes


def _as_factors(values, nominal):
    """(factor, offset) arrays that turn the nominal into ``values``."""
    if nominal:
        return values / nominal, np.zeros_like(values)
    return np.ones_like(values), values.copy()


def scenarios(params, robust=None, tolerances=(), yield_pct=99.0, seed=0, load_cases=None,
              distribution="normal"):
    """The :class:`Scenarios` of a tune.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
    robust : str, optional
        None (nominal), ``"corners"`` or ``"montecarlo:N"``.
    tolerances : sequence of Tolerance
        From :func:`cas_freq.core.tolerances.parse_tolerance` (required when robust).
    yield_pct : float
        The share of counted scenarios that must pass [%] (corners: always 100).
    seed : int
        Seed of the Monte Carlo draws.
    load_cases : sequence of float, optional
        Hinge stiffnesses [N*m/rad] every scenario is also taken at.
    """
    from cas_freq.studies.montecarlo import draw

    base = base_values(params)
    factors, offsets = {}, {}
    count, label, target = 1, "nominal", 1.0
    if robust is None and tolerances:
        raise ConfigError("--tolerance needs --robust corners or --robust montecarlo:N")
    if robust is not None:
        if not tolerances:
            raise ConfigError(f"--robust {robust}: give the tolerance set, e.g. --tolerance "
                              "motor.Km=10% --tolerance motor.J=10%")
        if robust == "corners":
            signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(tolerances))))
            for column, tolerance in enumerate(tolerances):
                nominal = base[tolerance.key]
                if nominal is None:
                    raise ConfigError(f"{tolerance.key}: derived in the config, cannot be "
                                      "toleranced")
                values = np.concatenate([[nominal], nominal + signs[:, column]
                                         * tolerance.half_width(nominal)])
                factors[tolerance.key], offsets[tolerance.key] = _as_factors(values, nominal)
            count = 1 + signs.shape[0]
            label, target = f"corners of the tolerance box ({signs.shape[0]})", 1.0
        else:
            kind, _, number = robust.partition(":")
            try:
                samples = int(number)
            except ValueError:
                samples = 0
            if kind != "montecarlo" or samples < 1:
                raise ConfigError(f"--robust {robust!r}: expected corners or montecarlo:N "
                                  "(N samples, e.g. montecarlo:200)")
            drawn, seed = draw(params, tolerances, samples, distribution, seed)
            for key, values in drawn.items():
                nominal = base[key]
                values = np.concatenate([[nominal], values])
                factors[key], offsets[key] = _as_factors(values, nominal)
            count = 1 + samples
            if not 0 < yield_pct <= 100:
                raise ConfigError(f"--yield: must be a percentage in (0, 100], got {yield_pct}")
            label = f"montecarlo:{samples} ({distribution}, seed {seed})"
            target = yield_pct / 100.0
    counted = np.ones(count, dtype=bool)
    if robust is not None and robust != "corners":
        counted[0] = False
    if load_cases is not None and len(load_cases):
        cases = np.asarray(load_cases, dtype=float)
        factors = {key: np.tile(value, cases.size) for key, value in factors.items()}
        offsets = {key: np.tile(value, cases.size) for key, value in offsets.items()}
        factors["load.hinge_stiffness"] = np.zeros(count * cases.size)
        offsets["load.hinge_stiffness"] = np.repeat(cases, count)
        counted = np.tile(counted, cases.size)
        count *= cases.size
        label += (f", at {cases.size} load springs K_h {cases.min():g}..{cases.max():g} "
                  "N*m/rad")
    return Scenarios(factors=factors, offsets=offsets, count=count, counted=counted,
                     target=target, label=label)


__all__ = ["Scenarios", "scenarios"]
