"""Randomization configs: plain data, a YAML file, a preset name or a `Randomization`, validated on load.

    parameters:                   # physical parameters by long name (qube_suite.devices.qube.parameters)
      pendulum_mass: {distribution: uniform, low: 0.9, high: 1.1}     # x nominal (relative: the default)
      arm_damping: {distribution: loguniform, low: 0.5, high: 2.0}
      motor_resistance: {distribution: normal, mean: 1.0, std: 0.05, clip: [0.8, 1.2]}
      arm_friction: {distribution: uniform, low: 0.0, high: 1.0e-3, relative: false}   # N m
      cable_stiffness: 1.0e-3     # a number: this absolute value in every episode
    effects:                      # sensor and actuator effects by name (catalog.EFFECTS)
      quantization: true          # true: default settings; false or absent: off
      observation_noise: {std: [0.002, 0.002, 0.05, 0.05]}
      action_delay: {steps: {distribution: uniform, low: 0, high: 2}}   # drawn per episode

A misspelt name is a ValueError listing the valid names; so is any value or range
that could give an impossible value (a mass <= 0, a negative dead-zone, ...).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import os
import pathlib
import re
from collections.abc import Mapping
from typing import Any

from qube_suite import files
from qube_suite.devices.qube import parameters as params
from qube_suite.randomization.base import Field
from qube_suite.randomization.catalog import EFFECTS
from qube_suite.randomization.distributions import Distribution, finite_number, fixed, is_list
from qube_suite.randomization.presets import PRESETS

SECTIONS = ("parameters", "effects")
"""Top-level keys of a config."""


@dataclasses.dataclass(frozen=True)
class Randomization:
    """A validated randomization: what to draw at each episode's start.

    `parameters`: parameter name -> `Distribution`, in the order of the parameter
    table. `effects`: effect name -> its settings (field -> number, tuple of
    numbers, or `Distribution` drawn per episode), in the order of application.
    """

    parameters: dict[str, Distribution] = dataclasses.field(default_factory=dict)
    effects: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)

    @functools.cached_property
    def stochastic(self) -> bool:
        """Whether an effect draws random numbers at every step (noise, jitter)."""
        return any(EFFECTS[name].stochastic for name in self.effects)


def load(spec: Randomization | Mapping | str | os.PathLike) -> Randomization:
    """A validated `Randomization` from a preset name, a mapping, a YAML file's path, or itself.

    Raises ValueError for an unknown preset, name or key (listing the valid ones)
    and for impossible values or ranges; MissingFileError (a FileNotFoundError and a ValueError)
    for a missing file.
    """
    if isinstance(spec, Randomization):
        return spec
    if isinstance(spec, Mapping):
        return parse(spec)
    if isinstance(spec, str) and spec in PRESETS:
        return parse(PRESETS[spec])
    if isinstance(spec, (str, os.PathLike)):
        path = pathlib.Path(spec)
        if path.suffix in (".yaml", ".yml") or path.is_file():
            return parse(_read_yaml(path))
        raise ValueError(f"unknown randomization preset {str(spec)!r}; valid presets: {', '.join(PRESETS)} "
                         f"(or the path of a .yaml file)")
    raise ValueError(f"randomization must be a preset name ({', '.join(PRESETS)}), a mapping, the path of "
                     f"a YAML file or a Randomization, got {type(spec).__name__}")


def parse(data: Mapping | None) -> Randomization:
    """A validated `Randomization` from config data (None or empty: nothing randomized)."""
    data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ValueError(f"a randomization config must be a mapping with keys {', '.join(SECTIONS)}, "
                         f"got {type(data).__name__}")
    for key in data:
        if key not in SECTIONS:
            raise ValueError(f"unknown randomization key {key!r}; valid keys: {', '.join(SECTIONS)}")
    return Randomization(_parse_parameters(_section(data, "parameters")),
                         _parse_effects(_section(data, "effects")))


def _section(data: Mapping, key: str) -> Mapping:
    section = data.get(key) or {}
    if not isinstance(section, Mapping):
        raise ValueError(f"{key} must be a mapping of names to settings, got {section!r}")
    return section


def _parse_parameters(section: Mapping) -> dict[str, Distribution]:
    for name in section:
        if name not in params.PARAMETERS:
            raise ValueError(f"unknown parameter {name!r}; valid parameters: {', '.join(params.PARAMETERS)}")
    distributions = {}
    for name, parameter in params.PARAMETERS.items():
        if name not in section:
            continue
        spec, where = section[name], f"parameters.{name}"
        if isinstance(spec, Mapping):
            distribution = Distribution.parse(spec, where, relative_default=True)
        elif isinstance(spec, numbers.Real) and not isinstance(spec, bool):
            distribution = fixed(finite_number(spec, where))
        else:
            raise ValueError(f"{where} must be a number ({parameter.unit}) or a distribution mapping, "
                             f"got {spec!r}")
        if distribution.relative and parameter.nominal == 0.0:
            raise ValueError(f"{where}: the nominal value is 0, so relative draws would all be 0; "
                             f"give absolute values in {parameter.unit} (relative: false)")
        lower, _ = distribution.bounds(parameter.nominal)
        may_be_zero = params.may_be_zero(name)
        if lower < 0.0 or (lower == 0.0 and not may_be_zero):
            fix = "add clip bounds" if lower == -math.inf else "narrow the range or add clip bounds"
            raise ValueError(f"{where}: draws could reach {lower:g} {parameter.unit}, but {name} must be "
                             f"{'>= 0' if may_be_zero else '> 0'}; {fix}")
        distributions[name] = distribution
    return distributions


def _parse_effects(section: Mapping) -> dict[str, dict[str, Any]]:
    for name in section:
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; valid effects: {', '.join(EFFECTS)}")
    effects = {}
    for name, cls in EFFECTS.items():
        spec, where = section.get(name), f"effects.{name}"
        if spec is None or spec is False:
            continue
        if spec is True:
            spec = {}
        if not isinstance(spec, Mapping):
            raise ValueError(f"{where} must be true, false or a mapping with keys {', '.join(cls.fields)}, "
                             f"got {spec!r}")
        for key in spec:
            if key not in cls.fields:
                raise ValueError(f"{where}: unknown setting {key!r}; valid settings: {', '.join(cls.fields)}")
        settings = {}
        for key, field in cls.fields.items():
            if key in spec:
                settings[key] = _parse_setting(spec[key], field, f"{where}.{key}")
            elif field.default is not None:
                settings[key] = field.default
            elif not field.optional:
                raise ValueError(f"{where} needs {key!r}: the {field.description} ({field.unit})")
        effects[name] = cls.complete(settings)
    return effects


def _parse_setting(value, field: Field, where: str):
    if field.size:
        if not is_list(value, field.size):
            raise ValueError(f"{where} must be a list of {field.size} numbers ({field.unit}), got {value!r}")
        values = tuple(finite_number(v, where) for v in value)
        _check_range(field, min(values), max(values), where)
        return values
    if isinstance(value, Mapping):
        distribution = Distribution.parse(value, where, relative_default=None, integer=field.integer)
        _check_range(field, *distribution.bounds(), where)
        return distribution
    number = finite_number(value, where)
    if field.integer:
        if not isinstance(value, numbers.Integral):
            raise ValueError(f"{where} must be an integer ({field.unit}), got {value!r}")
        number = int(value)
    _check_range(field, number, number, where)
    return number


def _check_range(field: Field, lower: float, upper: float, where: str) -> None:
    if not field.allows(lower, upper):
        shown = f"{lower:g}" if lower == upper else f"values in [{lower:g}, {upper:g}]"
        raise ValueError(f"{where} must be {field.describe_range()} {field.unit}, got {shown}")


_YAML_FLOAT = re.compile(r"^[-+]?(?:\d[\d_]*\.?\d*|\.\d+)[eE][-+]?\d+$")
"""Exponent notation without a dot (1e-3), which YAML 1.1 would read as text."""


def _read_yaml(path: pathlib.Path):
    import yaml  # only needed for YAML files

    class Loader(yaml.SafeLoader):
        """Safe loading that reads 1e-3 as a number, as YAML 1.2 does."""

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", _YAML_FLOAT, list("-+0123456789."))
    return files.read_yaml(path, "randomization", Loader)
