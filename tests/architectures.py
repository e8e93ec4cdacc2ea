"""Config data of the drive architectures for the config tests (made-up numbers), and a shipped
config with one filter more (:func:`with_filter`)."""

from cas_freq.config.loader import shipped_configs_dir


def as_cascade(raw):
    """Raw config data ``raw`` (changed in place, and returned) made a cascade: the PID
    position loop's derivative, current limit and acceleration feed-forward removed, P-PI gains
    in the cascade's units (Kp [1/s], Ki [1/s^2], ff_v [-]) and a velocity loop."""
    loop = raw["position_loop"]
    for key in ("Kd", "Tf", "i_max", "ff_a", "derivative_on"):
        loop.pop(key, None)
    loop.update(Kp=30.0, Ki=5.0, ff_v=1.0)
    raw["velocity_loop"] = {"Kp": 0.02, "Ki": 1.0, "i_max": "20 A", "delay": "0.1 ms"}
    raw.pop("variants", None)
    raw.pop("load_envelope", None)
    return raw


def with_filter(tmp_path, name, item):
    """A copy in ``tmp_path`` of the shipped config ``name`` with the filter ``item`` (YAML flow
    text, ``{at: ..., type: ...}``) first in its ``filters:`` list: its path."""
    text = (shipped_configs_dir() / name).read_text()
    if "\nfilters:\n" in text:
        text = text.replace("\nfilters:\n", f"\nfilters:\n  - {item}\n", 1)
    else:
        text += f"\nfilters:\n  - {item}\n"
    path = tmp_path / name
    path.write_text(text)
    return path
