"""Every figure of merit, declared once: its JSON key, unit, label, meaning and loop.

:data:`FIGURES` is to the figures what :data:`cas_freq.core.parameters.PARAMETERS` is to the
config's
parameters: one :class:`Figure` per figure, by the dotted key requirements name it with
(``position_loop.phase_margin_deg``, ``closed_loop.bandwidth_rad_s``, ``step.overshoot_pct``,
``fit.zeta``, ``sinedwell.bandwidth_rad_s``, ``profile.tracking_error_max_deg``). Each record
says which command's JSON holds it (and where, :attr:`Figure.json_key`), the unit of its value
there (the unit its key's suffix names), the unit and factor it is shown with, a short label,
a one-line meaning (defined in docs/model.md §7) and, for the margins of a loop, the loop
(where it is broken, and its symbol, are the loop structure's:
:class:`cas_freq.model.structure.Loop`). Everything else reads the table:

- the requirements (:mod:`cas_freq.config.requirement`): the accepted ``metric`` names
  (:data:`METRICS`), their units, the command that measures them;
- ``verify`` and ``tune``: the unit a verdict is shown in (:data:`UNIT_LABELS`);
- the report's, the comparison's and the text tables (:mod:`cas_freq.report.build`,
  :mod:`cas_freq.report.compare`, :mod:`cas_freq.report.text`), the plots' axes: labels,
  display units and factors (no label of this table is typed anywhere else; a test scans the
  package for copies).

A loop's figures are declared once (:data:`_LOOP_FIGURES`) and expanded per loop of
:data:`LOOPS`. A few records are figures shown in the tables but not accepted as requirements
(``requirement=False``: flags, verdicts, the time of a peak); the test conditions the JSON
carries beside the figures (a step's amplitude, a move's distance) are
:data:`CONDITIONS`, not figures.

This module imports nothing but the standard library: it is read on the ``verify`` path.
"""

import dataclasses
import math

__all__ = ["CONDITIONS", "FIGURES", "LOOPS", "METRICS", "UNIT_LABELS", "Figure",
           "accepted_metrics", "json_values", "loop_label"]


#: The loops with margins: the group names of their figures in the JSON (docs/model.md §3-4
#: and §13), each broken at its controller's output with the loops inside it closed and those
#: outside open, and (``<loop>.loop_at_a_time``) with every other loop closed. The velocity
#: loop's figures exist only for a drive with one. A loop's symbol and where it is broken are
#: the loop structure's (:class:`cas_freq.model.structure.Loop`: they depend on the drive),
#: not this table's.
LOOPS = ("current_loop", "velocity_loop", "position_loop")
LOOPS += tuple(f"{key}.loop_at_a_time" for key in LOOPS)


def loop_label(key):
    """A key of :data:`LOOPS` in words: ``"position loop"``, ``"position loop, every other
    loop closed"``."""
    loop, _, view = key.partition(".")
    return loop.replace("_", " ") + (", every other loop closed" if view else "")


#: How each unit (pint spelling, as :attr:`Figure.unit`) is shown.
UNIT_LABELS = {"rad/s": "rad/s", "deg": "deg", "dB": "dB", "percent": "%", "s": "s", "A": "A",
               "V": "V", "rad": "rad", "": "", "kg*m^2": "kg·m²", "N*m*s/rad": "N·m·s/rad",
               "N*m/rad": "N·m/rad", "mm": "mm", "N/m": "N/m", "A/rad": "A/rad", "A/m": "A/m",
               "deg/s": "deg/s", "m/s": "m/s", "mm/s": "mm/s", "N*m": "N·m", "N": "N",
               "ohm": "Ω"}


