"""Shared fixtures: temporary config files and the shipped config's raw data."""

import copy
from pathlib import Path

import pytest
import yaml

from cas_freq.config import default_config_path, read_config_file


@pytest.fixture(scope="session")
def shipped_config_path():
    """Path of the shipped ``configs/qt_cas.yaml``."""
    path = default_config_path()
    assert path.is_file(), path
    return path


@pytest.fixture(scope="session")
def _shipped_raw_once(shipped_config_path):
    return read_config_file(shipped_config_path)


@pytest.fixture
def shipped_raw(_shipped_raw_once):
    """The shipped config as plain YAML data (a fresh deep copy: tests may mutate it)."""
    return copy.deepcopy(_shipped_raw_once)


@pytest.fixture
def write_config(tmp_path):
    """``write_config(text_or_dict, name="config.yaml") -> Path``: a config file in tmp_path.

    A string is written as it is (for YAML syntax tests); a dict is dumped with ``yaml.safe_dump``
    (non-finite floats come out as ``.nan``/``.inf``, as a user would write them).
    """

    def write(content, name="config.yaml"):
        path = Path(tmp_path) / name
        if not isinstance(content, str):
            content = yaml.safe_dump(content, sort_keys=False)
        path.write_text(content, encoding="utf-8")
        return path

    return write
