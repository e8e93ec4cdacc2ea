"""What text calls the actuator's output: the config's ``output_name``, else "output".

Labels and text say "output" unless the config names its output (``output_name: fin`` in
configs/qt_cas.yaml, the QT-CAS being a fin actuator). One config's name is its
:attr:`~cas_freq.config.schema.ActuatorConfig.output_label`; the helpers here name it where
several configs meet (compare) and in the generic text of the tables
(:data:`~cas_freq.core.parameters.PARAMETERS`), which say "the output". Data keys (JSON
fields, CSV columns, API attributes) never depend on it.

Besides its name, the words follow the output's kind and role (:class:`OutputWords`): an angle
(δ) or, at a linear output (``gear.screw_lead``), a position (x); the flight-control words (the
flight-control system, the deflection δ/δ_cmd and the hinge moment M) only where the config
says the output is a control surface (``control_surface: true``).
"""

import dataclasses
import re

#: What text calls an output its config does not name.
OUTPUT = "output"

_THE_OUTPUT = re.compile(r"\bthe output\b")


def common_output_label(configs):
    """What text calls the output of several configs: their ``output_label`` when they all
    agree, else "output".

    Parameters
    ----------
    configs : iterable of cas_freq.config.ActuatorConfig

    Returns
    -------
    str
    """
    names = {config.output_label for config in configs}
    return names.pop() if len(names) == 1 else OUTPUT


def name_the_output(text, label):
    """``text`` written generically ("the output") naming the output ``label`` instead:
    ``name_the_output("load inertia J_L at the output", "fin")`` is
    ``"load inertia J_L at the fin"``.

    Parameters
    ----------
    text : str
    label : str
        An ``output_label`` (:func:`common_output_label` for several configs).

    Returns
    -------
    str
    """
    return text if label == OUTPUT else _THE_OUTPUT.sub(f"the {label}", text)


@dataclasses.dataclass(frozen=True)
class OutputWords:
    """The words of one config's output: its name, its kind and its role.

    Attributes
    ----------
    label : str
        What text calls the output (``output_label``: ``"fin"``, ``"rod"``, ``"output"``).
    linear : bool
        A linear output (``gear.screw_lead``): a position x [m], not an angle δ [rad].
    control_surface : bool
        The config says the output is a control surface (``control_surface: true``): text
        speaks of the flight-control system and of δ/δ_cmd.
    """

    label: str = OUTPUT
    linear: bool = False
    control_surface: bool = False

    @classmethod
    def of(cls, config):
        """The words of a validated config (an ``ActuatorConfig``); None gives the generic
        rotary output's."""
        if config is None:
            return cls()
        return cls(getattr(config, "output_label", OUTPUT), bool(getattr(config, "linear", False)),
                   bool(getattr(config, "control_surface", False)))

    @property
    def quantity(self):
        """``"angle"`` or ``"position"``."""
        return "position" if self.linear else "angle"

    @property
    def value(self):
        """The output's value as text names it: ``"fin angle"``, ``"rod position"``."""
        return f"{self.label} {self.quantity}"

    @property
    def symbol(self):
        """Its symbol in tables and figure labels: ``"δ"`` (an angle) or ``"x"`` (a length)."""
        return "x" if self.linear else "δ"

    @property
    def load(self):
        """What the load applies at the output: ``"load torque"`` or ``"load force"``."""
        return "load force" if self.linear else "load torque"

    @property
    def definition(self):
        """The output in the motor angle θ: ``"fin angle δ = θ / gear ratio"``, ``"rod position
        x = θ·lead / (2π·gear ratio)"`` (docs/model.md, "Linear output")."""
        if self.linear:
            return f"{self.value} x = θ·lead / (2π·gear ratio)"
        return f"{self.value} δ = θ / gear ratio"

    @property
    def closed_loop(self):
        """The closed loop's definition in the terminal's text: ``"T = delta/delta_cmd"`` at a
        control surface, else ``"T = rod position / its command"``."""
        if self.control_surface:
            return "T = delta/delta_cmd"
        return f"T = {self.value} / its command"

    @property
    def compliance(self):
        """The dynamic stiffness's definition in text: ``"1/|delta/M|"`` at a control surface,
        else ``"1/|output angle per load torque|"``."""
        if self.control_surface:
            return "1/|delta/M|"
        return f"1/|{self.value} per {self.load}|"

    @property
    def effort(self):
        """The control effort's definition in text: ``"|i/delta_cmd|"`` at a control surface,
        else ``"|current per output angle command|"``."""
        if self.control_surface:
            return "|i/delta_cmd|"
        return f"|current per {self.value} command|"

    @property
    def compliance_symbol(self):
        """The dynamic stiffness in a table's symbols: ``"1/|δ/M_load|"``, ``"1/|x/F_load|"``."""
        return "1/|x/F_load|" if self.linear else "1/|δ/M_load|"

    @property
    def effort_symbol(self):
        """The control effort in a table's symbols: ``"|i/δ_cmd|"``, ``"|i/x_cmd|"``."""
        return f"|i/{self.symbol}_cmd|"

    @property
    def seen(self):
        """The heading of the closed loop's figures besides the command (dynamic stiffness,
        control effort, encoder noise): ``"what the flight-control system sees"`` at a control
        surface, else ``"stiffness, effort and noise"``."""
        return ("what the flight-control system sees" if self.control_surface
                else "stiffness, effort and noise")


#: The words of an output its config neither names nor calls a control surface (a rotary one).
GENERIC = OutputWords()
