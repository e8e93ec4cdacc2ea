"""The disk cache of pint's conversion factors (cas_freq.core.unit_cache): a hit returns exactly
what pint returns, only factors are stored, a bad or unwritable file is harmless, and a start
whose units are all cached does not import pint."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from cas_freq.core import unit_cache
from cas_freq.core.units import registry, to_si


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    """An empty cache folder of this test (and a fresh in-memory table before and after)."""
    monkeypatch.setenv(unit_cache.CACHE_ENV, str(tmp_path))
    unit_cache._table.cache_clear()
    yield tmp_path
    unit_cache._table.cache_clear()


def _pint(value, unit):
    """The conversion by pint alone, as to_si did before the cache."""
    number, text = value.split(" ", 1)
    quantity = registry().Quantity(float(number), registry().parse_units(text))
    return float(quantity.to(registry().Unit(unit)).magnitude)


#: Unit strings of the shipped configs and the docs pages (docs/config.md, docs/cli.md), with
#: the SI unit each is read in.
CASES = [("0.071 mH", "H"), ("16300 rpm", "rad/s"), ("5.54e-7 kg*m^2", "kg*m^2"),
         ("0.4 ms", "s"), ("25 kHz", "Hz"), ("2835.3 V/(A*s)", "V/(A*s)"), ("10 deg", "rad"),
         ("1e5 deg/s^2", "rad/s^2"), ("5.54 g*cm^2", "kg*m^2"), ("2 mN*m", "N*m"),
         ("0.0105 V*s/rad", "V*s/rad"), ("3 arcmin", "rad")]


@pytest.mark.parametrize(("text", "unit"), CASES)
def test_a_hit_equals_pint_to_the_bit(cache_dir, text, unit):
    # The first conversion goes to pint and stores the factor; a fresh table then reads it
    # from the file. Any magnitude must come out as pint converts it, bit for bit.
    first = to_si(text, unit)
    assert first == _pint(text, unit)
    unit_cache._table.cache_clear()
    name = text.split(" ", 1)[1]
    assert unit_cache.cached_factor(name, unit) is not None
    for magnitude in np.random.default_rng(3).uniform(-1e6, 1e6, 50).tolist() + [0.0, 1.0]:
        shown = f"{magnitude!r} {name}"
        assert to_si(shown, unit) == _pint(shown, unit), shown


def test_offset_units_are_converted_by_pint_and_never_stored(cache_dir):
    assert to_si("20 degC", "K") == pytest.approx(293.15, abs=1e-12)
    assert unit_cache.cached_factor("degC", "K") is None
    assert to_si("0 degC", "K") == pytest.approx(273.15, abs=1e-12)


def test_failures_are_not_stored_and_still_name_the_dimension(cache_dir):
    for _ in range(2):
        with pytest.raises(ValueError, match="dimension"):
            to_si("3 ms", "ohm")
    assert unit_cache.cached_factor("ms", "ohm") is None


def test_the_file_holds_what_pint_gave(cache_dir):
    to_si("0.4 ms", "s")
    (path,) = cache_dir.iterdir()
    assert path.name.startswith(f"unit-factors-{unit_cache.FORMAT}-pint-")
    assert ["ms", "s", 0.001] in json.loads(path.read_text())


@pytest.mark.parametrize("content", ["{not json", "[[1, 2, 3]]", '[["ms", "s", "0.001"]]',
                                     '[["ms", "s", NaN]]', "{}"])
def test_a_malformed_file_is_ignored_and_rewritten(cache_dir, content):
    path = cache_dir / os.path.basename(unit_cache.cache_file())
    path.write_text(content)
    assert to_si("0.4 ms", "s") == _pint("0.4 ms", "s")
    unit_cache._table.cache_clear()
    assert unit_cache.cached_factor("ms", "s") == _pint("1 ms", "s")


def test_an_unwritable_folder_keeps_the_cache_in_memory(tmp_path, monkeypatch):
    monkeypatch.setenv(unit_cache.CACHE_ENV, str(tmp_path / "a-file"))
    (tmp_path / "a-file").write_text("")  # the cache 'folder' is a file: nothing can be written
    unit_cache._table.cache_clear()
    try:
        assert to_si("0.4 ms", "s") == _pint("0.4 ms", "s")
        assert unit_cache.cached_factor("ms", "s") == _pint("1 ms", "s")
    finally:
        unit_cache._table.cache_clear()


def test_off_keeps_nothing_on_disk(tmp_path, monkeypatch):
    monkeypatch.setenv(unit_cache.CACHE_ENV, "off")
    unit_cache._table.cache_clear()
    try:
        assert unit_cache.cache_file() is None
        assert to_si("0.4 ms", "s") == _pint("0.4 ms", "s")
    finally:
        unit_cache._table.cache_clear()


def test_a_start_with_every_unit_cached_does_not_import_pint(tmp_path):
    # Two fresh processes load the shipped config: the first fills the cache (and imports
    # pint), the second finds every factor there and never imports it.
    code = ("import sys; from cas_freq.config import load_variant; load_variant(); "
            "print('pint' in sys.modules)")
    env = {**os.environ, unit_cache.CACHE_ENV: str(tmp_path)}
    imported = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                               text=True, check=True).stdout.strip() for _ in range(2)]
    assert imported == ["True", "False"]
