"""The figure table (cas_freq.core.figures) against the commands' JSON: every figure's key resolves
to
a number of the command that measures it, and every number of those JSON groups is a figure of
the table or a declared test condition; the requirements, the report and the comparison read
their names, units and labels from it."""

import json

import pytest
from clirun import run_cli

from cas_freq.config.requirement import METRICS, Requirement, metric_unit
from cas_freq.core.figures import CONDITIONS, FIGURES, LOOPS, json_values, loop_label
from cas_freq.core.output import LENGTH
from cas_freq.core.parameters import PARAMETERS

#: One run per command, on the shipped config's base variant (a few seconds in all): a 10° step
#: (its fit too), a sine-dwell at 10° on a two-point grid that brackets its −3 dB point (426
#: rad/s on the report's grid; here interpolated between 200 and 1000 rad/s) and the profile
#: move of docs/model.md ("Profile moves").
COMMANDS = {
    "analyze": ["analyze", "--json"],
    # a loaded variant: its JSON has the drivetrain group as well
    "analyze loaded": ["analyze", "--variant", "loaded", "--json"],
    # a drive with a velocity loop: its JSON has the velocity loop's figures
    "analyze cascade": ["analyze", "configs/cascade_axis.yaml", "--json"],
    "step": ["simulate", "--step", "10deg", "--json"],
    "sinedwell": ["sinedwell", "--amplitudes", "10deg", "--frequencies", "200,1000", "--json"],
    "profile": ["simulate", "--profile", "10deg", "--velocity", "2000deg/s",
                "--acceleration", "1e5deg/s^2", "--json"],
    # a linear output (configs/ball_screw.yaml): its output quantities are the twins in mm
    "analyze linear": ["analyze", "configs/ball_screw.yaml", "--json"],
    "step linear": ["simulate", "configs/ball_screw.yaml", "--step", "5mm", "--json"],
    "sinedwell linear": ["sinedwell", "configs/ball_screw.yaml", "--amplitudes", "2mm",
                         "--frequencies", "50,400", "--json"],
    "profile linear": ["simulate", "configs/ball_screw.yaml", "--profile", "5mm", "--velocity",
                       "100mm/s", "--acceleration", "2000mm/s^2", "--json"],
}

#: The groups of each command's JSON whose numbers are figures (dotted, ``*``: each element of
#: a list). Not figures: the config's identity, the settings of the run, the time series and
#: the lists of every crossing or confidence interval (lists are not leaves here).
GROUPS = {
    "analyze": ("current_loop", "position_loop", "closed_loop", "stiffness", "effort",
                "envelope"),
    "analyze linear": ("current_loop", "position_loop", "closed_loop", "envelope",
                       "stiffness", "effort"),
    "analyze loaded": ("current_loop", "position_loop", "closed_loop", "drivetrain"),
    "analyze cascade": ("current_loop", "velocity_loop", "position_loop", "closed_loop"),
    "step": ("step", "fit"),
    "sinedwell": ("amplitudes.*",),
    "profile": ("profile",),
    "step linear": ("step", "fit"),
    "sinedwell linear": ("amplitudes.*",),
    "profile linear": ("profile",),
}


#: Nulls of those groups that stand for an object, not a number: the bound a sine-dwell grid
#: gives when it holds no −3 dB crossing ({"relation": ">", "edge_rad_s": ...}; the absent text
#: of sinedwell.bandwidth_rad_s).
NOT_NUMBERS = {"amplitudes.*.bandwidth_bound"}


@pytest.fixture(scope="module")
def outputs():
    data = {}
    for command, argv in COMMANDS.items():
        code, out, err = run_cli(argv)
        assert code == 0, err
        data[command] = json.loads(out)
    return data


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@pytest.mark.parametrize("key", list(FIGURES))
def test_every_figure_resolves_in_its_commands_json(outputs, key):
    figure = FIGURES[key]
    command = ("analyze loaded" if key.startswith("drivetrain.") else
               "analyze cascade" if key.startswith("velocity_loop.") else
               f"{figure.command} linear" if figure.output == "length" else figure.command)
    values = json_values(figure, outputs[command])  # KeyError: no such key
    assert values, key
    for value in values:
        if not figure.requirement:
            continue  # a flag or a verdict: present is enough
        # a requirement's figure is a number, or null where the table says when
        assert _is_number(value) or (value is None and figure.absent), (key, value)


def test_the_runs_give_numbers_where_the_shipped_config_has_them(outputs):
    # on the base variant only the lower gain margin of the current loop (no phase crossover
    # where |L_i| > 1, docs/model.md §7's table: "—") is absent; every other requirement figure
    # is a number, so the previous test checked real values, not nulls
    missing = sorted(key for key, figure in FIGURES.items() if figure.requirement
                     and not key.startswith("velocity_loop.") and figure.output != "length"
                     and None in json_values(figure, outputs[figure.command]))
    # (with the position loop closed, L_i has the position loop's two integrators: a lower
    # margin exists there)
    # (the shipped config gives no sensors.counts_per_rev: no encoder-noise figure)
    assert missing == ["current_loop.gain_margin_low_db", "current_loop.phase_crossover_low_rad_s",
                       "noise.current_rms_A"]


