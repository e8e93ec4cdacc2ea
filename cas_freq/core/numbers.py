"""Numbers as cas_freq writes them: at a stated precision, never the last bits of a float.

Floating-point results differ in their last bits between CPUs (numpy's SIMD exp/log, the
order of sums, BLAS), so everything ``cas-freq report`` and ``cas-freq compare`` write is
rounded at output, with the one rule set of this module:

* text (report.md, the tables of index.html, the CLI's tables): :data:`TEXT_DIGITS` (4)
  significant digits, 5 in the verdict table and the comparison's every-figure table
  (:func:`number`);
* results.json: every float to :data:`JSON_DIGITS` (6) significant digits
  (:func:`rounded_json`);
* figures: plotted data to 6 significant digits (:func:`round_array`), SVG coordinates to
  0.01 pt (:func:`cas_freq.plots.report.svg_text`).

**Zero.** Every figure is written in a unit where :data:`ZERO` = 1e-9 is far below anything
meaningful (s, ms, rad/s, deg, dB, %, A, V, or dimensionless), so a magnitude below it is
written as 0: a fitted delay of 7e-52 s, |T(0)| of 2e-15 dB. A **difference** of two figures is
computed from the two as results.json writes them (6 significant digits), and is 0 below 1e-9
of the larger figure; in a table it is 0 when below the precision the figures are shown with,
so two figures that print the same never differ by the noise of their last bits.

**Absent.** None, NaN and ±inf are "—" in text and null in JSON.

Rounding uses Python's correctly rounded float formatting (``format(x, ".6g")``), which gives
the same digits on every platform for the same float. Two machines can still disagree in the
last written digit when a value lies on a rounding boundary; :func:`json_differences` compares
two results.json files within the written precision (what ``.ci/run`` checks).
"""

import math
import re

import numpy as np

#: Magnitude below which a figure is written as 0 (in the unit it is written in).
ZERO = 1e-9

#: Significant digits of the floats in results.json.
JSON_DIGITS = 6

#: Significant digits of the figures in text tables.
TEXT_DIGITS = 4

#: Relative tolerance of :func:`json_differences` (the written precision, with room for a
#: last digit rounded the other way).
JSON_RELATIVE_TOLERANCE = 1e-4


def _is_real(value):
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def round_significant(value, digits=JSON_DIGITS):
    """``value`` rounded to ``digits`` significant digits, as a float.

    None for None, NaN and ±inf; 0.0 when ``|value| <`` :data:`ZERO` (never -0.0). Integers
    are returned unchanged.
    """
    if value is None:
        return None
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return int(value)
    value = float(value)
    if not math.isfinite(value):
        return None
    if abs(value) < ZERO:
        return 0.0
    return float(format(value, f".{digits}g")) + 0.0


def round_array(values, digits=JSON_DIGITS):
    r"""A float array with every element rounded like :func:`round_significant`; NaN and ±inf
    are kept (matplotlib draws NaN as a gap).

    The same floats as ``format(v, ".6g")`` element by element, about 20 times faster on the
    arrays a figure plots: with :math:`k = d - 1 - \lfloor\log_{10}|v|\rfloor`, the
    significand :math:`M = \mathrm{round}(v \cdot 10^k)` and :math:`M / 10^k` (or
    :math:`M \cdot 10^{-k}`) are what formatting gives wherever :math:`10^{|k|}` is exact
    (:math:`|k| \le 22`, one correctly rounded division or product), :math:`v \cdot 10^k` is
    no closer than 1e-6 to a rounding tie (its error is below 1e-9 there), and M has ``d``
    digits (:math:`\log_{10}` may be a bit off at powers of ten). The other elements go
    through :func:`round_significant` one by one.
    """
    values = np.asarray(values, dtype=float)
    out = np.array(values, dtype=float, copy=True)
    size = np.abs(values)
    finite = np.isfinite(values)
    out[finite & (size < ZERO)] = 0.0
    work = finite & (size >= ZERO)
    if not work.any():
        return out
    v = values[work]
    k = (digits - 1) - np.floor(np.log10(np.abs(v))).astype(np.int64)
    fast = np.abs(k) <= 22
    power = 10.0 ** np.abs(np.where(fast, k, 0))  # exact for |k| <= 22
    scaled = np.where(k >= 0, v * power, v / power)
    significand = np.round(scaled)
    magnitude = np.abs(significand)
    fast &= np.abs(np.abs(scaled - np.trunc(scaled)) - 0.5) > 1e-6
    fast &= (magnitude >= 10.0 ** (digits - 1)) & (magnitude <= 10.0 ** digits)
    rounded = np.where(k >= 0, significand / power, significand * power) + 0.0
    slow = np.flatnonzero(~fast)
    rounded[slow] = [round_significant(x, digits) for x in v[slow].tolist()]
    out[work] = rounded
    return out


