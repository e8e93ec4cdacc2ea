"""Config layer: read YAML, convert units to SI, validate. Imports nothing above it."""

from cas_freq.config.loader import (
    LoadedVariant,
    default_config_path,
    load_all_variants,
    load_variant,
    parse_set_option,
    read_config_file,
    variant_names,
)
from cas_freq.config.schema import BASE_VARIANT, ActuatorConfig

__all__ = [
    "BASE_VARIANT",
    "ActuatorConfig",
    "LoadedVariant",
    "default_config_path",
    "load_all_variants",
    "load_variant",
    "parse_set_option",
    "read_config_file",
    "variant_names",
]
