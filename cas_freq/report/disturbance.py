"""The "Stiffness, effort and noise" part of a variant's report section ("What the
flight-control system sees" of a control surface): the dynamic stiffness, the control effort and
the encoder noise's current (docs/model.md §15) as a small table, with the stiffness figure."""

from cas_freq.config.wording import OutputWords
from cas_freq.core.numbers import number
from cas_freq.report.document import Heading, Paragraph, Table


def disturbance_blocks(data, figure=None):
    """The heading, the table and (when drawn) the stiffness figure of one variant."""
    a = data.analysis
    stiff, push, noise = a.stiffness, a.effort, a.noise
    if stiff is None:
        return []
    per, unit = ("m", "N/m") if stiff.linear else ("rad", "N·m/rad")
    words = OutputWords.of(data.loaded.params)
    blocks = [Heading(3, f"{words.seen.capitalize()} ({data.loaded.variant})")]
    if stiff.minimum is None:
        blocks.append(Paragraph(f"Not reported: {stiff.note}."))
        return blocks
    rows = (
        (f"minimum dynamic stiffness {words.compliance_symbol}", unit,
         number(stiff.minimum, 4)),
        ("  at", "rad/s", number(stiff.min_at_rad_s, 4)),
        (f"peak control effort {words.effort_symbol}", f"A/{per}", number(push.peak, 4)),
        ("  at", "rad/s", number(push.peak_at_rad_s, 4)),
        ("RMS current of encoder quantisation noise", "mA",
         "—" if noise.current_rms_A is None else number(noise.current_rms_A * 1e3, 4)),
    )
    notes = [note for note in dict.fromkeys((stiff.note, push.note, noise.note)) if note]
    blocks.append(Table(("figure", "unit", "value"), rows,
                        f"every loop closed, {data.loaded.variant}: " + "; ".join(notes)))
    if figure is not None:
        blocks.append(figure)
    return blocks
