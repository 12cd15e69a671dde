"""The reference solvers' on-disk cache: one ``.npz`` per solved setup, named by the hash of the setup."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

R = TypeVar("R")


def cached(path: Path | None, fresh: bool, solve: Callable[[], R], load: Callable[[Any], R], arrays: Callable[[R], dict]) -> R:
    """The result stored at ``path``, or ``solve()``'s, then stored there.

    Parameters
    ----------
    path : Path or None
        The cache file (``.npz``); None: no cache, always solve.
    fresh : bool
        Solve and overwrite even if the file exists.
    solve : callable
        Computes the result.
    load : callable
        Builds the result from the loaded ``np.load`` archive.
    arrays : callable
        The named arrays to store for a result (``np.savez_compressed`` keywords).

    Returns
    -------
    The result.
    """
    if path is not None and path.exists() and not fresh:
        return load(np.load(path))
    res = solve()
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **arrays(res))
    return res
