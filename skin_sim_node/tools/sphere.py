"""The sphere punch (``tool.shape`` 'sphere'): a rigid ball of ``tool.radius_m`` (Hertz contact radius ``a = sqrt(R d)``,
load ``C (2/3) sqrt(d / R)`` of the flat punch's; :func:`skin_sim_node.model.layered_contact.contact_geometry`)."""

from __future__ import annotations

from .punch import Punch


class SpherePunch(Punch):
    """A spherical rigid tip: its contact grows with depth."""

    sphere = True
