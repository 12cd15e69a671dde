"""Independent 3D FEM reference (scikit-fem): the layered skin block under a rigid flat punch.

Model
-----
A linear-elastic block of the three layers, z up, rest surface z = 0, bottom at
``z = -H`` (H = total thickness). Each material point takes the modulus of the layer it
lies in, judged against the egg-carton interface functions
(:func:`skin_sim_node.model.interfaces.interface_depths_m`) at its global (x, y): the
material is evaluated at every quadrature point of every element (a finer version of
"each element's material by its position", so an interface that cuts an element is
resolved at quadrature resolution instead of snapped to element faces). Moduli: the
``default`` preset's sources (``skin_sim_node.model.calibration.LAYER_SOURCES``), Poisson ratio 0.48.

Element: 20-node serendipity hexahedra (``ElementHexS2``). Linear tets/hexes lock at
nu = 0.48 (bulk/shear = 24.7): their constant-strain kinematics cannot represent the
near-isochoric deformation under a punch and over-stiffen; quadratic serendipity hexes
do not lock at this nu and need about half the DOFs of 27-node hexes.

Mesh: a structured hex grid in the plane, mapped so that the ring of nodes at the tool
radius lies exactly on the circle ``r = r0`` (an O-grid blend), so the tool's contact
disk is conforming; uniform spacing out to a little beyond r0, then geometric growth to
the lateral extent. Through the thickness: fine uniform elements over the epidermis and
its rete-ridge band, the dermis and the dermis/fat interface band, then graded to the bottom.

Boundary conditions
-------------------
- bottom ``z = -H``: fixed (u = 0): the fat is bonded to fascia/muscle, taken as rigid.
- outer sides: rollers (zero normal displacement, free in-plane and vertical slip): the
  sheet continues beyond the modelled extent; the extent is large enough that clamping
  instead changes the force by under the convergence tolerance (see ``docs/validation.md``).
- a sheet edge (the near-edge scenario): traction free (a cut sheet).
- symmetry planes: rollers. With the contact on an interface peak or valley both egg
  cartons are even about the contact in x and y, so a quarter model is exact; near a
  sheet edge only the y-symmetry holds and a half model is used.
- tool: a rigid flat punch of radius r0, frictionless: ``u_z = -depth`` on the surface
  nodes inside the disk, in-plane free. The reaction force is the sum of the nodal
  z-forces there. The problem is linear, so one solve at unit depth gives the whole
  force-depth line and the surface field per metre of depth.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla
from skfem import Basis, BilinearForm, ElementHexS2, ElementVector, FacetBasis, LinearForm, MeshHex, condense
from skfem import solve as solve_linear
from skfem.helpers import ddot, sym_grad, trace
from tqdm import tqdm

from skin_sim_node.model.calibration import LAYER_SOURCES, POISSON_RATIO
from skin_sim_node.model.config import TissueConfig, preset

from .cache import cached

FEM_VERSION = 1  # bump when the discretisation changes: part of the cache key
CACHE_DIR = Path(__file__).resolve().parents[2] / "docs" / "validation" / "fem_cache"
USED_KEYS: set[str] = set()  # cache keys asked for in this process (for pruning stale entries)


@dataclass(frozen=True)
class FemSetup:
    """One FEM solve: geometry, mesh density and the tissue it runs on (lengths in m).

    ``contact_xy_m`` is the tool centre in the tissue frame; ``edge_distance_m`` the distance
    from it to a free sheet edge along +x (None: no edge within the model, quarter symmetry).
    ``n_tool`` elements span the tool radius; ``n_out`` graded elements run from there to
    ``half_width_m``; ``nz`` is the element count (epidermis band, dermis band, fat).
    """

    contact_xy_m: tuple[float, float] = (0.0, 0.0)
    half_width_m: float = 0.03
    edge_distance_m: float | None = None
    n_tool: int = 6
    n_out: int = 8
    nz: tuple[int, int, int] = (3, 6, 4)
    side_bc: str = "rollers"  # or "clamped"
    moduli_pa: tuple[float, float, float] = tuple(v[1] for v in LAYER_SOURCES.values())
    poisson: float = POISSON_RATIO
    tissue: tuple = field(default_factory=lambda: _geometry_key(preset("default")))

    def key(self) -> str:
        """Cache key: a hash of the setup and :data:`FEM_VERSION`."""
        blob = json.dumps({"v": FEM_VERSION, **asdict(self)}, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _geometry_key(cfg: TissueConfig) -> tuple:
    """The tissue geometry the FEM needs: thicknesses, interfaces, tool radius (hashable)."""
    return (
        tuple(la.thickness_m for la in cfg.layers),
        tuple((i.mean_depth_m, i.amplitude_m, i.wavelength_x_m, i.wavelength_y_m) for i in cfg.interfaces),
        cfg.tool_radius_m,
    )


@dataclass
class FemResult:
    """Unit-depth solution: force per metre of depth and the surface field per metre of depth."""

    setup: FemSetup
    stiffness_n_per_m: float  # F = stiffness * depth (linear)
    sample_x_m: np.ndarray  # global x of the surface samples (1D)
    sample_y_m: np.ndarray  # global y of the surface samples (1D)
    surface_per_depth: np.ndarray  # (ny, nx) downward surface displacement / tool depth
    n_dofs: int
    solve_s: float  # wall time of assembly + factorisation + solve on this machine

    def force_n(self, depth_m):
        """Force at ``depth_m`` (N): the linear reference scales with depth."""
        return self.stiffness_n_per_m * np.asarray(depth_m)


def axis_nodes(r0: float, n_tool: int, extent: float, n_out: int, n_band: int = 3) -> np.ndarray:
    """1D node positions: uniform (h = r0/n_tool) to ``r0 + n_band h``, then geometric to ``extent``."""
    h = r0 / n_tool
    inner = h * np.arange(n_tool + n_band + 1)
    start = inner[-1]
    if extent <= start + h:
        raise ValueError(f"extent {extent} m too small for the tool band ({start} m)")
    # geometric growth from h: solve sum_{k=1..n_out} h q^k = extent - start for q
    gap = extent - start
    lo, hi = 1.0, 10.0
    for _ in range(200):
        q = 0.5 * (lo + hi)
        total = h * q * (q**n_out - 1) / (q - 1) if q != 1 else h * n_out
        lo, hi = (q, hi) if total < gap else (lo, q)
    steps = h * q ** np.arange(1, n_out + 1)
    outer = start + np.cumsum(steps * gap / steps.sum())
    return np.concatenate([inner, outer])


def z_nodes(cfg_key: tuple, nz: tuple[int, int, int]) -> np.ndarray:
    """Depth nodes (z up, 0 .. -H): uniform over the epidermis band, the dermis band, graded fat."""
    (h_e, h_d, h_s), ifaces, _ = cfg_key
    (d1, a1, *_), (d2, a2, *_) = ifaces
    total = h_e + h_d + h_s
    z_a = d1 + a1 + 0.25 * h_e  # below the deepest rete ridge
    z_b = d2 + a2 + 0.1e-3  # below the deepest fat lobule crest
    ne, nd, nf = nz
    band1 = np.linspace(0.0, z_a, ne + 1)
    band2 = np.linspace(z_a, z_b, nd + 1)[1:]
    t = np.linspace(0.0, 1.0, nf + 1)[1:]
    band3 = z_b + (total - z_b) * t**1.5  # finer near the dermis, coarser at the bottom
    return -np.concatenate([band1, band2, band3])


def build_mesh(setup: FemSetup) -> MeshHex:
    """The mapped hex mesh in local coordinates (tool centre at the origin)."""
    r0 = setup.tissue[2]
    n_band = 3 if setup.edge_distance_m is None else 1  # a near edge leaves room for one ring only
    s_pos = axis_nodes(r0, setup.n_tool, setup.edge_distance_m or setup.half_width_m, setup.n_out, n_band)
    s_y = axis_nodes(r0, setup.n_tool, setup.half_width_m, setup.n_out, n_band)
    xs = s_pos if setup.edge_distance_m is None else np.concatenate([-s_y[:0:-1], s_pos])
    zs = z_nodes(setup.tissue, setup.nz)
    mesh = MeshHex.init_tensor(xs, s_y, zs[::-1])
    p = mesh.p.copy()
    p[0], p[1] = _o_grid(p[0], p[1], r0, r0 * (1 + n_band / setup.n_tool))
    return MeshHex(p, mesh.t)


def _o_grid(u: np.ndarray, y: np.ndarray, r0: float, k_band: float) -> tuple[np.ndarray, np.ndarray]:
    """The O-grid blend about a tool's centre (``u`` across, ``y`` along, from the centre): the ring of max-norm radius
    ``r0`` maps onto the circle ``r = r0``, the blend's weight falling linearly to 0 (the identity) at ``k_band``."""
    rho = np.maximum(np.abs(u), y)
    rad = np.hypot(u, y)
    w = np.where(rho <= r0, rho / r0, np.clip((k_band - rho) / (k_band - r0), 0.0, 1.0))
    blend = (1 - w) + w * np.where(rad > 0, rho / np.where(rad > 0, rad, 1.0), 1.0)
    return u * blend, y * blend


