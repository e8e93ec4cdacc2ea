"""What text calls the actuator's output: the config's ``output_name``, else "output".

Labels and text say "output" unless the config names its output (``output_name: fin`` in
configs/qt_cas.yaml, the QT-CAS being a fin actuator). One config's name is its
:attr:`~cas_freq.config.schema.ActuatorConfig.output_label`; the helpers here name it where
several configs meet (compare) and in the generic text of the tables (:data:`~cas_freq.parameters.
PARAMETERS`), which say "the output". Data keys (JSON fields, CSV columns, API attributes) never
depend on it.
"""

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
