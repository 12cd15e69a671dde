"""Stability where methods fail: numerical maps, haptic-loop sweep, stabiliser, charts (``docs/stability.md``)."""