def offset_axis_nodes(r0: float, n_tool: int, centre_m: float, extent: float, n_out: int, n_band: int = 3) -> np.ndarray:
    """1D node positions from 0 to ``extent`` with a tool of radius ``r0`` centred at ``centre_m`` (>= 0).

    To the right of the centre: :func:`axis_nodes` (uniform ``h = r0 / n_tool`` to ``r0 + n_band h``, then geometric).
    To the left: the same uniform band down to 0 when it reaches there (a node closer to 0 than ``0.3 h`` is dropped,
    so no sliver element sits on the symmetry plane), else the band and then geometric growth (elements about
    ``2 h`` on average) to 0. The node at 0 is always there: the plane ``x = 0`` is a mesh plane.
    """
    if centre_m <= 0.0:
        return axis_nodes(r0, n_tool, extent, n_out, n_band)
    h = r0 / n_tool
    right = centre_m + axis_nodes(r0, n_tool, extent - centre_m, n_out, n_band)
    band = r0 + n_band * h
    if centre_m >= band + 2 * h:
        n_left = max(1, round((centre_m - band) / (2 * h)))
        left = centre_m - axis_nodes(r0, n_tool, centre_m, n_left, n_band)[1:-1]
    else:
        left = centre_m - h * np.arange(1, int(np.floor(centre_m / h)) + 1)
        left = left[left > 0.3 * h]
    return np.concatenate([[0.0], np.sort(left), right])


