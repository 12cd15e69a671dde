"""The parameter record shared by the node and tissue schemas: name, type, default, unit, bounds.

Imports nothing from the implementation: the model and the node import this, never the reverse.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from dataclasses import KW_ONLY, dataclass
from typing import Any, Generic, TypeVar, cast

import numpy as np

T = TypeVar("T", bool, int, float, str)


class ConfigError(ValueError):
    """A parameter value or a tissue configuration that cannot be used; the message says why."""


def read_yaml(path) -> Any:
    """The YAML document of a parameter file, parsed once.

    Raises
    ------
    ConfigError
        The file is not YAML: one line naming the file, the line and column, and what the parser expected (rcl's own
        parser would print a C log line and raise).
    """
    import yaml

    try:
        with open(path) as fh:
            return yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" (line {where.line + 1}, column {where.column + 1})" if where is not None else ""
        raise ConfigError(f"{path}: not a YAML parameter file{at}: {getattr(exc, 'problem', None) or exc}") from None


SUGGEST_CUTOFF = 0.6
"""difflib similarity from which a valid name is offered as the one meant (difflib's own default: ``max_forse_n``
finds ``max_force_n`` and ``tissue.layers.dermis.stifness_n_per_m`` its layer's ``stiffness_n_per_m``, while an
unrelated word gets no guess)."""


def unknown_name(name: str, valid: Iterable[str]) -> str:
    """The reason an unknown parameter name is refused: the name and the closest valid one.

    Parameters
    ----------
    name : str
        The name as given (dotted for nested keys).
    valid : iterable of str
        Every name the reader accepts.

    Returns
    -------
    str
        E.g. ``unknown parameter 'max_forse_n' (did you mean 'max_force_n'?)``; with no close name, where the
        valid names are listed.
    """
    close = difflib.get_close_matches(name, list(valid), n=1, cutoff=SUGGEST_CUTOFF)
    hint = f"did you mean {close[0]!r}?" if close else "docs/parameters.md lists the valid names"
    return f"unknown parameter {name!r} ({hint})"


def check_names(names: Iterable[str], valid: Iterable[str]) -> None:
    """Refuse any name not in ``valid``, each with the closest valid name, in one line.

    Parameters
    ----------
    names : iterable of str
    valid : iterable of str

    Raises
    ------
    ConfigError
        At least one unknown name (all are named, sorted).
    """
    valid = set(valid)
    unknown = sorted(set(names) - valid)
    if unknown:
        raise ConfigError("; ".join(unknown_name(n, valid) for n in unknown))


@dataclass(frozen=True)
class ParamSpec(Generic[T]):
    """One parameter: dotted name, Python type, default, unit, description; bounds and flags by keyword.

    Parameters
    ----------
    name : str
        Dotted name (``tissue.`` prefix for tissue parameters as the node declares them).
    type : type
        ``float``, ``int``, ``bool`` or ``str``: :meth:`check` returns a value of this type.
    default : T
    unit : str
        SI unit (``"1"``: a count or ratio, ``"-"``: none).
    description : str
        The reason for the default and what the parameter does.
    min, max : float, optional
        Bounds (None: unbounded).
    min_exclusive : bool
        ``min`` itself is out of bounds (default True: ``value > min``; False: ``value >= min``).
    choices : tuple of str
        The allowed values of a string parameter (empty: any).
    read_only : bool
        Read at start only: a live set is refused.
    """

    name: str
    type: type[T]
    default: T
    unit: str
    description: str
    _: KW_ONLY
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = True
    choices: tuple[str, ...] = ()
    read_only: bool = False

    def check(self, value: Any, label: str | None = None) -> T:
        """``value`` coerced to this spec's type and bound-checked.

        Parameters
        ----------
        value : Any
        label : str, optional
            The name the error message gives (default: :attr:`name`).

        Returns
        -------
        T

        Raises
        ------
        ConfigError
            A value of the wrong type, non-finite, out of bounds, or not one of the choices.
        """
        name = self.name if label is None else label
        if self.type is str:
            if not isinstance(value, str):
                raise ConfigError(f"{name}: expected a string, got {value!r}")
            if self.choices and value not in self.choices:
                raise ConfigError(f"{name} = {value!r}: must be one of {', '.join(self.choices)}")
            # T is str here; mypy checks the branch under each of T's constraints, and the narrowed str fits only one
            return cast(Any, value)
        if self.type is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{name}: expected true/false, got {value!r}")
            return bool(value)
        if self.type is int:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                if isinstance(value, float) and value.is_integer():
                    value = int(value)
                else:
                    raise ConfigError(f"{name}: expected an integer, got {value!r}")
            value = int(value)
        elif self.type is float:
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ConfigError(f"{name}: expected a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError(f"{name}: must be finite, got {value!r}")
        unit = "" if self.unit in ("1", "-", "") else f" {self.unit}"  # a count or a unitless value: no unit
        if self.min is not None:
            bad = value <= self.min if self.min_exclusive else value < self.min
            if bad:
                op = ">" if self.min_exclusive else ">="
                raise ConfigError(f"{name} = {value!r}{unit}: must be {op} {self.min}")
        if self.max is not None and value > self.max:
            raise ConfigError(f"{name} = {value!r}{unit}: must be <= {self.max}")
        return value
