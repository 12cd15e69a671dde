"""The reference solvers' on-disk cache: one ``.npz`` per solved setup, named by the hash of the setup."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

R = TypeVar("R")

DOCS = Path(__file__).resolve().parents[2] / "docs"
"""The tracked docs folder: its caches (``docs/validation/*_cache``) are read, and written only with :data:`WRITE_DOCS`."""
LOCAL_CACHE = Path("out") / "cache"
"""Where a solve that is not in a tracked cache is stored (untracked, like every command's output under ``out/``)."""
WRITE_DOCS = False
"""Store new solves in the tracked caches: set by ``skin-sim chart validation --docs`` (its ``--out`` under ``docs/``)."""


def local_path(path: Path) -> Path:
    """The untracked copy of a cache file under ``docs/`` (:data:`LOCAL_CACHE`, same cache folder name); others as given."""
    return LOCAL_CACHE / path.parent.name / path.name if path.resolve().is_relative_to(DOCS) else path


def cached(path: Path | None, fresh: bool, solve: Callable[[], R], load: Callable[[Any], R], arrays: Callable[[R], dict]) -> R:
    """The result stored at ``path``, or ``solve()``'s, then stored there.

    Parameters
    ----------
    path : Path or None
        The cache file (``.npz``); None: no cache, always solve. A file under ``docs/`` is also looked for in
        :data:`LOCAL_CACHE`, and a new solve goes there unless :data:`WRITE_DOCS`.
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
    if path is not None and not fresh:
        for p in (path, local_path(path)):
            if p.exists():
                return load(np.load(p))
    res = solve()
    if path is not None:
        dest = path if WRITE_DOCS else local_path(path)  # the tracked cache only with --docs
        dest.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(dest, **arrays(res))
    return res