@pytest.mark.parametrize("command", list(COMMANDS))
def test_every_number_of_a_figure_group_is_in_the_table(outputs, command):
    linear = command.endswith(" linear")  # the output quantities' twins in mm
    known = {f.json_key for f in FIGURES.values() if f.command == command.split()[0]
             and f.output != ("angle" if linear else "length")}
    known |= {LENGTH.key(key) if linear else key
              for key in CONDITIONS.get(command.split()[0] if linear else command, ())}
    for group in GROUPS[command]:
        node = [outputs[command]]
        for part in group.split("."):
            node = ([item for value in node for item in value] if part == "*"
                    else [value[part] for value in node])
        # the scalars of the group: not its lists (every crossing, the confidence intervals,
        # the dwell's responses) nor its sub-groups (the step and fit under each sine-dwell
        # amplitude are the step command's figures, checked there)
        numbers = {f"{group}.{key}" for value in node for key, item in value.items()
                   if _is_number(item) or item is None}
        numbers -= NOT_NUMBERS
        assert numbers, group
        assert numbers - known == set(), f"{command}: numbers without a figure record"


def test_requirement_metrics_are_the_tables_with_their_units():
    assert METRICS == {key: f.command for key, f in FIGURES.items() if f.requirement}
    # the unit each key's suffix names (the rule requirement bounds are written by)
    suffixes = (("_rad_s", "rad/s"), ("_deg", "deg"), ("_db", "dB"), ("_pct", "percent"),
                ("_s", "s"), ("_a", "A"), ("_v", "V"))
    for key in METRICS:
        name = key.rpartition(".")[2]
        expected = next((unit for suffix, unit in (*suffixes, ("_mm", "mm"))
                         if name.endswith(suffix)), None)
        if expected is not None:
            assert metric_unit(key) == expected, key
    assert metric_unit("fit.zeta") == "" and metric_unit("fit.rms_residual") == "rad"
    with pytest.raises(ValueError, match="no unit known"):
        metric_unit("position_loop.stability")  # a verdict, not a requirement figure
    # a figure the table shows but no requirement bounds is refused by name
    with pytest.raises(ValueError, match="unknown figure 'step.current_limited'"):
        Requirement(id="X", metric="step.current_limited", max=0, step="10 deg")


def test_loop_figures_are_declared_once_per_loop_with_their_loop():
    per_loop = {loop: sorted(f.name for f in FIGURES.values() if f.loop == loop
                             and f.requirement) for loop in LOOPS}
    assert per_loop["current_loop"] == per_loop["position_loop"]
    assert len(per_loop["position_loop"]) == 13  # 12 before delay_margin_crossover_rad_s
    assert FIGURES["position_loop.loop_at_a_time.phase_margin_deg"].loop == (
        "position_loop.loop_at_a_time")
    assert FIGURES["closed_loop.bandwidth_rad_s"].loop is None
    assert loop_label("velocity_loop.loop_at_a_time") == (
        "velocity loop, every other loop closed")
    # the shown value and the column heading follow the unit and factor
    delay = FIGURES["position_loop.delay_margin_s"]
    assert delay.shown(0.002) == pytest.approx(2.0) and delay.heading == "delay margin [ms]"
    assert delay.shown(None) is None and FIGURES["fit.zeta"].heading == "damping ratio ζ"
    # every display factor is the conversion its units name
    for figure in FIGURES.values():
        if figure.shown_unit == "ms":
            assert (figure.unit, figure.scale) == ("s", 1e3), figure.key
        elif figure.key == "fit.rms_residual":
            assert figure.shown_unit == "deg" and figure.scale == pytest.approx(57.29577951)
        else:
            assert figure.scale == 1.0 and figure.unit_label == figure.shown_unit, figure.key


def test_verify_reads_the_field_the_json_prints(outputs):
    # verify measures a figure as the typed result's attribute path named by the metric
    # (cas_freq.verify.measure.figure): the same number the analyze JSON prints under the key
    from cas_freq.analysis import analyze
    from cas_freq.config import default_config_path, load_variant
    from cas_freq.verify.measure import figure

    analyses = {"analyze": analyze(load_variant(default_config_path(), "base")),
                 "analyze cascade": analyze(load_variant("configs/cascade_axis.yaml", "base")),
                 "analyze linear": analyze(load_variant("configs/ball_screw.yaml", "base"))}
    for key, command in METRICS.items():
        if command == "analyze":
            run = ("analyze cascade" if key.startswith("velocity_loop.") else
                   "analyze linear" if FIGURES[key].output == "length" else "analyze")
            (printed,) = json_values(FIGURES[key], outputs[run])
            assert figure(analyses[run], key) == printed, key


def test_the_reports_tables_read_the_labels_of_the_tables():
    from cas_freq.report.parameter_table import _LOAD_KEYS, _PARAMETER_KEYS, parameter_row_head

    # parameter labels and units from cas_freq.core.parameters, "the output" as the config names it
    assert parameter_row_head("load.inertia", "fin") == (
        "load inertia J_L at the fin", "kg·m²", 1.0)
    assert parameter_row_head("motor.L", "output") == ("motor terminal inductance L", "mH", 1e3)
    assert parameter_row_head("gear.backlash", "fin")[1:] == ("deg", pytest.approx(57.29577951))
    assert parameter_row_head("gear.ratio", "fin") == ("gear ratio N", "-", 1.0)
    assert parameter_row_head("position_loop.i_max", "fin")[0] == "current-command limit ±i_max"
    # the table's ASCII symbols as a reader writes them, whole words only
    assert parameter_row_head("motor.mu_v", "fin")[0] == "viscous friction μv"
    assert parameter_row_head("current_loop.delay", "fin")[0] == (
        "current-loop transport delay τc")
    greek = {"μv": "mu_v", "η_b": "eta_b", "η": "eta", "τc": "tau_c", "τp": "tau_p",
             "τ_h": "tau_h", "δ": "delta"}
    for key in _PARAMETER_KEYS + _LOAD_KEYS:
        label = parameter_row_head(key, "output")[0]
        for symbol, ascii_name in greek.items():
            label = label.replace(symbol, ascii_name)
        assert label == PARAMETERS[key].label.replace("+/-", "±")