@dataclasses.dataclass(frozen=True)
class Figure:
    """One figure of merit.

    Attributes
    ----------
    key : str
        Dotted key, as requirements name it (``"position_loop.phase_margin_deg"``).
    command : str
        The command whose JSON holds it: ``analyze``, ``step`` (``simulate --step``),
        ``sinedwell`` or ``profile`` (``simulate --profile``).
    unit : str
        Unit of its value in the JSON, as pint spells it (``"rad/s"``, ``"percent"``; ``"dB"``;
        ``""`` dimensionless or not a number).
    label : str
        Short readable label (``"phase margin"``), without the loop or the unit.
    shown_unit : str
        Unit the tables show it in (``"ms"``).
    scale : float
        Factor from the JSON value to ``shown_unit``.
    meaning : str
        One line saying what it is (docs/model.md §7 defines it).
    absent : str
        When the JSON holds null instead of a number ("" when it never does).
    loop : str or None
        Key of :data:`LOOPS` for a loop's figure, else None.
    requirement : bool
        True when a requirement may bound it (a number of the command's JSON); False for a
        figure only shown (a flag, a verdict, the time of a peak).
    json_key : str
        Where the command's JSON holds it, dotted; ``*`` stands for each element of a list (the
        sine-dwell's amplitudes). Default: ``key``.
    output : str
        ``"angle"`` for a quantity of a rotary output (an error, a residual), ``"length"`` for
        its twin at a linear output (``gear.screw_lead``), ``""`` for any other figure.
    twin : str
        The key of the other kind's record of an output quantity
        (``profile.tracking_error_max_mm`` <-> ``profile.tracking_error_max_deg``), else ``""``.
    short : str
        Its symbol or abbreviation where a compact column or a plot's annotation names it
        (``"PM"``), ``""`` for none (the label is then used).
    """

    key: str
    command: str
    unit: str
    label: str
    shown_unit: str
    scale: float
    meaning: str
    absent: str = ""
    loop: str | None = None
    requirement: bool = True
    json_key: str = ""
    output: str = ""
    twin: str = ""
    short: str = ""

    def __post_init__(self):
        if not self.json_key:
            object.__setattr__(self, "json_key", self.key)

    @property
    def name(self):
        """The key's last part (``"phase_margin_deg"``)."""
        return self.key.rpartition(".")[2]

    @property
    def unit_label(self):
        """The JSON unit as shown (``"%"`` for ``"percent"``)."""
        return UNIT_LABELS[self.unit]

    @property
    def heading(self):
        """Label and shown unit as a column or an axis names it (``"delay margin [ms]"``;
        the label alone for a dimensionless figure)."""
        return f"{self.label} [{self.shown_unit}]" if self.shown_unit else self.label

    @property
    def short_name(self):
        """:attr:`short`, else the label (``"PM"``, ``"delay margin"``)."""
        return self.short or self.label

    @property
    def short_heading(self):
        """:attr:`short_name` and the shown unit: ``"PM [deg]"``."""
        name = self.short_name
        return f"{name} [{self.shown_unit}]" if self.shown_unit else name

    def shown(self, value):
        """``value`` [the JSON unit] in :attr:`shown_unit`; None, NaN and flags unchanged."""
        if value is None or isinstance(value, bool | str):
            return value
        return value * self.scale


_MS = ("ms", 1e3)
_NO_CROSSOVER = "no gain crossover (|L| = 1) in the analysed range"
_NOT_STABLE = "the loop is not stable"