def build_offset_mesh(setup: FemSetup, centre_x_m: float, mirror: bool) -> MeshHex:
    """The mapped hex mesh of a tool centred at ``(centre_x_m, 0)`` in the tissue frame (no local shift).

    The block is ``0 <= x, y <= half_width_m`` (a quarter: symmetry planes ``x = 0`` and ``y = 0``), or with
    ``mirror`` its reflection across ``x = 0`` added (``-half_width_m <= x``, a half model; the nodes at ``x < 0``
    are the mirror images of those at ``x > 0``, so a solution even in ``x`` is the quarter model's). Along x the
    nodes are :func:`offset_axis_nodes`, along y :func:`axis_nodes`, in z :func:`z_nodes`, as in :func:`build_mesh`.

    The ring of nodes at max-norm distance ``r0`` from the tool centre lies on the circle ``r = r0`` (the contact
    disk conforms), while the plane ``x = 0`` stays a plane:

    - when the plane is beyond the tool (``centre_x_m > r0``), by the O-grid blend of :func:`build_mesh`, whose weight
      also falls linearly to 0 between the ring and the plane;
    - when it cuts the tool (``centre_x_m < r0``: two overlapping punches, the union of their disks in the quarter is
      this disk), the columns left of the centre are stretched along y only (the ring node of column ``u`` goes to
      ``y = sqrt(r0^2 - u^2)``, the band above is stretched to meet the unmapped grid), and the right side uses the
      O-grid blend; both are the identity on the column through the centre.

    A single tool (``mirror``) that crosses ``x = 0`` (``centre_x_m < r0``: the single of an overlapping pair) is the
    exception: the mirror image of the quarter's mesh conforms to the union of the two disks, not to the one disk, so
    the sliver of the disk beyond ``x = 0`` would end on a staircase of nodes, and its force would move with the mesh
    level (the 4 mm single at 0.25 mm: 0.0856, 0.0894, 0.0862 N at levels -2, -1, 0). It gets a mesh of its own,
    :func:`_single_overlap_mesh`.
    """
    r0 = setup.tissue[2]
    n_band = 3
    h = r0 / setup.n_tool
    a = float(centre_x_m)
    if mirror and a < r0:
        return _single_overlap_mesh(setup, a, n_band)
    xs = offset_axis_nodes(r0, setup.n_tool, a, setup.half_width_m, setup.n_out, n_band)
    ys = axis_nodes(r0, setup.n_tool, setup.half_width_m, setup.n_out, n_band)
    zs = z_nodes(setup.tissue, setup.nz)
    if mirror:
        xs = np.concatenate([-xs[:0:-1], xs])
    mesh = MeshHex.init_tensor(xs, ys, zs[::-1])
    p = mesh.p.copy()
    sign, ax = np.where(p[0] < 0, -1.0, 1.0), np.abs(p[0])  # the map of x >= 0, reflected onto x < 0
    u, y = ax - a, p[1]
    au = np.abs(u)
    rho = np.maximum(au, y)
    rad = np.hypot(au, y)
    k_tool, k_band = r0, r0 + n_band * h
    w = np.where(rho <= k_tool, rho / k_tool, np.clip((k_band - rho) / (k_band - k_tool), 0.0, 1.0))
    if a > r0:
        w = np.where(u < -r0, w * np.clip((u + a) / (a - r0), 0.0, 1.0), w)
    scale = np.where(rad > 0, rho / np.where(rad > 0, rad, 1.0), 1.0)
    blend = (1 - w) + w * scale
    new_u, new_y = u * blend, y * blend
    if a < r0:
        left = u < 0
        c = np.sqrt(np.maximum(r0**2 - u**2, 0.0))
        y_str = np.where(y <= r0, y * c / r0, np.where(y <= k_band, c + (y - r0) * (k_band - c) / (k_band - r0), y))
        new_u = np.where(left, u, new_u)
        new_y = np.where(left, y_str, new_y)
    new_x = np.where(ax < 1e-15, 0.0, new_u + a)  # the plane x = 0 exactly
    p[0], p[1] = sign * new_x, new_y
    return MeshHex(p, mesh.t)


