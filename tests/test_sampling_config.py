"""Issue 26: the ``sampling:`` declaration (rates per loop, ``method``), its rules, its older
spelling ``simulation.controllers: sampled``, and the static ``LoopParameters.sample_rates`` /
``sampling_method`` that carry it to the model and the simulator.

Every test here fails before issue 26: the config refused ``sampling:`` as an unknown key,
LoopParameters had no ``sample_rates``, and the simulator's refusal named
``simulation.controllers`` only. The last test pins that a config without ``sampling:`` stays
continuous, as before.
"""

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.config import load_all_variants, load_variant, parse_set_option
from cas_freq.config.loader import shipped_configs_dir, validate
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import STATIC_FIELDS, LoopParameters, variant_parameters
from cas_freq.model.loops import Selector

CASCADE = shipped_configs_dir() / "cascade_axis.yaml"
EPOS4 = [("sampling.current_loop", "25 kHz"), ("sampling.position_loop", "2.5 kHz")]
EPOS4_PAIRS = (("current_loop", 25e3), ("position_loop", 2.5e3))


def _error(overrides, path=None):
    """The one-line message of loading the shipped (or ``path``'s) base with ``overrides``."""
    with pytest.raises(ConfigError) as info:
        load_variant(path, "base", overrides)
    message = str(info.value)
    assert "\n" not in message
    return message.split(": ", 1)[1]  # after the file and overrides


# ---- each rule: one line naming the key, the value and what is accepted ----------------------

@pytest.mark.parametrize("overrides, path, expected", [
    # a rate is > 0, within 1..1e9 Hz, in a frequency unit (the parameter table's bound)
    ([("sampling.current_loop", "0 Hz")], None,
     "sampling.current_loop: must be >= 1 and <= 1e+09 Hz, got '0 Hz'"),
    ([("sampling.current_loop", "-25 kHz")], None,
     "sampling.current_loop: must be >= 1 and <= 1e+09 Hz, got '-25 kHz'"),
    ([("sampling.position_loop", "2 GHz")], None,
     "sampling.position_loop: must be >= 1 and <= 1e+09 Hz, got '2 GHz'"),
    ([("sampling.current_loop", "25000 rad/s")], None,
     "sampling.current_loop: cannot read '25000 rad/s' as a value in Hz"),
    ([("sampling.method", "zoh")], None,
     "sampling.method: must be one of 'backward' or 'tustin', got 'zoh'"),
    ([("sampling.fast_loop", "1 kHz")], None,
     "sampling.fast_loop: unknown key (value '1 kHz'); sampling accepts current_loop, "
     "velocity_loop, position_loop, method"),
    # a loop the architecture has
    ([*EPOS4, ("sampling.velocity_loop", "5 kHz")], None,
     "sampling.velocity_loop: the config has no velocity_loop section, got 5000 Hz; accepted: "
     "sampling.current_loop and sampling.position_loop"),
    # the current loop sampled whenever any loop is
    ([("sampling.position_loop", "2 kHz")], None,
     "sampling.current_loop: absent (continuous) while sampling.position_loop is 2000 Hz; "
     "accepted: a current-loop rate whenever any loop is sampled (a continuous current loop "
     "inside a sampled loop is not modelled)"),
    ([("sampling.velocity_loop", "5 kHz")], CASCADE,
     "sampling.current_loop: absent (continuous) while sampling.velocity_loop is 5000 Hz"),
    # the inner loop not slower than the outer
    ([("sampling.current_loop", "25 kHz"), ("sampling.position_loop", "50 kHz")], None,
     "sampling.position_loop: 50000 Hz is faster than sampling.current_loop (25000 Hz) inside "
     "it; accepted: at most 25000 Hz"),
    # an integer multiple of the next outer sampled loop (25000/3000 = 8.33; 25000/8 = 3125,
    # 25000/9 = 2777.78)
    ([("sampling.current_loop", "25 kHz"), ("sampling.position_loop", "3 kHz")], None,
     "sampling.position_loop: 3000 Hz is not sampling.current_loop (25000 Hz) divided by an "
     "integer (ratio 8.33333); accepted: 25000 Hz/N, e.g. 3125 Hz (N = 8) or 2777.78 Hz "
     "(N = 9): multirate must be exact"),
    # the velocity loop is the next outer sampled loop of the current loop (20000/3000 = 6.67),
    # then of the position loop (5000/2000 = 2.5)
    ([("sampling.current_loop", "20 kHz"), ("sampling.velocity_loop", "3 kHz")], CASCADE,
     "sampling.velocity_loop: 3000 Hz is not sampling.current_loop (20000 Hz) divided by an "
     "integer (ratio 6.66667)"),
    ([("sampling.current_loop", "20 kHz"), ("sampling.velocity_loop", "5 kHz"),
      ("sampling.position_loop", "2 kHz")], CASCADE,
     "sampling.position_loop: 2000 Hz is not sampling.velocity_loop (5000 Hz) divided by an "
     "integer (ratio 2.5)"),
])
def test_each_rule_refuses_with_one_line_naming_key_value_and_accepted(overrides, path, expected):
    assert _error(overrides, path).startswith(expected)


