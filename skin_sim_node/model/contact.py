"""The local linearisation of the contact that the model hands to the session (issue 12).

The device side renders ``F(x, v) = f0 + K (x - x0) + D (v - v0)`` between server updates
(Mark et al. 1996, "Adding force feedback to graphics systems": plane-and-probe local model;
sawSensablePhantom ``servo_ci``). The model gives ``f0`` and the Jacobians; the session adds the
pose it answers, the time-to-live, the validity radius and a sequence number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from msgs_schema.contact_model import NeedleLaw

Z_UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Indenter:
    """The rigid tip the tissue's kernel is pressed by: the contact geometry of the layered form's eq 6 and of the modal
    load (a uniform pressure on the contact disk, :func:`~.modal.disk_load_coefficients`).

    The tool (:mod:`skin_sim_node.tools`) gives it to :class:`~.skin_model.SkinModel`; the tissue does not know which
    tool pressed it.

    Attributes
    ----------
    radius_m : float
        Radius of the flat tip, or of the sphere (m).
    sphere : bool
        A spherical tip (Hertz contact radius ``a = sqrt(R d)``); else a flat punch.
    """

    radius_m: float
    sphere: bool = False

    @classmethod
    def of(cls, cfg) -> Indenter:
        """The punch of a tissue configuration (``tool.radius_m``; spherical for ``tool.shape`` 'sphere')."""
        return cls(cfg.tool_radius_m, cfg.tool_shape == "sphere")


_ZZ = np.outer(Z_UP, Z_UP)


@dataclass(frozen=True)
class ContactTangent:
    """The tissue's reaction force and its derivatives at the current tool state (tissue frame, SI).

    Attributes
    ----------
    force_n : ndarray, shape (3,)
        Reaction force on the tool ``f0`` (N).
    stiffness_n_per_m : ndarray, shape (3, 3)
        ``K = dF/dx`` (N/m), row-major: ``F(x) ~ f0 + K (x - x0)``. A press (tool moving
        along ``-normal``) raises the force along ``+normal``, so ``normal . K . normal <= 0``.
    damping_n_s_per_m : ndarray, shape (3, 3)
        ``D = dF/dv`` (N s/m), the same sign convention.
    normal : ndarray, shape (3,)
        Unit contact normal, out of the tissue (``+z`` on an undeformed flat sheet).
    contact_radius_m : float
        Radius of the contact patch (m); 0 out of contact.
    friction_coefficient : float
        ``mu`` of the presliding friction the force follows (issue 30, :mod:`.friction`); 0: the force has no
        friction term (the paper form, the needle, a tangent built without the law).
    tangential_stiffness_n_per_m : float
        The friction's presliding stiffness ``k_t`` (N/m): the skin stretches with the tool at it until
        ``k_t |s| = mu F_n``; 0 with no friction.
    friction_anchor_m : ndarray, shape (3,) or None
        The friction's anchor ``z`` (adhesion point) after the tick (m, tissue frame); None with no friction.
    needle : NeedleLaw or None
        The needle's axial law (``tool.shape`` 'needle', issue 22): rupture ahead, post-rupture line, Dahl friction;
        None for the other tools.
    coupling_rate_n_per_s : ndarray, shape (3,), or None
        Two hands (issue 32): the rate at which the other tools' motion moves this force (N/s), ``K[:, 2] dw/dt`` with
        ``w`` the other fields' deflection under this tool (:class:`skin_sim_node.tools.hands.CoupledTool`); None:
        one tool.
    """

    force_n: np.ndarray
    stiffness_n_per_m: np.ndarray
    damping_n_s_per_m: np.ndarray
    normal: np.ndarray
    contact_radius_m: float
    friction_coefficient: float = 0.0
    tangential_stiffness_n_per_m: float = 0.0
    friction_anchor_m: np.ndarray | None = None
    needle: NeedleLaw | None = None
    coupling_rate_n_per_s: np.ndarray | None = None

    def published(self, force_n: np.ndarray, scale: float, friction: bool = True) -> ContactTangent:
        """This tangent as the session publishes it: ``f0 = force_n`` (the published force, this one's scaled by
        ``scale``), ``K``, ``D`` and the tool's law scaled alike, and the presliding friction the force follows.

        Parameters
        ----------
        force_n : ndarray, shape (3,)
            The published force (N); copied.
        scale : float
            Published over the tool's force magnitude (> 0).
        friction : bool
            The tool's force follows the tissue's friction (:attr:`skin_sim_node.tools.base.ToolNeeds.friction`): its
            anchor, and its stiffness scaled as the force was (the slip distance ``mu F_n / k_t`` is the model's);
            False: no friction law in the contact model (the needle's law is its own).

        Returns
        -------
        ContactTangent
        """
        return ContactTangent(
            force_n=force_n.copy(),
            stiffness_n_per_m=self.stiffness_n_per_m * scale,
            damping_n_s_per_m=self.damping_n_s_per_m * scale,
            normal=self.normal,
            contact_radius_m=self.contact_radius_m,
            friction_coefficient=self.friction_coefficient if friction else 0.0,
            tangential_stiffness_n_per_m=self.tangential_stiffness_n_per_m * scale if friction else 0.0,
            friction_anchor_m=self.friction_anchor_m if friction else None,
            needle=None if self.needle is None else self.needle.scaled(scale),
            coupling_rate_n_per_s=None if self.coupling_rate_n_per_s is None else self.coupling_rate_n_per_s * scale,
        )

    @property
    def in_contact(self) -> bool:
        """True if the tool touches the tissue (a contact radius > 0)."""
        return self.contact_radius_m > 0.0

    @property
    def normal_force_n(self) -> float:
        """``F_n = n . f0`` (N): the normal part of the force (the friction term is tangential)."""
        return float(self.normal @ self.force_n)

    @property
    def normal_force_gradient_n_per_m(self) -> np.ndarray:
        """``grad F_n = K^T n`` (N/m), the normal force's gradient in the tool position.

        Exact for both forms: the layered form's ``K = n grad(F_n)^T + dF_t/dx`` whose friction part has no component
        along ``n`` (:func:`~.friction.presliding_tangent`), the paper form's ``K = -k z z^T`` with ``n = z``.
        """
        return self.stiffness_n_per_m.T @ self.normal


def normal_tangent(force_z_n: float, k_normal_n_per_m: float, b_normal_n_s_per_m: float, radius_m: float) -> ContactTangent:
    """A tangent with force and stiffness along ``+z`` only (no tangential terms)."""
    return ContactTangent(
        force_n=force_z_n * Z_UP,
        stiffness_n_per_m=-k_normal_n_per_m * _ZZ,
        damping_n_s_per_m=-b_normal_n_s_per_m * _ZZ,
        normal=Z_UP.copy(),
        contact_radius_m=radius_m,
    )