def _single_overlap_mesh(setup: FemSetup, centre_x_m: float, n_band: int) -> MeshHex:
    """The half model ``y >= 0``, ``-half_width_m <= x <= half_width_m``, of one tool at ``(centre_x_m, 0)`` that
    crosses ``x = 0``: :func:`build_mesh`'s O-grid centred on the tool (its disk conforms all round), the graded nodes
    running from the tool's band to each side (``half_width_m - centre_x_m`` to the right, ``half_width_m +
    centre_x_m`` to the left, ``setup.n_out`` elements each). Nothing keeps ``x = 0`` a mesh plane: the half
    model has no symmetry plane there."""
    r0 = setup.tissue[2]
    a = float(centre_x_m)
    w_half = setup.half_width_m
    right = a + axis_nodes(r0, setup.n_tool, w_half - a, setup.n_out, n_band)
    left = a - axis_nodes(r0, setup.n_tool, w_half + a, setup.n_out, n_band)[:0:-1]
    xs = np.concatenate([left, right])
    ys = axis_nodes(r0, setup.n_tool, w_half, setup.n_out, n_band)
    zs = z_nodes(setup.tissue, setup.nz)
    mesh = MeshHex.init_tensor(xs, ys, zs[::-1])
    p = mesh.p.copy()
    u, p[1] = _o_grid(p[0] - a, p[1], r0, r0 * (1 + n_band / setup.n_tool))
    p[0] = a + u
    p[0] = np.where(np.abs(np.abs(p[0]) - w_half) < 1e-12, np.sign(p[0]) * w_half, p[0])  # the outer planes exactly
    return MeshHex(p, mesh.t)


def _modulus_field(setup: FemSetup, x, y, z):
    """Young's modulus at global (x, y) and depth -z, by the egg-carton interfaces."""
    (_, ifaces, _) = setup.tissue
    depth = -z
    e = np.full(np.shape(x), setup.moduli_pa[2])
    lower = np.zeros(np.shape(x), dtype=bool)
    for j in (1, 0):
        mean, amp, wx, wy = ifaces[j]
        d_j = mean - amp * np.cos(2 * np.pi * x / wx) * np.cos(2 * np.pi * y / wy)
        above = depth < d_j
        e = np.where(above, setup.moduli_pa[j], e)
        lower |= ~above
    return e


def elasticity_form(setup: FemSetup, offset_xy_m=(0.0, 0.0)) -> BilinearForm:
    """Isotropic linear elasticity with the modulus of :func:`_modulus_field` at each quadrature point."""
    nu = setup.poisson
    xc, yc = offset_xy_m

    @BilinearForm
    def elasticity(u, v, w):
        e = _modulus_field(setup, w.x[0] + xc, w.x[1] + yc, w.x[2])
        lam = e * nu / ((1 + nu) * (1 - 2 * nu))
        mu = e / (2 * (1 + nu))
        eu, ev = sym_grad(u), sym_grad(v)
        return 2 * mu * ddot(eu, ev) + lam * trace(eu) * trace(ev)

    return elasticity