#: A loop's figures, declared once and expanded per loop: (name, unit, label, shown unit,
#: scale, meaning, absent).
_LOOP_FIGURES = (
    ("crossover_rad_s", "rad/s", "gain crossover (nearest −1)", "rad/s", 1.0,
     "the gain crossover (|L| = 1) nearest the critical point: the smallest |PM|",
     _NO_CROSSOVER),
    ("phase_margin_deg", "deg", "phase margin", "deg", 1.0,
     "180° + ∠L at that gain crossover, modulo 360° into (−180°, 180°]", _NO_CROSSOVER),
    ("delay_margin_s", "s", "delay margin", *_MS,
     "the smallest over all gain crossovers of the smallest positive extra delay that puts L on "
     "−1 there", _NO_CROSSOVER),
    ("delay_margin_crossover_rad_s", "rad/s", "crossover of the smallest delay margin", "rad/s",
     1.0, "the gain crossover at which the delay margin is smallest", _NO_CROSSOVER),
    ("gain_margin_db", "dB", "gain margin (upper)", "dB", 1.0,
     "−20·log10|L| at a phase crossover, the smallest positive (upper) one",
     "no phase crossover with an upper margin in the analysed range"),
    ("phase_crossover_rad_s", "rad/s", "upper gain margin's phase crossover", "rad/s", 1.0,
     "frequency of the upper gain margin's phase crossover (L real and negative)",
     "no phase crossover with an upper margin in the analysed range"),
    ("gain_margin_low_db", "dB", "gain margin (lower)", "dB", 1.0,
     "−20·log10|L| at a phase crossover where |L| > 1, the one closest to 0 dB",
     "no phase crossover with a lower margin in the analysed range"),
    ("phase_crossover_low_rad_s", "rad/s", "lower gain margin's phase crossover", "rad/s", 1.0,
     "frequency of the lower gain margin's phase crossover",
     "no phase crossover with a lower margin in the analysed range"),
    ("sensitivity_peak_db", "dB", "sensitivity peak Ms", "dB", 1.0,
     "Ms = max |S| = max 1/|1 + L| in dB", _NOT_STABLE),
    ("sensitivity_peak_rad_s", "rad/s", "frequency of the sensitivity peak", "rad/s", 1.0,
     "the frequency at which |S| is largest", _NOT_STABLE),
    ("disk_margin_alpha", "", "disk margin α", "", 1.0,
     "α = 1 / max |S − 1/2| (symmetric disk margin, skew 0)", _NOT_STABLE),
    ("disk_margin_gain_db", "dB", "disk gain margin ±", "dB", 1.0,
     "± 20·log10((2 + α)/(2 − α)): gain variation tolerated together with the disk phase margin",
     f"{_NOT_STABLE}, or unbounded (α ≥ 2)"),
    ("disk_margin_phase_deg", "deg", "disk phase margin ±", "deg", 1.0,
     "± 2·atan(α/2): phase variation tolerated together with the disk gain margin",
     _NOT_STABLE),
)

#: The short names of a loop's figures (:attr:`Figure.short`).
_LOOP_SHORT = {"crossover_rad_s": "ωc", "phase_margin_deg": "PM", "gain_margin_db": "GM",
               "gain_margin_low_db": "lower GM", "sensitivity_peak_db": "Ms"}

_UNSTABLE_T = "the closed loop is not stable"

