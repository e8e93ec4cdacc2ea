"""The "Load and drivetrain" part of a loaded variant's report section.

The linear figures of :mod:`cas_freq.analysis.drivetrain` as a table, and a sentence naming the
nonlinear load terms that act in this variant's step and sine-dwell simulations (so that the
figures beside the linear ones are read as what they are).
"""

import math

from cas_freq.core.figures import FIGURES
from cas_freq.core.numbers import number
from cas_freq.core.output import output_unit
from cas_freq.report.document import Paragraph, Table


def _modes(modes):
    return "; ".join(f"{number(m.frequency_rad_s, 4)} rad/s (ζ {number(m.damping, 3)})"
                     for m in modes) or "—"


def nonlinear_terms(params):
    """The nonlinear load terms of a config as text, or None when there is none."""
    terms = []
    if params.motor.coulomb_friction:
        terms.append(f"Coulomb friction {number(params.motor.coulomb_friction * 1e3, 4)} mN·m "
                     "on the motor shaft")
    if params.gear.backlash:
        play = (f"{number(params.gear.backlash * 1e3, 4)} mm" if params.linear else
                f"{number(math.degrees(params.gear.backlash), 4)}°")
        terms.append(f"backlash {play} (total, at the {params.output_label})")
    if params.linear and params.load.bias:
        terms.append(f"a constant load force {number(params.load.bias, 4)} N")
    elif not params.linear and params.load.hinge_bias:
        terms.append(f"a constant load moment {number(params.load.hinge_bias, 4)} N·m")
    if params.gear.backdrive != params.gear.efficiency:
        terms.append(f"backdrive efficiency {number(params.gear.backdrive, 3)}"
                     + (" (self-locking)" if params.gear.backdrive == 0 else "")
                     + f" against the forward {number(params.gear.efficiency, 3)}")
    return ", ".join(terms) if terms else None


def drivetrain_blocks(data):
    """Blocks for a loaded variant (none for an unloaded one)."""
    load = data.analysis.drivetrain
    if load is None:
        return []

    unit = output_unit(data.loaded.params)
    low, high = load.stable_hinge_stiffness_n_m_rad
    span = ("none scanned" if low is None and high is None else
            f"{'−∞' if low is None else number(low, 4)} .. "
            f"{'+∞' if high is None else number(high, 4)}")
    rows = (
        ("gear", "", "compliant (two masses)" if load.compliant else "rigid"),
        *((FIGURES[f"drivetrain.{name}"].label, FIGURES[f"drivetrain.{name}"].shown_unit,
           number(FIGURES[f"drivetrain.{name}"].shown(getattr(load, name)), 4))
          for name in ("reflected_inertia_kg_m2", "reflected_damping_n_m_s_rad",
                       "reflected_stiffness_n_m_rad")),
        ("open-loop plant", "", "stable" if load.plant_stable else
         f"UNSTABLE, pole at +{number(load.plant_unstable_pole_rad_s, 4)} rad/s"),
        ("resonances (poles of θ/i)", "", _modes(load.resonances)),
        ("anti-resonances (zeros of θ/i)", "", _modes(load.anti_resonances)),
        (f"closed loop stable for {unit.spring} (at the {data.loaded.params.output_label})",
         unit.spring_unit.replace("*", "·"), span),
    )
    blocks = [Table(("load and drivetrain", "unit", "value"), rows,
                    f"load and drivetrain of {data.loaded.variant} (motor shaft unless named)")]
    terms = nonlinear_terms(data.loaded.params)
    if terms:
        blocks.append(Paragraph(
            f"Nonlinear load terms in this variant's steps and sine-dwells: {terms}. The linear "
            "figures above do not see them (they are about the operating point); the step and "
            "bandwidth-versus-amplitude figures below do, beside the linear ones."))
    return blocks
