"""What the nonlinear simulation of a variant has that its linear model does not (no matplotlib).

The report compares a small step of the simulator with the linear model's (Padé delays). When no
limit is hit the two differ only by the elements :func:`nonlinear_elements` names
(docs/model.md §5, "Nonlinear simulation"): the direction-dependent gear efficiency, Coulomb
friction, the constant load moment, backlash, and sampled controllers; with none of them, only
the Padé approximation of the delays is left.
"""

import math

from cas_freq.core.sampling_config import rates_text


def nonlinear_elements(params, loaded):
    """The simulator's elements of a variant that the linear model does not have, as phrases.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
    loaded : bool
        Whether the output carries a load (inertia, damping, stiffness, bias or a compliant
        gear): only then does the gear efficiency act (it scales the reflected load).

    Returns
    -------
    list of str
        E.g. ``"the gear efficiency by the direction of power (η = 0.75 while the motor drives
        the output, η_b = 0.75 while the output drives the motor; the linear model divides the
        reflected load by η both ways)"``, the output named by the config's ``output_label``;
        empty when the simulation has none.
    """
    gear, motor, load = params.gear, params.motor, params.load
    output = params.output_label
    found = []
    efficiency, backdrive = gear.efficiency, gear.backdrive
    if loaded and (efficiency != 1.0 or backdrive != 1.0):
        found.append(f"the gear efficiency by the direction of power (η = {efficiency:g} while "
                     f"the motor drives the {output}, η_b = {backdrive:g} while the {output} "
                     "drives the motor; the linear model divides the reflected load by η both "
                     "ways)")
    if motor.coulomb_friction:
        found.append(f"Coulomb friction of {1e3 * motor.coulomb_friction:g} mN·m on the motor "
                     "shaft")
    if params.linear and load.bias:
        found.append(f"a constant load force of {load.bias:g} N on the {output}")
    elif not params.linear and load.hinge_bias:
        found.append(f"a constant load moment of {load.hinge_bias:g} N·m on the {output}")
    if gear.backlash:
        play = (f"{1e3 * gear.backlash:.3g} mm" if params.linear else
                f"{math.degrees(gear.backlash):.3g}°")
        found.append(f"a gear backlash of {play}")
    if params.sampling.sample_rates:
        found.append(f"sampled controllers ({rates_text(params.sampling.sample_rates)}, "
                     "zero-order hold)")
    return found