def number(value, digits=TEXT_DIGITS, unit=""):
    """A figure as text: ``digits`` significant digits, "0" when numerically zero, "—" when
    absent; booleans as yes/no and strings as they are."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, str):
        return value
    if value is None:
        return "—"
    if isinstance(value, (int, np.integer)):
        text = str(int(value))
    else:
        rounded = round_significant(value, digits)
        if rounded is None:
            return "—"
        text = format(rounded, f".{digits}g")
    return f"{text} {unit}" if unit else text


def difference_value(value, baseline, digits=JSON_DIGITS):
    """``value - baseline`` computed from both rounded to ``digits`` significant digits, itself
    rounded to ``digits``; 0.0 below 1e-9 of the larger figure; None when either is absent or
    not a number."""
    if not (_is_real(value) and _is_real(baseline)):
        return None
    a, b = round_significant(value, digits), round_significant(baseline, digits)
    if a is None or b is None:
        return None
    delta = a - b
    if abs(delta) <= ZERO * max(abs(a), abs(b)):
        return 0.0
    return round_significant(delta, digits)


def _last_unit(magnitude, digits):
    """Value of one unit in the last of ``digits`` significant digits of ``magnitude``."""
    if magnitude == 0:
        return 0.0
    exponent = int(format(magnitude, f".{digits - 1}e").split("e")[1])
    return 10.0 ** (exponent - digits + 1)


def difference(value, baseline, digits=TEXT_DIGITS, shown_digits=5):
    """``value - baseline`` as signed text with the relative change.

    Computed from both figures as results.json writes them (:data:`JSON_DIGITS` significant
    digits, :func:`difference_value`), written with ``digits`` significant digits, and "0"
    when smaller than half a unit in the last digit of the figures as the table shows them
    (``shown_digits``): two figures that print the same never differ by the noise of their
    last bits. Booleans and strings give "same" / "differs"; "—" when one is absent.
    """
    if value is None or baseline is None:
        return "—"
    if not (_is_real(value) and _is_real(baseline)):
        return "same" if value == baseline else "differs"
    delta = difference_value(value, baseline, JSON_DIGITS)
    if delta is None:
        return "—"
    a, b = round_significant(value, JSON_DIGITS), round_significant(baseline, JSON_DIGITS)
    if abs(delta) < 0.5 * _last_unit(max(abs(a), abs(b)), shown_digits) or delta == 0:
        return "0"
    text = f"{round_significant(delta, digits):+.{digits}g}"
    if b:
        text += f" ({round_significant(100.0 * delta / abs(b), 3):+.3g} %)"
    return text


def rounded_json(value, digits=JSON_DIGITS):
    """Plain JSON data of nested dicts/lists/tuples with every float rounded by
    :func:`round_significant` (non-finite floats become None, numpy scalars plain)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return round_significant(value, digits)
    if isinstance(value, dict):
        return {key: rounded_json(item, digits) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded_json(item, digits) for item in value]
    return value


# ---- comparing written results ---------------------------------------------------------------

_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _close(a, b, rel, scale=0.0):
    return math.isclose(a, b, rel_tol=rel, abs_tol=max(10 * ZERO, rel * abs(scale)))


def _last_digit(token):
    """Value of one unit in the last written digit of a number token."""
    mantissa, _, exponent = token.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (int(exponent or 0) - decimals)


def _strings_close(a, b):
    """Equal text, and the numbers in it equal within one unit of their last written digit."""
    if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
        return False
    for x, y in zip(_NUMBER.findall(a), _NUMBER.findall(b), strict=True):
        tolerance = max(_last_digit(x), _last_digit(y)) * 1.0001
        if abs(float(x) - float(y)) > tolerance:
            return False
    return True


def json_differences(expected, actual, rel=JSON_RELATIVE_TOLERANCE, path="$"):
    """Where two results.json documents differ beyond the written precision.

    Numbers must agree within ``rel`` (relative, with 1e-8 absolute for figures at zero); a
    comparison's ``differences`` list (a figure minus the baseline) within ``rel`` of the
    figures themselves; numbers inside text within one unit of their last digit; everything
    else (keys, lengths, text, booleans, null) exactly.

    Returns
    -------
    list of str
        One line per difference (``path: expected ... got ...``); empty when they agree.
    """
    out = []
    if isinstance(expected, dict) and isinstance(actual, dict):
        if list(expected) != list(actual):
            return [f"{path}: keys {sorted(expected)} != {sorted(actual)}"]
        scale = 0.0
        if "differences" in expected and isinstance(expected.get("values"), list):
            scale = max([abs(v) for v in expected["values"] + (actual.get("values") or [])
                         if _is_real(v)], default=0.0)
        for key in expected:
            if key == "differences" and isinstance(expected[key], list) and isinstance(
                    actual[key], list) and len(expected[key]) == len(actual[key]):
                for k, (x, y) in enumerate(zip(expected[key], actual[key], strict=True)):
                    if _is_real(x) and _is_real(y):
                        if not _close(x, y, rel, scale):
                            out.append(f"{path}.{key}[{k}]: expected {x!r}, got {y!r}")
                    else:
                        out += json_differences(x, y, rel, f"{path}.{key}[{k}]")
            else:
                out += json_differences(expected[key], actual[key], rel, f"{path}.{key}")
        return out
    if isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            return [f"{path}: {len(expected)} items expected, got {len(actual)}"]
        for k, (x, y) in enumerate(zip(expected, actual, strict=True)):
            out += json_differences(x, y, rel, f"{path}[{k}]")
        return out
    if _is_real(expected) and _is_real(actual):
        return [] if _close(expected, actual, rel) else [
            f"{path}: expected {expected!r}, got {actual!r}"]
    if isinstance(expected, str) and isinstance(actual, str):
        return [] if _strings_close(expected, actual) else [
            f"{path}: expected {expected!r}, got {actual!r}"]
    if expected == actual and type(expected) is type(actual):
        return []
    return [f"{path}: expected {expected!r}, got {actual!r}"]