def test_a_refused_sampling_exits_2_from_the_cli():
    code, out, err = run_cli(["analyze", "--set", "sampling.position_loop=2 kHz"])
    assert code == 2 and out == ""
    assert "sampling.current_loop: absent (continuous) while sampling.position_loop is 2000 Hz" \
        in err


def test_accepted_rates_innermost_first():
    # the rate ratios are exact integers: 20 kHz / 5 kHz = 4, 5 kHz / 1 kHz = 5; a loop left
    # out between two sampled ones is continuous (only the sampled loops are listed)
    cascade = load_variant(CASCADE, "base", [
        ("sampling.current_loop", "20 kHz"), ("sampling.velocity_loop", "5 kHz"),
        ("sampling.position_loop", "1 kHz"), ("sampling.method", "tustin")]).params
    loop = LoopParameters.from_config(cascade)
    assert loop.sample_rates == (("current_loop", 20e3), ("velocity_loop", 5e3),
                                 ("position_loop", 1e3))
    assert loop.sampling_method == "tustin"
    # equal rates are an integer multiple (1)
    same = load_variant(None, "base", [("sampling.current_loop", "10 kHz"),
                                       ("sampling.position_loop", "10 kHz")]).params
    assert same.sampling.sample_rates == (("current_loop", 1e4), ("position_loop", 1e4))


def test_every_loop_is_sampled_once_one_is():
    # a continuous position loop around a sampled current loop would be faster than the loop
    # inside it; a continuous velocity loop between two sampled loops likewise
    with pytest.raises(ConfigError, match=r"sampling\.position_loop: absent \(continuous\) "
                                          r"while sampling\.current_loop are sampled"):
        load_variant(None, "base", [("sampling.current_loop", "25 kHz")])
    with pytest.raises(ConfigError, match=r"sampling\.velocity_loop: absent"):
        load_variant(CASCADE, "base", [("sampling.current_loop", "25 kHz"),
                                       ("sampling.position_loop", "2.5 kHz")])


# ---- the two spellings ----------------------------------------------------------------------

def test_the_older_spelling_is_the_same_declaration():
    new = load_variant(None, "base", EPOS4).params
    old = load_variant(None, "base", [("simulation.controllers", "sampled")]).params
    # both sections state the one declaration once validated: the configs are equal
    assert new == old
    assert new.sampling.sample_rates == EPOS4_PAIRS and new.sampling.method == "backward"
    assert new.simulation.controllers == "sampled"
    assert new.simulation.rates_hz == old.simulation.rates_hz == (25e3, 2.5e3)
    assert LoopParameters.from_config(old).sample_rates == EPOS4_PAIRS
    # both given and the same: accepted, sampling.method joins the older spelling's rates
    both = load_variant(None, "base", [("simulation.controllers", "sampled"), *EPOS4]).params
    assert both == new
    tustin = load_variant(None, "base", [("simulation.controllers", "sampled"),
                                         ("sampling.method", "tustin")]).params
    assert tustin.sampling.sample_rates == EPOS4_PAIRS and tustin.sampling.method == "tustin"
    # the older spelling's rates at other values
    other = load_variant(None, "base", [("simulation.controllers", "sampled"),
                                        ("simulation.current_loop_rate", "20 kHz"),
                                        ("simulation.position_loop_rate", "4 kHz")]).params
    assert other.sampling.sample_rates == (("current_loop", 2e4), ("position_loop", 4e3))


