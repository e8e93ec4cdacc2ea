r"""Figures of the load and drivetrain of one variant (docs/model.md, "Load and drivetrain").

- The load reflected to the motor shaft (rigid gear): :math:`J_{eff} = J + J_L/(\eta N^2)`,
  :math:`\mu_{eff} = \mu_v + b_L/(\eta N^2)`, :math:`k_{eff} = K_h/(\eta N^2)`.
- The open-loop plant's mechanical poles, the roots of D (:func:`cas_freq.model.parts.mechanics`):
  an aiding hinge moment (:math:`K_h < 0`) puts one in the right half-plane, a statically
  unstable surface.
- A compliant gear's resonance (the complex roots of D, the poles of :math:`\theta/i`) and
  anti-resonance (the roots of :math:`n_\theta`, the zeros of :math:`\theta/i`, where the fin
  moves and the motor does not), each as natural frequency and damping ratio. Without damping
  and hinge moment they are the textbook two-mass values
  :math:`\omega_r^2 = K_g (1/J_L + 1/(\eta N^2 J))` and :math:`\omega_a^2 = K_g/J_L`.
- The range of hinge stiffness over which the closed loop is stable, all else fixed: how much
  aiding moment the loop tolerates (and whether a stiff opposing one destabilises it), found
  by scanning :math:`K_h` and bisecting the verdict of the Padé model.
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.stability import stability_verdicts
from cas_freq.model import parts
from cas_freq.model.delay import DEFAULT_PADE_ORDER

#: Hinge stiffness scanned, relative to the loop's own stiffness at the fin Km Kp eta N^2:
#: +-(1e-4 .. 1e4) of it, log-spaced, and 0.
_SCAN_DECADES = 4
_SCAN_POINTS = 33
#: Bisection steps on each stability boundary (relative width 2**-40).
_BISECTIONS = 40
#: Bisection steps decided by one batch of verdicts (:func:`_boundary`): 2**4 - 1 = 15 runs.
_STEPS_PER_BATCH = 4


@dataclasses.dataclass(frozen=True)
class Mode:
    """A pair of complex roots (or a real root) of the drivetrain: frequency and damping."""

    frequency_rad_s: float
    damping: float


@dataclasses.dataclass(frozen=True)
class Drivetrain:
    """The load and drivetrain of one variant, at the motor shaft unless named "fin".

    Attributes
    ----------
    compliant : bool
        True for a two-mass gear (``gear.stiffness`` given).
    reflected_inertia_kg_m2, reflected_damping_n_m_s_rad, reflected_stiffness_n_m_rad : float
        J_eff, mu_eff, k_eff of the rigid model (the compliant gear's low-frequency limit).
    plant_stable : bool
        Whether the open-loop plant's mechanics have no pole in the right half-plane.
    plant_unstable_pole_rad_s : float or None
        The largest real part of a mechanical pole, where it is positive [rad/s].
    resonances, anti_resonances : tuple of Mode
        The compliant gear's resonance(s) (complex poles of theta/i) and anti-resonance(s)
        (complex zeros); empty for a rigid gear.
    stable_hinge_stiffness_n_m_rad : (float or None, float or None)
        The closed loop is stable for hinge stiffness K_h (at the fin) between these bounds,
        the other parameters fixed; None where no bound lies within the scan (+-1e4 of the
        loop's stiffness at the fin). Both None if the loop is stable nowhere in the scan.
    hinge_stiffness_n_m_rad : float
        The variant's own K_h at the fin.
    """

    compliant: bool
    reflected_inertia_kg_m2: float
    reflected_damping_n_m_s_rad: float
    reflected_stiffness_n_m_rad: float
    plant_stable: bool
    plant_unstable_pole_rad_s: float | None
    resonances: tuple
    anti_resonances: tuple
    stable_hinge_stiffness_n_m_rad: tuple
    hinge_stiffness_n_m_rad: float


def _modes(coefficients):
    """Complex root pairs of a polynomial (highest power first) as Modes, slowest first."""
    coefficients = np.trim_zeros(np.asarray(coefficients, dtype=float), "f")
    if coefficients.size < 3:
        return ()
    roots = np.roots(coefficients)
    pairs = roots[roots.imag > 0]
    modes = [Mode(float(abs(r)), float(-r.real / abs(r))) for r in pairs]
    return tuple(sorted(modes, key=lambda m: m.frequency_rad_s))


def drivetrain(params, pade_order=DEFAULT_PADE_ORDER, hinge_range=True):
    """The drivetrain figures of one variant.

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        One variant.
    pade_order : int
        Padé order of the stability verdicts of the hinge-stiffness scan.
    hinge_range : bool
        Scan the stable hinge-stiffness range (a batch of ~68 stability verdicts and 10
        batches of 15 per boundary, most of the time of a loaded variant's analysis);
        without, ``stable_hinge_stiffness_n_m_rad`` is None (``cas-freq design``, which does
        not show it, per change).

    Returns
    -------
    Drivetrain
    """
    p = parts.one_variant(params)
    e_n2 = 1.0 / float(p.eta[0] * p.ratio[0] ** 2)
    d, n_theta, _ = parts.mechanics(p)
    d = [float(np.squeeze(c)) for c in d]
    roots = np.roots(np.trim_zeros(np.asarray(d), "f"))
    unstable = roots.real[roots.real > 0]
    compliant = bool(p.K_g[0] > 0)
    return Drivetrain(
        compliant=compliant,
        reflected_inertia_kg_m2=float(p.J[0] + e_n2 * p.J_L[0]),
        reflected_damping_n_m_s_rad=float(p.mu_v[0] + e_n2 * p.b_L[0]),
        reflected_stiffness_n_m_rad=float(e_n2 * p.K_h[0]),
        plant_stable=not unstable.size,
        plant_unstable_pole_rad_s=float(unstable.max()) if unstable.size else None,
        resonances=_modes(d) if compliant else (),
        anti_resonances=_modes([float(np.squeeze(c)) for c in n_theta]) if compliant else (),
        stable_hinge_stiffness_n_m_rad=(stable_hinge_range(p, pade_order) if hinge_range
                                        else None),
        hinge_stiffness_n_m_rad=float(p.K_h[0]),
    )


def stable_hinge_range(p, pade_order=DEFAULT_PADE_ORDER):
    """(lowest, highest) hinge stiffness [N*m/rad] at the fin with a stable closed loop.

    The stable interval that contains the variant's own K_h if it is stable, else the one
    nearest to it; None for a bound beyond the scan. (None, None) if no scanned K_h is stable.
    """
    scale = float(p.Km[0] * max(p.cp_Kp[0], 1e-12) * p.eta[0] * p.ratio[0] ** 2)
    magnitudes = scale * np.logspace(-_SCAN_DECADES, _SCAN_DECADES, _SCAN_POINTS)
    own = float(p.K_h[0])
    grid = np.unique(np.concatenate([-magnitudes[::-1], [0.0, own], magnitudes]))
    stable = _stable(p, grid, pade_order)
    if not stable.any():
        return (None, None)
    index = int(np.flatnonzero(grid == own)[0])
    if not stable[index]:
        candidates = np.flatnonzero(stable)
        index = int(candidates[np.argmin(np.abs(candidates - index))])
    low, high = index, index
    while low > 0 and stable[low - 1]:
        low -= 1
    while high < grid.size - 1 and stable[high + 1]:
        high += 1
    lower = None if low == 0 else _boundary(p, grid[low - 1], grid[low], pade_order)
    upper = None if high == grid.size - 1 else _boundary(p, grid[high + 1], grid[high],
                                                         pade_order)
    return (lower, upper)


def _stable(p, hinge, pade_order):
    """Bool per hinge stiffness: the closed loop is stable (Padé model of the loops run
    continuously, sampled or not)."""
    batch = p.take(np.zeros(len(hinge), dtype=int)).replace(K_h=np.asarray(hinge, float),
                                                            sample_rates=())
    return stability_verdicts(batch, pade_order)[0] == "stable"


def _boundary(p, unstable, stable, pade_order):
    """The hinge stiffness where the verdict changes between ``unstable`` and ``stable``.

    :data:`_BISECTIONS` halvings of the bracket, :data:`_STEPS_PER_BATCH` of them decided by
    one batch of verdicts: the midpoints of every path those halvings can take
    (:func:`_midpoint_tree`), then the path the verdicts choose. The same midpoints, computed
    the same way, and the same verdicts as one halving per verdict, in a quarter of the calls.
    """
    done = 0
    while done < _BISECTIONS:
        steps = min(_STEPS_PER_BATCH, _BISECTIONS - done)
        middles = _midpoint_tree(unstable, stable, steps)
        verdicts = _stable(p, middles, pade_order)
        node = 0
        for _ in range(steps):
            if verdicts[node]:
                stable, node = middles[node], 2 * node + 1
            else:
                unstable, node = middles[node], 2 * node + 2
        done += steps
    return float(0.5 * (unstable + stable))


def _midpoint_tree(unstable, stable, steps):
    """The midpoints ``0.5 * (unstable + stable)`` of every bracket ``steps`` halvings can
    reach, in heap order: node ``j``'s bracket keeps its lower half (the midpoint was stable)
    in node ``2 j + 1`` and its upper half in node ``2 j + 2``."""
    brackets, middles = [(unstable, stable)], []
    for j in range(2 ** steps - 1):
        low, high = brackets[j]
        middle = 0.5 * (low + high)
        middles.append(middle)
        brackets += [(low, middle), (middle, high)]
    return middles


def drivetrain_notes(load, output="output", spring=("K_h", "N*m/rad")):
    """Plain sentences on what the drivetrain figures mean for stability (``output``: what
    they call the output, the config's ``output_label``; ``spring``: the load spring's symbol
    and unit, :class:`cas_freq.core.output.OutputUnit`)."""
    symbol, unit = spring
    notes = []
    own = load.hinge_stiffness_n_m_rad
    if not load.plant_stable:
        notes.append(
            f"the open-loop plant is statically unstable: the aiding load spring {symbol} "
            f"{own:.4g} {unit} puts a mechanical pole at +{load.plant_unstable_pole_rad_s:.4g} "
            f"rad/s; only feedback can hold the {output}"
        )
    if load.stable_hinge_stiffness_n_m_rad is None:  # not scanned
        return notes
    low, high = load.stable_hinge_stiffness_n_m_rad
    if low is None and high is None:
        notes.append(f"the closed loop is unstable for every load spring {symbol} scanned")
        return notes
    inside = (low is None or own > low) and (high is None or own < high)
    span = (f"{'-inf' if low is None else f'{low:.4g}'} .. "
            f"{'+inf' if high is None else f'{high:.4g}'} {unit}")
    if inside:
        margin = [] if low is None else [f"{own - low:.4g} {unit} more aiding stiffness"]
        margin += [] if high is None else [f"{high - own:.4g} {unit} more opposing"]
        notes.append(f"closed loop stable for load spring {symbol} {span} at the {output}; it is "
                     f"lost with {' or '.join(margin) or 'no stiffness within the scan'}")
    else:
        notes.append(f"closed loop unstable at this load spring {symbol} ({own:.4g} {unit}); "
                     f"the nearest stable range is {span}")
    return notes


def derived_load_notes(config):
    """Sentences on the load values a validated config derives from a description: the load
    inertia from an inertia simulant's geometry, the efficiencies from a worm's."""
    notes = []
    simulant = getattr(config.load, "simulant", None)
    if simulant is not None:
        bore = f", bore {1e3 * simulant.bore:g} mm" if simulant.bore else ""
        notes.append(f"load inertia J_L = {simulant.inertia:.4g} kg*m^2 at the "
                     f"{config.output_label}: the {simulant.name}, a disc of "
                     f"{1e3 * simulant.diameter:g} mm diameter and {1e3 * simulant.thickness:g} "
                     f"mm thickness{bore}, {simulant.density:g} kg/m^3")
    worm = getattr(config.gear, "worm", None)
    if worm is not None:
        locking = " (self-locking)" if config.gear.backdrive == 0 else ""
        notes.append(f"gear efficiencies from the worm (lead angle "
                     f"{math.degrees(worm.lead_angle):.4g} deg, friction "
                     f"{worm.friction_coefficient:g}, pressure angle "
                     f"{math.degrees(worm.pressure_angle):.4g} deg): forward "
                     f"{config.gear.efficiency:.4g}, backdrive {config.gear.backdrive:.4g}"
                     f"{locking}")
    return notes