def layered_column(setup: FemSetup, pressure_pa: float, width_m: float = 1e-3, n_per_layer: int = 2) -> tuple[float, float]:
    """Top settlement (m, down) of a laterally confined layered column under uniform pressure.

    The same material law and assembly as :func:`solve`, on a ``width_m`` square column with
    roller sides and a fixed bottom; flat interfaces at the layers' mean depths. Returns the
    FEM settlement and the series-spring closed form ``p sum(h_i / M_i)``, with the
    constrained modulus ``M = E (1 - nu) / ((1 + nu)(1 - 2 nu))`` (uniaxial strain).
    """
    (hs, ifaces, r0) = setup.tissue
    flat = FemSetup(
        moduli_pa=setup.moduli_pa, poisson=setup.poisson, tissue=(hs, tuple((m, 0.0, 1.0, 1.0) for m, *_ in ifaces), r0)
    )
    edges = np.concatenate([[0.0], np.cumsum(hs)])
    zs = np.unique(np.concatenate([np.linspace(a, b, n_per_layer + 1) for a, b in zip(edges[:-1], edges[1:])]))
    mesh = MeshHex.init_tensor(np.linspace(0, width_m, 2), np.linspace(0, width_m, 2), -zs[::-1])
    basis = Basis(mesh, ElementVector(ElementHexS2()), intorder=3)
    K = elasticity_form(flat).assemble(basis)
    top = FacetBasis(mesh, basis.elem, facets=mesh.facets_satisfying(lambda x: np.abs(x[2]) < 1e-12), intorder=3)

    @LinearForm
    def load(v, w):
        return -pressure_pa * v[2]

    f = load.assemble(top)
    tol = 1e-12
    fixed = np.concatenate(
        [
            basis.get_dofs(lambda x: np.abs(x[2] + edges[-1]) < tol).all(),
            basis.get_dofs(lambda x: (np.abs(x[0]) < tol) | (np.abs(x[0] - width_m) < tol)).all("u^1"),
            basis.get_dofs(lambda x: (np.abs(x[1]) < tol) | (np.abs(x[1] - width_m) < tol)).all("u^2"),
        ]
    )
    u = solve_linear(*condense(K, f, D=np.unique(fixed)))
    top_dofs = basis.get_dofs(lambda x: np.abs(x[2]) < tol).all("u^3")
    nu = setup.poisson
    m_con = np.array(setup.moduli_pa) * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    return float(-u[top_dofs].mean()), float(pressure_pa * np.sum(np.array(hs) / m_con))


def sparse_solve(a, b):
    """Solve the SPD system: Intel MKL PARDISO when ``pypardiso`` is installed, else SuperLU.

    SuperLU (scipy) needs minutes and GBs from about 50k DOFs of these 3D quadratic meshes;
    PARDISO's nested-dissection ordering does 50k DOFs in ~25 s on one busy core.
    """
    try:
        import pypardiso
    except ImportError:
        return spla.splu(a.tocsc(), permc_spec="COLAMD").solve(b)
    return pypardiso.spsolve(a.tocsr(), b)


