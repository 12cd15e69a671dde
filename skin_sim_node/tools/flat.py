"""The flat punch (``tool.shape`` 'flat'): a rigid cylinder of ``tool.radius_m`` pressed end-on (the paper's tool)."""

from __future__ import annotations

from .punch import Punch


class FlatPunch(Punch):
    """A flat-ended rigid punch: contact radius ``tool.radius_m`` from first contact (eq 6's ``A_0``)."""

    sphere = False