#: Every other figure: (key, command, unit, label, shown unit, scale, meaning, absent[,
#: {keyword: value}]).
_OTHER_FIGURES = (
    # the closed loop T = δ/δ_cmd (analyze)
    ("closed_loop.dc_gain_db", "analyze", "dB", "DC gain |T(0)|", "dB", 1.0,
     "|T(0)| in dB (0 dB with integral action)", _UNSTABLE_T),
    ("closed_loop.bandwidth_rad_s", "analyze", "rad/s", "bandwidth ω_BW (−3.01 dB)", "rad/s",
     1.0, "lowest frequency at which |T| is 3.0103 dB below |T(0)|",
     f"{_UNSTABLE_T}, or |T| stays above −3.01 dB in the analysed range", {"short": "ω_BW"}),
    ("closed_loop.peak_db", "analyze", "dB", "resonance peak", "dB", 1.0,
     "max |T|/|T(0)| in dB, at an interior maximum of |T|",
     f"{_UNSTABLE_T}, or |T| has no interior maximum", {"short": "peak"}),
    ("closed_loop.peak_rad_s", "analyze", "rad/s", "frequency of the resonance peak", "rad/s",
     1.0, "the frequency of the resonance peak",
     f"{_UNSTABLE_T}, or |T| has no interior maximum"),
    ("closed_loop.phase_90_rad_s", "analyze", "rad/s", "frequency of −90° phase", "rad/s", 1.0,
     "lowest frequency at which the phase of T, unwrapped from DC, reaches −90°",
     f"{_UNSTABLE_T}, or the phase does not reach −90° in the analysed range"),
    # a nonlinear step (simulate --step; the report's linear steps have the same figures)
    ("step.rise_time_s", "step", "s", "rise time 10–90 %", *_MS,
     "from the first time δ reaches 10 % of the step to the first time it reaches 90 %",
     "the output never reaches 90 % of the step"),
    ("step.overshoot_pct", "step", "percent", "overshoot", "%", 1.0,
     "(peak − final)/final in %, 0 if δ never exceeds the final value"),
    ("step.settling_time_s", "step", "s", "settling time ±2 %", *_MS,
     "the last time δ is outside ±2 % of the step", "not settled by the end of the run"),
    ("step.settling_time_5pct_s", "step", "s", "settling time ±5 %", *_MS,
     "the last time δ is outside ±5 % of the step", "not settled by the end of the run"),
    ("step.peak_time_s", "step", "s", "peak time", *_MS, "the time of the largest δ"),
    ("step.max_current_a", "step", "A", "largest |current|", "A", 1.0,
     "the largest |i| during the run", "a linear step (no current computed)"),
    ("step.max_voltage_v", "step", "V", "largest |voltage|", "V", 1.0,
     "the largest |V| during the run", "a linear step (no voltage computed)"),
    ("step.current_limited", "step", "", "current limit reached", "", 1.0,
     "whether the ±i_max clamp acted", "a linear step (no limits)", {"requirement": False}),
    ("step.voltage_limited", "step", "", "voltage limit reached", "", 1.0,
     "whether the ±v_max clamp acted", "a linear step (no limits)", {"requirement": False}),
    # the second-order-plus-delay fit of that step (docs/model.md §7)
    ("fit.wn_rad_s", "step", "rad/s", "natural frequency ωn", "rad/s", 1.0,
     "ωn of the second-order-plus-delay model fitted to the step"),
    ("fit.zeta", "step", "", "damping ratio ζ", "", 1.0,
     "ζ of the second-order-plus-delay model fitted to the step"),
    ("fit.td_s", "step", "s", "delay td", *_MS,
     "td of the second-order-plus-delay model fitted to the step"),
    ("fit.bandwidth_closed_form_rad_s", "step", "rad/s", "closed-form bandwidth", "rad/s", 1.0,
     "ωn·sqrt((1 − 2ζ²) + sqrt(4ζ⁴ − 4ζ² + 2)): the −3 dB point of the fitted model"),
    ("fit.rms_residual", "step", "rad", "RMS residual", "deg", math.degrees(1.0),
     "RMS of the fitted model's step response minus the simulated one"),
    ("fit.success", "step", "", "fit converged", "", 1.0,
     "whether the least-squares fit converged", "", {"requirement": False}),
    # the sine-dwell (feed-forward off)
    ("sinedwell.bandwidth_rad_s", "sinedwell", "rad/s", "bandwidth ω_BW (−3.01 dB)", "rad/s",
     1.0, "−3.0103 dB point of the first harmonic of δ/δ_cmd at one amplitude",
     "the grid holds no −3.01 dB crossing (bandwidth_bound then gives > or < its edge)",
     {"json_key": "amplitudes.*.bandwidth_rad_s"}),
    ("sinedwell.limit_onset_amplitude_deg", "sinedwell", "deg",
     "smallest amplitude at which a limit acts", "deg", 1.0,
     "the smallest dwelled amplitude at which the current or voltage clamp acts",
     "no limit acts at any amplitude",
     {"requirement": False, "json_key": "limit_onset_amplitude_deg"}),
    # a profile move (simulate --profile, with the config's feed-forward)
    ("profile.tracking_error_max_deg", "profile", "deg",
     "largest tracking error during the move", "deg", 1.0,
     "the largest |δ_cmd − δ| from the move's start to its end"),
    ("profile.tracking_error_max_time_s", "profile", "s", "time of the largest tracking error",
     *_MS, "when the largest tracking error occurs, from the move's start", "",
     {"requirement": False}),
    ("profile.tracking_error_rms_deg", "profile", "deg", "RMS tracking error during the move",
     "deg", 1.0, "RMS of δ_cmd − δ from the move's start to its end"),
    ("profile.overshoot_pct", "profile", "percent", "overshoot past the target", "%", 1.0,
     "(peak − D)/D in %, as for a step"),
    ("profile.settling_time_s", "profile", "s", "settling after the move's end, ±2 %", *_MS,
     "arrival time (±2 %) minus the move's duration, 0 when already inside the band",
     "not settled by the end of the run"),
    ("profile.settling_time_5pct_s", "profile", "s", "settling after the move's end, ±5 %",
     *_MS, "arrival time (±5 %) minus the move's duration, 0 when already inside the band",
     "not settled by the end of the run"),
    ("profile.arrival_time_s", "profile", "s", "arrival from the move's start, ±2 %", *_MS,
     "from the move's start, the last time δ is outside ±2 % of D around D",
     "not settled by the end of the run"),
    ("profile.arrival_time_5pct_s", "profile", "s", "arrival from the move's start, ±5 %",
     *_MS, "from the move's start, the last time δ is outside ±5 % of D around D",
     "not settled by the end of the run"),
    ("profile.final_error_deg", "profile", "deg", "final error", "deg", 1.0,
     "δ_cmd − δ at the end of the run (signed)", "", {"requirement": False}),
    ("profile.max_current_a", "profile", "A", "largest current", "A", 1.0,
     "the largest |i| over the whole run"),
    ("profile.max_voltage_v", "profile", "V", "largest voltage", "V", 1.0,
     "the largest |V| over the whole run"),
    ("profile.current_limited", "profile", "", "current limit reached", "", 1.0,
     "whether the ±i_max clamp acted", "", {"requirement": False}),
    ("profile.voltage_limited", "profile", "", "voltage limit reached", "", 1.0,
     "whether the ±v_max clamp acted", "", {"requirement": False}),
    # the load and drivetrain of a loaded variant (docs/model.md §5; motor shaft unless named)
    ("drivetrain.compliant", "analyze", "", "compliant gear (two masses)", "", 1.0,
     "whether the gear has a torsional spring (gear.stiffness > 0)", "",
     {"requirement": False}),
    ("drivetrain.reflected_inertia_kg_m2", "analyze", "kg*m^2", "reflected inertia J_eff",
     "kg·m²", 1.0, "J + J_L/(η N²) (docs/model.md §5), of the rigid model", "",
     {"requirement": False}),
    ("drivetrain.reflected_damping_n_m_s_rad", "analyze", "N*m*s/rad",
     "reflected damping μ_eff", "N·m·s/rad", 1.0, "μv + b_L/(η N²), of the rigid model", "",
     {"requirement": False}),
    ("drivetrain.reflected_stiffness_n_m_rad", "analyze", "N*m/rad",
     "reflected load spring k_eff", "N·m/rad", 1.0, "K_h/(η N²), of the rigid model", "",
     {"requirement": False}),
    ("drivetrain.plant_stable", "analyze", "", "open-loop plant stable", "", 1.0,
     "whether the plant θ/i has no right-half-plane pole", "", {"requirement": False}),
    ("drivetrain.plant_unstable_pole_rad_s", "analyze", "rad/s",
     "unstable pole of the open-loop plant", "rad/s", 1.0,
     "the largest real part of a mechanical pole, where positive", "the plant is stable",
     {"requirement": False}),
    ("drivetrain.hinge_stiffness_n_m_rad", "analyze", "N*m/rad", "load spring K_h", "N·m/rad",
     1.0, "the config's load spring at the output", "", {"requirement": False}),
    # stiffness, effort and noise (docs/model.md §15), of the continuous loops
    ("stiffness.min_N_m_per_rad", "analyze", "N*m/rad", "minimum dynamic stiffness",
     "N·m/rad", 1.0, "min over frequency of 1/|δ/M_load(jω)|, every loop closed", _UNSTABLE_T,
     {"output": "angle", "twin": "stiffness.min_N_per_m"}),
    ("stiffness.min_N_per_m", "analyze", "N/m", "minimum dynamic stiffness", "N/m", 1.0,
     "min over frequency of 1/|x/F_load(jω)| at a linear output, every loop closed",
     _UNSTABLE_T, {"output": "length", "twin": "stiffness.min_N_m_per_rad"}),
    ("stiffness.min_at_rad_s", "analyze", "rad/s", "frequency of the minimum stiffness",
     "rad/s", 1.0, "where 1/|δ/M_load| is least", _UNSTABLE_T),
    ("effort.peak_A_per_rad", "analyze", "A/rad", "peak control effort", "A/rad", 1.0,
     "max over frequency of |i/δ_cmd(jω)| (no feed-forward)", _UNSTABLE_T,
     {"output": "angle", "twin": "effort.peak_A_per_m"}),
    ("effort.peak_A_per_m", "analyze", "A/m", "peak control effort", "A/m", 1.0,
     "max over frequency of |i/x_cmd(jω)| at a linear output (no feed-forward)", _UNSTABLE_T,
     {"output": "length", "twin": "effort.peak_A_per_rad"}),
    ("effort.peak_at_rad_s", "analyze", "rad/s", "frequency of the peak effort", "rad/s", 1.0,
     "where |i/δ_cmd| is largest", _UNSTABLE_T),
    ("stiffness.min_at_range_edge", "analyze", "", "minimum stiffness at the range edge", "",
     1.0, "whether the least 1/|δ/M_load| lies at an end of the analysed range", _UNSTABLE_T,
     {"requirement": False}),
    ("noise.counts_per_rev", "analyze", "", "encoder counts per revolution", "", 1.0,
     "the config's sensors.counts_per_rev", "no sensors.counts_per_rev",
     {"requirement": False}),
    ("noise.quantum_rad", "analyze", "rad", "encoder quantum q", "rad", 1.0,
     "2π/counts_per_rev, of the angle the position loop's encoder reads",
     "no sensors.counts_per_rev", {"requirement": False}),
    ("noise.band_rad_s", "analyze", "rad/s", "band of the white quantisation noise", "rad/s",
     1.0, "the noise is white over 0..band: the position loop's Nyquist frequency, or the top "
     "of the analysed range", "no sensors.counts_per_rev", {"requirement": False}),
    ("noise.current_rms_A", "analyze", "A", "RMS current of encoder noise", "A", 1.0,
     "RMS motor current from the encoder's quantisation noise (q²/12) through the loops",
     f"no sensors.counts_per_rev, or {_UNSTABLE_T}"),
    # the rate and torque envelope (docs/model.md §15; a linear output's in m/s, mm/s and N)
    *(("envelope.no_load_rate_" + unit.replace("/", "_"), "analyze", unit, "no-load rate",
       unit, 1.0, "output rate at the supply voltage with no load", "",
       {"requirement": False, "output": output})
      for unit, output in (("rad/s", "angle"), ("deg/s", "angle"), ("m/s", "length"),
                           ("mm/s", "length"))),
    ("envelope.stall_torque_N_m", "analyze", "N*m", "stall torque", "N·m", 1.0,
     "output torque at stall (the current limit through the gear efficiency)", "",
     {"requirement": False, "output": "angle"}),
    ("envelope.stall_force_N", "analyze", "N", "stall force", "N", 1.0,
     "output force at stall (the current limit through the gear efficiency)", "",
     {"requirement": False, "output": "length"}),
    ("envelope.stall_limited_by", "analyze", "", "stall limited by", "", 1.0,
     "the limit of the stall current: current (i_max) or voltage (the supply)", "",
     {"requirement": False}),
    ("envelope.rate_limited_by", "analyze", "", "no-load rate limited by", "", 1.0,
     "supply, or velocity command (a cascade's position_loop.omega_max)", "",
     {"requirement": False}),
    ("envelope.supply_voltage_v", "analyze", "V", "supply voltage", "V", 1.0,
     "supply.voltage (default current_loop.v_max)", "", {"requirement": False}),
    ("envelope.supply_resistance_ohm", "analyze", "ohm", "supply resistance", "Ω", 1.0,
     "supply.resistance (default 0)", "", {"requirement": False}),
    ("envelope.voltage_limit_v", "analyze", "V", "voltage limit", "V", 1.0,
     "the current controller's clamp v_max", "", {"requirement": False}),
    ("envelope.current_limit_a", "analyze", "A", "current limit", "A", 1.0,
     "the current command's clamp i_max", "", {"requirement": False}),
    ("envelope.basis", "analyze", "", "sine limits of", "", 1.0,
     "the loops the sine limits are computed of", "", {"requirement": False}),
    ("envelope.feedforward", "analyze", "", "sine limits with the feed-forward", "", 1.0,
     "whether the config's feed-forward acts in the sine limits", "",
     {"requirement": False}),
    # verdicts of the analysis (text)
    ("stable", "analyze", "", "stable", "", 1.0,
     "whether the closed loop is stable (poles of the Padé model)", "",
     {"requirement": False}),
    ("stability", "analyze", "", "stability (Padé model)", "", 1.0,
     "the closed loop's verdict from the poles of the Padé model", "",
     {"requirement": False}),
    ("current_loop.stability", "analyze", "", "stability (Padé model)", "", 1.0,
     "the current loop's own verdict from the poles of its Padé model", "",
     {"requirement": False, "loop": "current_loop"}),
    ("closed_loop.peak_at_range_edge", "analyze", "", "resonance peak at the range edge", "",
     1.0, "whether the largest |T| lies at an end of the analysed range", _UNSTABLE_T,
     {"requirement": False}),
)


