"""The closing line of a command that checks something: what passed, what failed, and the exit code.

``demo``, ``replay --live``, ``soak`` and ``scale`` each collect ``(passed, description)`` checks and end
with :func:`verdict_line`; the exit code is :func:`exit_code`: 1 when any check failed.
"""

from __future__ import annotations

Check = tuple[bool, str]


def verdict_line(name: str, checks: list[Check]) -> str:
    """``NAME PASS: a; b`` or ``NAME FAIL: c; d; passed: a; b``.

    Parameters
    ----------
    name : str
        The command, e.g. ``"demo"``.
    checks : list of (bool, str)
        Each check's result and what it checked (for a failure: also what was measured).

    Returns
    -------
    str
        One line; ``NAME FAIL: nothing was checked`` when ``checks`` is empty.
    """
    if not checks:
        return f"{name} FAIL: nothing was checked"
    failed = [what for ok, what in checks if not ok]
    passed = [what for ok, what in checks if ok]
    if not failed:
        return f"{name} PASS: " + "; ".join(passed)
    return f"{name} FAIL: " + "; ".join(failed) + ("; passed: " + "; ".join(passed) if passed else "")


def exit_code(checks: list[Check]) -> int:
    """0 when every check passed (and there was one), else 1."""
    return 0 if checks and all(ok for ok, _ in checks) else 1
