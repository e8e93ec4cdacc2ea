"""The tune's names and defaults, without imports: the CLI builds its parser from them at
start-up, and every command builds that parser."""

#: The objectives, figure, and +1 to maximise or -1 to minimise it.
OBJECTIVES = {
    "max-bandwidth": ("closed_loop.bandwidth_rad_s", 1.0),
    "min-settling": ("step.settling_time_s", -1.0),
    "max-margin": ("position_loop.phase_margin_deg", 1.0),
}

#: Keys freed when ``--free`` is not given.
DEFAULT_FREE = ("position_loop.Kp", "position_loop.Ki", "position_loop.Kd")
#: Keys freed when ``--free`` is not given, in a config with a velocity loop (no Kd there).
CASCADE_DEFAULT_FREE = ("position_loop.Kp", "velocity_loop.Kp", "velocity_loop.Ki")

#: Default range of a key without ``--bounds``: its value divided and multiplied by this.
DEFAULT_FACTOR = 4.0

#: Defaults of the search: global points, refinement rounds and points per round.
GLOBAL_COUNT = 128
ROUNDS = 6
ROUND_COUNT = 32

__all__ = ["CASCADE_DEFAULT_FREE", "DEFAULT_FACTOR", "DEFAULT_FREE", "GLOBAL_COUNT", "OBJECTIVES",
           "ROUNDS", "ROUND_COUNT"]