def _table():
    figures = []
    for loop in LOOPS:
        for name, unit, label, shown, scale, meaning, absent in _LOOP_FIGURES:
            figures.append(Figure(f"{loop}.{name}", "analyze", unit, label, shown, scale,
                                  meaning, absent, loop, short=_LOOP_SHORT.get(name, "")))
        figures.append(Figure(
            f"{loop}.sensitivity_peak_at_range_edge", "analyze", "",
            "sensitivity peak at the range edge", "", 1.0,
            "whether the largest |S| lies at an end of the analysed range", _NOT_STABLE, loop,
            requirement=False))
    for row in _OTHER_FIGURES:
        keywords = row[-1] if isinstance(row[-1], dict) else {}
        positional = row[:len(row) - bool(keywords)]
        figure = Figure(*positional, **keywords)
        if figure.key in _OUTPUT_FIGURES:  # an output quantity, and its twin in mm
            twin = _OUTPUT_FIGURES[figure.key]
            figures += [
                dataclasses.replace(figure, output="angle", twin=twin),
                dataclasses.replace(figure, key=twin, unit="mm", shown_unit="mm", scale=1.0,
                                    json_key=_length_key(figure.json_key), output="length",
                                    twin=figure.key),
            ]
        else:
            figures.append(figure)
    return {figure.key: figure for figure in figures}