@pytest.mark.parametrize("overrides, expected", [
    ([("simulation.controllers", "sampled"), ("sampling.current_loop", "25 kHz"),
      ("sampling.position_loop", "2 kHz")],
     "sampling.position_loop: 2000 Hz, but simulation.position_loop_rate is 2500 Hz "
     "(simulation.controllers: sampled, the older spelling of the same declaration); accepted: "
     "the same rates in both spellings, or one spelling only (drop simulation.controllers: "
     "sampled)"),
    ([("simulation.controllers", "sampled"), ("sampling.current_loop", "25 kHz")],
     "sampling.position_loop: absent (continuous), but simulation.position_loop_rate is 2500 Hz"),
    ([("simulation.controllers", "sampled"), ("simulation.current_loop_rate", "50 kHz"),
      *EPOS4],
     "sampling.current_loop: 25000 Hz, but simulation.current_loop_rate is 50000 Hz"),
])
def test_both_spellings_given_and_different_is_an_error(overrides, expected):
    assert _error(overrides).startswith(expected)


def test_rates_hz_follows_sampling_and_the_simulator_samples():
    # simulation.rates_hz (what the simulator reads) comes from sampling: even where the file
    # says controllers: continuous (the shipped qt_cas.yaml does): that value declares nothing
    params = load_variant(None, "base", EPOS4).params
    assert params.simulation.rates_hz == (25e3, 2.5e3)
    from cas_freq.simulation.commands import Step
    from cas_freq.simulation.simulator import simulate_batch

    current, position = params.simulation.rates_hz
    t_end = 4e-3
    sampled = simulate_batch([params], Step(0.01), t_end=t_end, extend=False,
                             current_rate_hz=current, position_rate_hz=position).run(0)
    continuous = simulate_batch([load_variant(None, "base").params], Step(0.01), t_end=t_end,
                                extend=False).run(0)
    # the position controller's output is held for its 0.4 ms period: at most one value per
    # period (+1 for the initial hold) where the continuous controller's changes every step
    assert len(np.unique(sampled.current_command)) <= t_end * 2.5e3 + 1
    assert len(np.unique(continuous.current_command)) > 100


# ---- --set, variants, dumps -----------------------------------------------------------------

def test_set_reaches_a_sampling_key():
    # 24 kHz / 2 kHz = 12 (25 kHz / 2 kHz = 12.5 is refused above)
    overrides = [parse_set_option("sampling.current_loop=24 kHz"),
                 parse_set_option("sampling.position_loop=2 kHz")]
    assert overrides == [("sampling.current_loop", "24 kHz"), ("sampling.position_loop", "2 kHz")]
    params = load_variant(None, "base", overrides).params
    assert params.sampling.sample_rates == (("current_loop", 24e3), ("position_loop", 2e3))


def test_a_sweep_cannot_vary_a_rate_but_fixes_one():
    code, _, err = run_cli(["sweep", "--set", "sampling.current_loop=25kHz,50kHz"])
    assert code == 2
    assert ("sampling.current_loop: cannot be varied (a sample rate is static, one for every run "
            "of a batch: give one value, or a variant per rate)") in err


def test_a_variant_overrides_sampling(write_config, shipped_raw):
    raw = shipped_raw
    raw.pop("load_envelope")  # it names the shipped variants replaced here
    raw["sampling"] = {"current_loop": "25 kHz", "position_loop": "2.5 kHz"}
    raw["variants"] = {
        "slower": {"sampling": {"position_loop": "1 kHz", "method": "tustin"}},
        "analog": {"sampling.current_loop": None, "sampling.position_loop": None},
        "old": {"sampling": {"current_loop": None, "position_loop": None},
                "simulation.controllers": "sampled", "simulation.position_loop_rate": "5 kHz"},
    }
    path = write_config(raw)
    loops = {name: LoopParameters.from_config(load_variant(path, name).params)
             for name in ("base", "slower", "analog", "old")}
    assert loops["base"].sample_rates == EPOS4_PAIRS
    assert loops["slower"].sample_rates == (("current_loop", 25e3), ("position_loop", 1e3))
    assert loops["slower"].sampling_method == "tustin"
    assert loops["analog"].sample_rates == ()
    assert loops["old"].sample_rates == (("current_loop", 25e3), ("position_loop", 5e3))
    # a variant that breaks a rule is reported whichever variant is loaded
    raw["variants"] = {"bad": {"sampling.position_loop": "3 kHz"}}
    with pytest.raises(ConfigError, match=r"variant 'bad'.*sampling.position_loop: 3000 Hz is "
                                          r"not sampling.current_loop \(25000 Hz\)"):
        load_variant(write_config(raw, "bad.yaml"), "base")


