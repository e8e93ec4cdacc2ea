"""Config data of the drive architectures for the config tests (made-up numbers)."""


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
