"""The parameter record shared by the node and tissue schemas: name, type, default, unit, bounds.

Imports nothing from the implementation: the model and the node import this, never the reverse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


class ConfigError(ValueError):
    """A tissue configuration that the model cannot run on; the message says why."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: dotted name, Python type, default, unit, bounds, description."""

    name: str
    type: type
    default: Any
    unit: str
    description: str
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = True
    choices: tuple[str, ...] = ()
    read_only: bool = False

    def check(self, value: Any) -> Any:
        """Return ``value`` coerced to this spec's type, or raise :class:`ConfigError`."""
        if self.type is str:
            if not isinstance(value, str):
                raise ConfigError(f"{self.name}: expected a string, got {value!r}")
            if self.choices and value not in self.choices:
                raise ConfigError(f"{self.name} = {value!r}: must be one of {', '.join(self.choices)}")
            return value
        if self.type is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{self.name}: expected true/false, got {value!r}")
            return bool(value)
        if self.type is int:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                if isinstance(value, float) and value.is_integer():
                    value = int(value)
                else:
                    raise ConfigError(f"{self.name}: expected an integer, got {value!r}")
            value = int(value)
        elif self.type is float:
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ConfigError(f"{self.name}: expected a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError(f"{self.name}: must be finite, got {value!r}")
        if self.min is not None:
            bad = value <= self.min if self.min_exclusive else value < self.min
            if bad:
                op = ">" if self.min_exclusive else ">="
                raise ConfigError(f"{self.name} = {value!r} {self.unit}: must be {op} {self.min}")
        if self.max is not None and value > self.max:
            raise ConfigError(f"{self.name} = {value!r} {self.unit}: must be <= {self.max}")
        return value