@pytest.mark.parametrize("overrides", [EPOS4, [("sampling.current_loop", "50 kHz"),
                                                ("sampling.position_loop", "5 kHz")]])
def test_a_dumped_sampled_config_validates_again(overrides):
    config = load_variant(None, "base", overrides).params
    data = config.model_dump(exclude={"load_envelope", "variants"})
    data["motor"]["no_load"]["speed"] = f"{data['motor']['no_load']['speed']!r} rad/s"
    data["requirements"] = []
    again = validate(data, "test")
    assert again.sampling == config.sampling and again.simulation == config.simulation


# ---- the static fields ----------------------------------------------------------------------

def test_the_static_fields_survive_every_copy():
    base = load_variant(None, "base", EPOS4).params
    fitted = load_variant(None, "fitted", EPOS4).params
    batch = LoopParameters.from_configs([base, fitted])
    assert {"sample_rates", "sampling_method"} <= set(STATIC_FIELDS)
    varied = variant_parameters(base, {"motor.J": [5e-7, 6e-7, 7e-7]})
    copies = [batch, batch.take([1, 0, 1]), batch.run(1), batch.without_feedforward(),
              batch.replace(cascade=False), varied, varied.take(slice(1, 3))]
    for copy in copies:
        assert copy.sample_rates == EPOS4_PAIRS and copy.sampling_method == "backward"
    # the response parameters pass them on unchanged (tuples and strings, not arrays)
    p = Selector(batch.take([0, 1, 0]))(column=True)
    assert p.sample_rates == EPOS4_PAIRS and p.sampling_method == "backward"
    # configs of one batch share their sampling
    with pytest.raises(ConfigError, match="must share their loop structure .*sampling"):
        LoopParameters.from_configs([base, load_variant(None, "fitted").params])


@pytest.mark.parametrize("changes, expected", [
    ({"sample_rates": (("position_loop", 2500.0),)},
     "sampling.current_loop: absent (continuous) while sampling.position_loop is 2500 Hz"),
    ({"sample_rates": (("position_loop", 2500.0), ("current_loop", 25e3))},
     "sample_rates: one pair per loop, innermost first"),
    ({"sample_rates": (("current_loop", 25e3), ("velocity_loop", 5e3))},
     "sampling.velocity_loop: the config has no velocity_loop section"),
    ({"sample_rates": (("current_loop", 0.0),)}, "sample_rates: current_loop: must be a finite "
                                                 "rate > 0 Hz, got 0.0"),
    ({"sample_rates": (("fast_loop", 1e3),)}, "sample_rates: loop names must be among"),
    ({"sample_rates": 25e3}, "sample_rates: must be (loop name, rate [Hz]) pairs"),
    ({"sampling_method": "zoh"}, "sampling_method: must be one of backward, tustin, got 'zoh'"),
])
def test_loop_parameters_check_the_static_sampling(changes, expected):
    loop = LoopParameters.from_config(load_variant(None, "base").params)
    with pytest.raises(ConfigError, match="^simulation parameters: ") as info:
        loop.replace(**changes)
    assert expected in str(info.value)


def test_without_sampling_everything_is_continuous_as_before():
    # unchanged: every variant of every shipped config but the QT-CAS's `sampled` (the one that
    # declares sampling) is continuous
    for path in sorted(shipped_configs_dir().glob("*.yaml")):
        for loaded in load_all_variants(path):
            if loaded.variant == "sampled":
                assert LoopParameters.from_config(loaded.params).sample_rates == (
                    ("current_loop", 25e3), ("position_loop", 2.5e3))
                continue
            loop = LoopParameters.from_config(loaded.params)
            assert loop.sample_rates == () and loop.sampling_method == "backward", loaded.variant
            assert loaded.params.simulation.rates_hz == (None, None)
            assert variant_parameters(loaded.params, {}).sample_rates == ()