def solve(setup: FemSetup, progress: bool = True, sample_step_m: float = 0.5e-3) -> FemResult:
    """Assemble and solve the unit-depth punch problem (no cache; see :func:`reference`)."""
    t0 = time.perf_counter()
    steps = tqdm(total=4, desc=f"FEM {setup.key()[:8]}", disable=not progress, leave=False)
    mesh = build_mesh(setup)
    basis = Basis(mesh, ElementVector(ElementHexS2()), intorder=3)
    xc, yc = setup.contact_xy_m

    elasticity = elasticity_form(setup, (xc, yc))
    K = elasticity.assemble(basis).tocsr()
    steps.update()
    r0 = setup.tissue[2]
    bottom = mesh.p[2].min()
    far = setup.half_width_m * (1 - 1e-9)
    tol = 1e-12
    fixed = {
        "bottom": basis.get_dofs(lambda x: np.abs(x[2] - bottom) < tol).all(),
        "ysym": basis.get_dofs(lambda x: np.abs(x[1]) < tol).all("u^2"),
    }
    if setup.edge_distance_m is None:
        fixed["xsym"] = basis.get_dofs(lambda x: np.abs(x[0]) < tol).all("u^1")
    side_names = ["u^1", "u^2", "u^3"] if setup.side_bc == "clamped" else None
    side_x = basis.get_dofs(lambda x: np.abs(x[0]) > far if setup.edge_distance_m is None else x[0] < -far)
    side_y = basis.get_dofs(lambda x: x[1] > far)
    fixed["side_x"] = side_x.all(side_names or "u^1")
    fixed["side_y"] = side_y.all(side_names or "u^2")
    tool = basis.get_dofs(lambda x: (np.abs(x[2]) < tol) & (np.hypot(x[0], x[1]) <= r0 * (1 + 1e-9))).all("u^3")
    fixed_all = np.unique(np.concatenate(list(fixed.values())))
    fixed_all = np.setdiff1d(fixed_all, tool)
    u = np.zeros(K.shape[0])
    u[tool] = -1.0  # unit depth, z up
    known = np.concatenate([fixed_all, tool])
    free = np.setdiff1d(np.arange(K.shape[0]), known)
    rhs = -K[free][:, known] @ u[known]
    Kff = K[free][:, free].tocsc()
    steps.update()
    u[free] = sparse_solve(Kff, rhs)
    steps.update()
    reaction = K[tool] @ u  # nodal z-forces on the tool dofs (z up): negative = pushing down
    sym = 4.0 if setup.edge_distance_m is None else 2.0
    stiffness = float(-reaction.sum() * sym)
    # surface samples in local coordinates
    xmax = setup.edge_distance_m or setup.half_width_m
    sx = np.arange(0.0 if setup.edge_distance_m is None else -setup.half_width_m, xmax + 1e-12, sample_step_m)
    sy = np.arange(0.0, setup.half_width_m + 1e-12, sample_step_m)
    sx = np.clip(sx, -setup.half_width_m * (1 - 1e-9), xmax * (1 - 1e-9))
    sy = np.clip(sy, 0.0, setup.half_width_m * (1 - 1e-9))
    X, Y = np.meshgrid(sx, sy)
    pts = np.vstack([X.ravel(), Y.ravel(), np.full(X.size, -1e-12)])
    uz, uz_basis = basis.split(u)[2]
    field_down = -(uz_basis.probes(pts) @ uz).reshape(X.shape)
    steps.update()
    steps.close()
    return FemResult(setup, stiffness, sx + xc, sy + yc, field_down, K.shape[0], time.perf_counter() - t0)


def reference(setup: FemSetup, cache_dir: Path | None = CACHE_DIR, progress: bool = True) -> FemResult:
    """:func:`solve` with an on-disk cache keyed by the hash of ``setup``."""
    USED_KEYS.add(setup.key())
    path = None if cache_dir is None else Path(cache_dir) / f"{setup.key()}.npz"

    def load(z) -> FemResult:
        return FemResult(setup, float(z["stiffness"]), z["sx"], z["sy"], z["field"], int(z["n_dofs"]), float(z["solve_s"]))

    def arrays(res: FemResult) -> dict:
        return {
            "stiffness": res.stiffness_n_per_m,
            "sx": res.sample_x_m,
            "sy": res.sample_y_m,
            "field": res.surface_per_depth.astype(np.float32),
            "n_dofs": res.n_dofs,
            "solve_s": res.solve_s,
            "setup": json.dumps(asdict(setup), default=str),
        }

    # the tracked cache is read; a new solve goes to out/cache unless skin-sim chart validation --docs (cache.py)
    return cached(path, False, lambda: solve(setup, progress), load, arrays)


def mesh_levels(level: int, base: FemSetup) -> FemSetup:
    """Uniform refinement: ``level`` doubles every element count ``level`` times... by 1.5x steps."""
    f = 1.5**level
    return FemSetup(
        contact_xy_m=base.contact_xy_m,
        half_width_m=base.half_width_m,
        edge_distance_m=base.edge_distance_m,
        n_tool=max(2, round(base.n_tool * f)),
        n_out=max(2, round(base.n_out * f)),
        nz=tuple(max(1, round(n * f)) for n in base.nz),
        side_bc=base.side_bc,
        moduli_pa=base.moduli_pa,
        poisson=base.poisson,
        tissue=base.tissue,
    )


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def main(argv=None) -> int:  # pragma: no cover - exercised by the chart command
    """Solve one FEM reference at ``--level`` and print its size, stiffness and solve time."""
    import argparse

    ap = argparse.ArgumentParser(description="solve one FEM reference and print its force per depth")
    ap.add_argument("--level", type=int, default=0)
    ap.add_argument("--no-cache", action="store_true")
    a = ap.parse_args(argv)
    res = reference(mesh_levels(a.level, FemSetup()), None if a.no_cache else CACHE_DIR)
    print(f"dofs {res.n_dofs}  K {_fmt(res.stiffness_n_per_m)} N/m  solve {res.solve_s:.1f} s")
    return 0