def _length_key(key):
    """The key of an output quantity at a linear output: ``_deg`` -> ``_mm``; the fit's
    residual (in the output's SI unit) -> ``rms_residual_mm``."""
    return key.replace("_deg", "_mm") if "_deg" in key else f"{key}_mm"


#: The figures that are quantities of the output (an angle at a rotary output), with the key
#: of their twin at a linear output (a length in mm, :mod:`cas_freq.core.output`).
_OUTPUT_FIGURES = {key: _length_key(key) for key in (
    "fit.rms_residual", "sinedwell.limit_onset_amplitude_deg", "profile.tracking_error_max_deg",
    "profile.tracking_error_rms_deg", "profile.final_error_deg")}


#: Every figure, by its dotted key.
FIGURES = _table()

#: The figures a requirement may bound: key -> the command whose JSON holds it.
METRICS = {key: figure.command for key, figure in FIGURES.items() if figure.requirement}

def accepted_metrics():
    """The figures a requirement may name, in a few lines' worth of words: each loop's figures
    once for every loop and view, then the others."""
    loops = [key for key in LOOPS if "." not in key]
    names = [name for name, *_ in _LOOP_FIGURES]
    others = sorted(key for key in METRICS if FIGURES[key].loop is None)
    return (f"LOOP.FIGURE or LOOP.loop_at_a_time.FIGURE with LOOP one of {', '.join(loops)} "
            f"and FIGURE one of {', '.join(names)}; or one of {', '.join(others)}")


#: Numbers the commands' JSON carries beside the figures that are test conditions, not figures
#: (the step's amplitude, the move): key as :attr:`Figure.json_key` would spell it.
CONDITIONS = {
    "step": ("step.amplitude_deg",),
    "sinedwell": ("amplitudes.*.amplitude_deg",),
    "profile": ("profile.distance_deg", "profile.peak_rate_deg_s", "profile.move_time_s"),
}


def json_values(figure, data):
    """The values of ``figure`` in its command's JSON ``data`` (a dict, as ``--json`` prints
    one variant): a list of one value, or one per list element where ``json_key`` has ``*``.

    Raises
    ------
    KeyError
        When the JSON has no such key (the table and the command disagree).
    """
    values = [data]
    for part in figure.json_key.split("."):
        if part == "*":
            values = [item for value in values for item in value]
        else:
            values = [value[part] for value in values]
    return values
