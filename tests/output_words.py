"""What each shipped config's output is called, and the words that do not belong to it: shared
by tests/test_output_words.py and tests/test_output_wording.py (pytest puts this folder on
sys.path; the tests are not a package)."""

import re

#: What each shipped config's output is, read by hand from its file: (output_name or "output",
#: "position" where gear.screw_lead makes it linear else "angle", control_surface).
SHIPPED = {
    "qt_cas": ("fin", "angle", True),
    "dc_servo": ("output", "angle", False),
    "cascade_axis": ("output", "angle", False),
    "ball_screw": ("rod", "position", False),
}

#: "fin" as a word or a part of a name, not inside a longer word (``final``, ``define``).
FIN = re.compile(r"(?<![a-z])fin(?![a-z])", re.IGNORECASE)
#: "hinge" is allowed only as the config's key names (dotted, or in a YAML section).
HINGE_KEYS = re.compile(r"load\.hinge_(stiffness|bias)|^\s*hinge_(stiffness|bias):", re.MULTILINE)


def leaks(text, label, quantity, surface):
    """The words in ``text`` that do not belong to an output named ``label`` of kind
    ``quantity`` ("angle" or "position") that is (``surface``) or is not a control surface."""
    found = []
    if not surface:
        found += FIN.findall(text)
        found += re.findall(r"flight|\bdelta\b|deflection|aerodynamic", text, re.IGNORECASE)
        found += re.findall("hinge", HINGE_KEYS.sub("", text), re.IGNORECASE)
    if quantity == "position":  # a length is never the output's angle, nor δ
        found += re.findall(rf"\b(?:{label}|output) angle\b|δ", text)
    return found
