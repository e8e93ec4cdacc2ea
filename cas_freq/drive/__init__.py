"""Drive parameter files: a config variant's gains in a servo drive's own objects and units.

- :mod:`cas_freq.drive.epos4`: maxon EPOS4, read and written as the INI-style (CiA 306 DCF)
  parameter file EPOS Studio exports (the object table, its sources and what could not be
  confirmed are in that module and in docs/epos4.md).
- :mod:`cas_freq.drive.variant_text`: a new variant inserted into a config file's text,
  keeping every comment and line of the rest.

This package sits beside the config layer: it imports :mod:`cas_freq.config`,
:mod:`cas_freq.core.parameters` and :mod:`cas_freq.core.units`, nothing above them.
"""

from cas_freq.drive.epos4 import (
    OBJECTS,
    DriveObject,
    DriveSetting,
    Epos4Export,
    export_text,
    import_values,
    read_export,
    settings_of,
    settings_table,
    variant_entries,
)
from cas_freq.drive.variant_text import insert_variant

__all__ = [
    "OBJECTS",
    "DriveObject",
    "DriveSetting",
    "Epos4Export",
    "export_text",
    "import_values",
    "insert_variant",
    "read_export",
    "settings_of",
    "settings_table",
    "variant_entries",
]
