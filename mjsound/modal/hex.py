r"""Hexahedral voxel-embedding FEM (Picard et al. 2010, after Nesme et al.).

The object is embedded in a regular grid of coarse 8-node hexahedra of size
``(hx, hy, hz)``. Each coarse cell is split into ``r^3`` fine cells whose occupancy
``o_c in [0, 1]`` comes from voxelizing the surface mesh (:mod:`.voxelize`). The coarse
cell's matrices are accumulated from its children (Picard et al., eq. 1):

.. math::  K_{parent} = \sum_c o_c\, L_c^T K_f L_c, \qquad
           M_{parent} = \sum_c o_c\, L_c^T M_f L_c

where :math:`L_c` (24x24) interpolates the child's 8 corners trilinearly from the
parent's, and :math:`K_f, M_f` are the matrices of one full fine cell. Empty children
add nothing, so partly filled cells are lighter and softer where the material is missing,
and the distribution of material inside the cell is kept.

Thin walls and locking. A fully integrated trilinear hexahedron cannot bend (its
bending mode carries parasitic shear) and rings far too high on beams, plates and
shells. The fine cell here is Wilson's *incompatible-mode* hexahedron (Wilson, Taylor,
Doherty & Ghaboussi 1973; Taylor, Beresford & Wilson 1976): the trilinear field is
enriched with the bubble modes :math:`(1-\xi^2), (1-\eta^2), (1-\zeta^2)` per component
and the 9 extra dofs are condensed out element by element,

.. math::  K_f = K_{uu} - K_{ua} K_{aa}^{-1} K_{au}.

On rectangular cells this element represents pure bending exactly. A coarse parent's
bending field restricted to a child is again trilinear, so each child relaxes its own
parasitic shear and the accumulated parent does not lock either.

Quadratic parents (``order=2``, the analysis' default) follow curved thin walls without
bubbles. They are 20-node serendipity cells (corners and edge midpoints): the 27-node
triquadratic cell's face and body centres add 42 % more dofs but, on the bowl, beam and
rod, move no frequency by more than 0.1 % (``serendipity=False`` keeps them).

All cells of a grid have the same shape, so ``K_f``, ``M_f`` and the 2 x r^3 products
:math:`L_c^T K_f L_c` are computed once; the matrices of every coarse cell are then one
matrix product ``occupancy (n_cells, r^3) @ A (r^3, 576)``: no per-element Python loop.
"""

from __future__ import annotations

import functools

import numba as nb
import numpy as np
import scipy.sparse as sp
import trimesh

from ..materials import Material
from .discretization import Discretization
from .hex_cell import (
    _CORNERS,
    CellSum,
    _condense,
    _elasticity_matrix,
    _taylor_correction,
    hex_element_matrices,
    hex_strain_integral,
    quadratic_cell_matrices,
)
from .node_mass import kron_identity3
from .surface import cavities, face_components
from .voxelize import surface_voxels, winding_moments, winding_occupancy

__all__ = ["discretize_hex", "hex_element_matrices", "grid_for"]


def _child_interpolations(r: int) -> np.ndarray:
    """L_c (r^3, 24, 33): child corner dofs from the parent's 24 corner dofs and its 9
    incompatible (bubble) amplitudes, columns ``24 + 3 d + j`` = component j times
    ``1 - xi_d^2``."""
    L = np.zeros((r**3, 24, 33))
    bits = _CORNERS > 0  # corner k has offset bits (a, b, c)
    I3 = np.eye(3)
    for a in range(r):
        for b in range(r):
            for c in range(r):
                u = (np.array([a, b, c]) + bits) / r  # child corners in parent [0,1]^3, (8, 3)
                W = np.where(bits[None, :, :], u[:, None, :], 1.0 - u[:, None, :]).prod(axis=2)  # (8 child, 8 parent)
                bubble = 1.0 - (2.0 * u - 1.0) ** 2  # (8 child, 3 directions)
                Lc = L[a * r * r + b * r + c]
                Lc[:, :24] = np.kron(W, I3)
                Lc[:, 24:] = np.kron(bubble, I3)
    return L


#: the moment correction of partly filled children (:func:`_cell_operators`) is used when
#: its 7 tables stay under this many bytes (20-node cells: up to 10 children per axis)
MOMENT_TABLE_BYTES = 110e6
#: ... which is this many children per axis of a 20-node cell
MOMENT_MAX_REFINE = 10
#: sample columns per fine voxel per axis (x, y) for the moments: the rod's bending pairs
#: split by up to 2.5 cents at 4, 0.5 at 8, 0.2 at 12 (its section sampled unevenly in x, y)
MOMENT_SUPERSAMPLE = 12
#: ... fewer (at least 2) where the fine grid's columns times ``s^2`` would exceed this
MOMENT_MAX_COLUMNS = 4e6

#: stiffness and mass of an empty child in a 27-node cell, as fractions of a full one
VOID_K = 1e-5
VOID_M = 1e-12


def _lagrange_1d(u: np.ndarray, q: int) -> np.ndarray:
    """Lagrange basis on ``q`` equally spaced nodes of [0, 1], evaluated at ``u``: (..., q)."""
    x = np.linspace(0.0, 1.0, q)
    out = np.ones(u.shape + (q,))
    for j in range(q):
        for m in range(q):
            if m != j:
                out[..., j] *= (u - x[m]) / (x[j] - x[m])
    return out


def _lagrange_1d_slope(u: np.ndarray, q: int) -> np.ndarray:
    """Derivatives d/du (..., q) of :func:`_lagrange_1d`'s basis at ``u``."""
    x = np.linspace(0.0, 1.0, q)
    out = np.zeros(u.shape + (q,))
    for j in range(q):
        others = [m for m in range(q) if m != j]
        for k in others:
            term = np.ones(u.shape) / (x[j] - x[k])
            for m in others:
                if m != k:
                    term = term * (u - x[m]) / (x[j] - x[m])
            out[..., j] += term
    return out


def _parent_weights(u: np.ndarray, q: int, slope_axis: int | None = None) -> np.ndarray:
    """Tensor Lagrange weights (..., q^3) of points u (..., 3) in [0,1]^3, x index fastest;
    with ``slope_axis`` their derivative along that axis of u."""
    w = [_lagrange_1d_slope(u[..., d], q) if d == slope_axis else _lagrange_1d(u[..., d], q) for d in range(3)]
    wx, wy, wz = w
    return (wz[..., :, None, None] * wy[..., None, :, None] * wx[..., None, None, :]).reshape(u.shape[:-1] + (q**3,))


def _child_interpolations_lagrange(r: int, q: int, shift_axis: int | None = None) -> np.ndarray:
    """L_c (r^3, 24, 3 q^3): child corner dofs from a q^3-node parent; with ``shift_axis``
    the derivative of L_c as the child moves along that axis by one child (1/r of the
    parent)."""
    bits = (_CORNERS > 0).astype(float)
    abc = np.stack(np.meshgrid(np.arange(r), np.arange(r), np.arange(r), indexing="ij"), -1).reshape(-1, 3)
    u = (abc[:, None, :] + bits[None, :, :]) / r  # (r^3 children, 8 corners, 3)
    W = _parent_weights(u, q, shift_axis)  # (r^3, 8, q^3)
    if shift_axis is not None:
        W = W / r
    L = np.zeros((r**3, 8, 3, q**3, 3))
    for j in range(3):
        L[:, :, j, :, j] = W
    return L.reshape(r**3, 24, 3 * q**3)


def _serendipity_nodes() -> np.ndarray:
    """Indices (20,) of the 27-node cell's nodes (x fastest) that a 20-node serendipity
    cell keeps: the corners and edge midpoints (at most one coordinate in the middle)."""
    loc = np.array([[a, b, c] for c in range(3) for b in range(3) for a in range(3)])
    return np.flatnonzero((loc == 1).sum(axis=1) <= 1)


@functools.lru_cache(maxsize=1)
def _serendipity_embedding() -> np.ndarray:
    r"""T (27, 20): the 27 node values of a 20-node serendipity field from its 20 nodes.

    The serendipity space (P2 plus the cubic and quartic terms of at most quadratic
    degree per variable) lies inside the triquadratic one, so a 20-node cell is a 27-node
    cell whose face and body centres follow the others:
    face centre = -1/4 (its 4 corners) + 1/2 (its 4 edge midpoints),
    body centre = -1/4 (8 corners) + 1/4 (12 edge midpoints).
    """
    loc = np.array([[a, b, c] for c in range(3) for b in range(3) for a in range(3)]) - 1  # in {-1, 0, 1}
    keep = _serendipity_nodes()
    xi = loc[keep].astype(float)  # (20, 3) node coordinates
    T = np.zeros((27, 20))
    for p, x in enumerate(loc.astype(float)):
        for j, n in enumerate(xi):
            zero = n == 0
            if not zero.any():  # corner
                T[p, j] = np.prod(1 + x * n) * (np.dot(x, n) - 2) / 8.0
            else:  # edge midpoint, middle along axis d
                d = int(np.flatnonzero(zero)[0])
                o = [k for k in range(3) if k != d]
                T[p, j] = (1 - x[d] ** 2) * np.prod(1 + x[o] * n[o]) / 4.0
    T.flags.writeable = False
    return T


def _congruence(L: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``L_c^T A L_c`` for every child c (batched matmuls; einsum of three operands is slow)."""
    return np.swapaxes(L, 1, 2) @ (A @ L)


def _node_block_order(m3: int) -> np.ndarray:
    """Columns that reorder a flattened (3 m3, 3 m3) element matrix, dofs ``3 node + axis``,
    into its m3 x m3 node blocks of 3 x 3: entry ``((a m3 + b) 3 + i) 3 + j`` is
    ``(3 a + i, 3 b + j)``, so the 9 numbers of each node pair are contiguous."""
    a, b, i, j = np.meshgrid(np.arange(m3), np.arange(m3), np.arange(3), np.arange(3), indexing="ij")
    return ((3 * a + i) * (3 * m3) + 3 * b + j).ravel()


def grid_for(bounds, h: float, min_cells=1):
    """Coarse grid tiling the bounding box exactly: per-axis cell count and size.

    ``n_d = max(min_cells_d, ceil(extent_d / h))`` and ``h_d = extent_d / n_d``, so
    box-like objects fit their cells (cells may be non-cubic, as in Picard et al.).
    """
    lo, hi = (np.asarray(b, float) for b in bounds)
    ext = hi - lo
    n = np.maximum(np.maximum(1, min_cells), np.ceil(ext / h - 1e-9)).astype(int)
    return lo, n, ext / n


def _components(mesh: trimesh.Trimesh) -> list:
    """Connected pieces of a mesh (faces sharing an edge, :func:`.surface.face_components`)."""
    n, label = face_components(mesh)
    if n == 1:
        return [mesh]
    return [trimesh.Trimesh(mesh.vertices, mesh.faces[label == k], process=False) for k in range(n)]


def _occupancy(mesh: trimesh.Trimesh, lo, nfine, hfine, supersample: int, thickness: float | None,
               moments: bool = False):
    """Fine-voxel occupancy in [0, 1], shape ``nfine``, and with ``moments`` the first
    moments of the filled parts (``nfine + (3,)``, :func:`.voxelize.winding_moments`; zero
    in full voxels and in an open surface's slab), else None."""
    s = int(supersample)
    occ = np.zeros(tuple(nfine), np.float32)
    mom = np.zeros(tuple(nfine) + (3,), np.float32) if moments else None

    def closed_fill(tris):
        if moments:
            return winding_moments(tris, lo, hfine, nfine, s)
        return winding_occupancy(tris, lo, hfine, nfine, s), None

    parts = _components(mesh)
    closed = [p.is_watertight and abs(p.volume) > 0 for p in parts]
    # An inward-facing closed part inside an outward one is a cavity (the inner shell of a
    # hollow object): it is cut out after the solids are filled. Other inward parts are
    # solids with flipped faces: filled.
    cavity = cavities(parts)
    for part, is_closed, is_cavity in zip(parts, closed, cavity):
        tris = part.triangles
        if is_cavity:
            continue
        if is_closed:
            frac, m = closed_fill(tris)
            if moments:  # a union keeps the fuller part's voxel
                mom = np.where((frac > occ)[..., None], m, mom)
            occ = np.maximum(occ, frac)
        else:
            # An open surface becomes a slab of the wall thickness around it: the voxels
            # touched by copies of the surface offset along its vertex normals by up to t/2
            # (a slab thinner than a voxel fills its voxels fractionally).
            hmin = float(np.min(hfine))
            t = hmin if thickness is None else float(thickness)
            fill = min(1.0, t / hmin)
            n_off = int(min(64, 2 * np.ceil(0.5 * t / (0.5 * hmin)) + 1))
            shell = np.zeros(tuple(nfine), np.uint8)
            normals = part.vertex_normals[part.faces]  # (F, 3, 3)
            for off in np.linspace(-0.5 * t, 0.5 * t, n_off) if t > hmin else [0.0]:
                shell |= surface_voxels(tris + off * normals, lo, hfine, nfine)
            slab = shell.astype(np.float32) * fill
            if moments:
                mom[slab > occ] = 0.0
            occ = np.maximum(occ, slab)
    for part, is_cavity in zip(parts, cavity):
        if is_cavity:
            frac, m = closed_fill(part.triangles)
            if moments:
                mom -= m
            occ = np.maximum(occ - frac, 0.0)
    if moments:
        mom[(occ <= 0.0) | (occ >= 1.0)] = 0.0
    return occ, mom


def _cell_operators(hf, r: int, material: Material, order: int, incompatible: bool, embed=None,
                    moments: bool = False):
    r"""The coarse cell's matrices as functions of its children's occupancies (cells, r^3).

    Returns ``cell_K(occ, mom=None)`` (cells, (3m)^2) in node-block order
    (:func:`_node_block_order`) and ``cell_M(occ, mom=None)`` (cells, m^2), the scalar node
    mass, for m parent nodes; ``hf`` is the fine cell size [m], ``embed`` the quadratic
    cell's 27-node values from its own nodes (:func:`_serendipity_embedding`; None: all 27
    nodes).

    ``moments`` (quadratic cells): also take the children's first moments ``mom`` (cells,
    r^3, 3) [children], ``o d`` with ``d`` the filled part's centroid offset from the
    child's centre (:func:`.voxelize.winding_moments`). A partly filled child then counts
    as a full one of density ``o`` moved by ``d``: with :math:`L_{c,k}'` the derivative of
    :math:`L_c` as the child moves along axis k by one child, and
    :math:`A = L_c^T K_f L_c`, :math:`B_k = L_{c,k}'^T K_f L_c + L_c^T K_f L_{c,k}'`,
    :math:`C_k = L_{c,k}'^T K_f L_{c,k}'`,

    .. math:: K_c = o \left(A + \sum_k d_k B_k + 3 \sum_k d_k^2 C_k\right)
              = \frac{o}{3} \sum_k (L_c + 3 d_k L_{c,k}')^T K_f (L_c + 3 d_k L_{c,k}')

    right to first order in ``d`` (the shifted child's own second-order term is
    :math:`\sum_{jk} d_j d_k L_{c,j}'^T K_f L_{c,k}'`) and positive semi-definite (a sum of
    congruences; the first-order terms alone are not, and made a thin disc's stiffness
    indefinite). The mass is weighted alike. The weights are ``o``, ``o d_k`` and
    ``3 o d_k^2``: 7 tables instead of 1. Without them the surface children's material
    sits at their centres, outside where it is: a round rod's bending modes rang +15 cents
    sharp (its section's second moment 1 % high) at default quality.
    """
    Kf, Mf = hex_element_matrices(hf, material, incompatible=incompatible)
    if order == 1:
        L = _child_interpolations(r)
        Lu = L[:, :, :24]
        AK = _congruence(L if incompatible else Lu, Kf).reshape(r**3, -1)
        AS = (hex_strain_integral(hf) @ L).reshape(r**3, 6 * 33)
        AM = CellSum(lambda: _congruence(Lu[:, 0::3, 0::3], Mf[0::3, 0::3]), 8)
        D = _elasticity_matrix(material)
        V_f = float(np.prod(hf))

        def cell_K(ch, mom=None):
            if not incompatible:
                return (ch @ AK)[:, _node_block_order(8)]
            K33 = (ch @ AK).reshape(-1, 33, 33)
            G = (ch @ AS).reshape(-1, 6, 33)
            K33 = _taylor_correction(K33, G, ch.sum(axis=1) * V_f, D)
            return _condense(K33).reshape(len(ch), -1)[:, _node_block_order(8)]

        def mass_weight(ch, mom=None):
            return ch
    else:
        # Quadratic (20- or 27-node) parents follow curved thin walls without bubbles. Their
        # nodes are not all pinned by the corners of a few filled children, so the empty
        # children get a "stiff void": stiffness VOID_K and mass VOID_M of a full cell, which
        # removes the null space and puts the void's own modes far above any audible band.
        # Full cells get the exact quadratic cell (.hex_cell); the children's table is
        # built only if a partly filled cell needs it.
        m = 27 if embed is None else embed.shape[1]
        Kx, Mx = quadratic_cell_matrices(hf * r, material, order + 1, embed)

        @functools.lru_cache(maxsize=4)
        def children(shift_axis=None):
            Lu = _child_interpolations_lagrange(r, order + 1, shift_axis)
            return Lu if embed is None else Lu @ np.kron(embed, np.eye(3))

        def table(A, comp):
            """The children's congruences of ``A`` (and, with moments, the B_k and C_k
            above), one block at a time."""
            L = children()[:, comp, comp]
            AL = A @ L
            yield np.swapaxes(L, 1, 2) @ AL
            if moments:
                for k in range(3):
                    dLt = np.swapaxes(children(k)[:, comp, comp], 1, 2)
                    B = dLt @ AL
                    yield B + np.swapaxes(B, 1, 2)
                for k in range(3):
                    yield _congruence(children(k)[:, comp, comp], A)

        scalar = slice(0, None, 3)
        AK = CellSum(lambda: table(Kf, slice(None)), 3 * m, full=Kx, columns=_node_block_order(m),
                     n_occupancy=r**3)
        AM = CellSum(lambda: table(Mf[scalar, scalar], scalar), m, full=Mx, n_occupancy=r**3)

        def weights(ch, mom, void):
            w = ch + void * (1.0 - ch)  # the void (stiff or heavy only to VOID_*) stays centred
            if not moments:
                return w
            first = np.moveaxis(mom, 2, 1).reshape(len(ch), -1)  # (cells, 3 r^3): o d_k, axis-major
            second = 3.0 * first**2 / np.maximum(np.tile(ch, 3), 1e-30)  # 3 o d_k^2
            return np.concatenate([w, first, second], axis=1)

        def cell_K(ch, mom=None):
            return AK(weights(ch, mom, VOID_K))

        def mass_weight(ch, mom=None):
            return weights(ch, mom, VOID_M)

    # Mass from the compatible field only, as for Wilson's element. The consistent mass of
    # an isotropic field is (scalar node mass) x I3: M_f = m_f (x) I3 and L_c = W_c (x) I3,
    # so L_c^T M_f L_c = (W_c^T m_f W_c) (x) I3 and only the scalar part is summed (9x
    # fewer entries), and M = kron(M_node, I3) holds exactly (the eigensolver's fast mass
    # product relies on it): AM sums the scalar parts.

    def cell_M(ch, mom=None):
        return AM(mass_weight(ch, mom))

    return cell_K, cell_M


def discretize_hex(
    mesh: trimesh.Trimesh,
    material: Material,
    h: float,
    points: np.ndarray,
    refine: int = 3,
    supersample: int | None = None,
    thickness: float | None = None,
    incompatible: bool = True,
    min_fill: float = 1e-3,
    min_cells=1,
    order: int = 1,
    serendipity: bool = True,
    moments: bool = False,
) -> Discretization:
    """Voxel-embedded hexahedral FEM of a surface mesh (any mesh: open, non-manifold ...).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Surface in metres. Closed components are filled (inward-facing ones beside outward
        ones are cavities: the inner shell of a hollow object); open ones become voxel shells.
    material : Material
    h : float
        Target coarse element size [m] (per-axis sizes tile the bounding box, <= h).
    points : (p, 3) array
        Surface points where mode shapes are wanted [m].
    refine : int
        Fine cells per coarse cell per axis (``r``); ``r^3`` children per element.
    supersample : int, optional
        Inside-test samples per fine cell per axis (occupancy resolution ``1/s^3``); with
        ``moments``, sample columns per fine cell in x and y (z is exact). Default 2, or
        with moments :data:`MOMENT_SUPERSAMPLE` (fewer where the columns would exceed
        :data:`MOMENT_MAX_COLUMNS`).
    thickness : float, optional
        Wall thickness [m] for open surfaces; default one fine voxel.
    incompatible : bool
        Wilson incompatible-mode fine cells (True) or plain trilinear (locks).
    min_fill : float
        Coarse cells filled less than this fraction are dropped.
    min_cells : int or (3,) ints
        Minimum coarse cells per axis (thin bars need a few across their section).
    order : {1, 2}
        Coarse element: 8-node (trilinear + condensed bubbles) or quadratic, which also
        follows curved thin walls (less membrane locking).
    serendipity : bool
        Quadratic cells with 20 nodes (True) or 27 (triquadratic).
    moments : bool
        Quadratic cells: place each partly filled child's material at its centroid, to
        first order (:func:`_cell_operators`), where the children's tables (7 x those
        without) stay under :data:`MOMENT_TABLE_BYTES` (:func:`.plan.hex_moments` decides
        for an analysis).

    Returns
    -------
    Discretization with ``info`` = element sizes, grid, cell and node counts.
    """
    r = int(refine)
    if order not in (1, 2):
        raise ValueError(f"hex order must be 1 or 2, got {order}")
    if r < 1:
        raise ValueError(f"refine must be >= 1, got {refine}")
    # A flat (zero-volume) surface has a zero extent: give it the wall thickness (or one
    # fine voxel) so the grid has cells to fill.
    bounds = np.array(mesh.bounds, dtype=float)
    wall = float(thickness) if thickness is not None else h / r
    thin = (bounds[1] - bounds[0]) < 0.5 * wall
    bounds[0, thin] -= 0.5 * wall
    bounds[1, thin] += 0.5 * wall
    lo, n, hc = grid_for(bounds, h, min_cells)
    nfine = n * r
    embed = _serendipity_embedding() if order == 2 and serendipity else None
    cell_nodes = 27 if embed is None else embed.shape[1]
    moments = bool(moments and order == 2 and 7 * r**3 * (3 * cell_nodes) * (3 * cell_nodes + 1) / 2 * 8 <= MOMENT_TABLE_BYTES)
    if supersample is None:
        columns = float(nfine[0]) * float(nfine[1])
        supersample = int(np.clip(np.sqrt(MOMENT_MAX_COLUMNS / columns), 2, MOMENT_SUPERSAMPLE)) if moments else 2
    if np.prod(nfine.astype(float)) * supersample ** (2 if moments else 3) > 4e9:
        raise ValueError(
            f"hex grid of {tuple(nfine)} fine cells is too large; lower the quality or --resolution"
        )
    occ, mom = _occupancy(mesh, lo, nfine, hc / r, supersample, thickness, moments)
    cell_K, cell_M = _cell_operators(hc / r, r, material, order, incompatible, embed, moments)
    q = int(order) + 1  # parent nodes per axis
    # (NX, r, NY, r, NZ, r) -> (cells, children) with child index a r^2 + b r + c
    child = occ.reshape(n[0], r, n[1], r, n[2], r).transpose(0, 2, 4, 1, 3, 5).reshape(-1, r**3)
    fill = child.mean(axis=1)
    active = np.flatnonzero(fill >= min_fill)
    if len(active) == 0:
        raise ValueError("hex: the mesh fills no voxel; it is degenerate (zero volume and no area) or far too small")
    child = child[active].astype(np.float64)
    if moments:
        mom = mom.reshape(n[0], r, n[1], r, n[2], r, 3).transpose(0, 2, 4, 1, 3, 5, 6).reshape(-1, r**3, 3)
        mom = mom[active].astype(np.float64)

    # cell (i, j, k) local node (a, b, c) -> lattice node ((q-1) i + a, ...)
    ci, cj, ck = np.unravel_index(active, tuple(n))
    loc = np.array([[a, b, c] for c in range(q) for b in range(q) for a in range(q)])  # x fastest
    if embed is not None:
        loc = loc[_serendipity_nodes()]
    gnode = np.ravel_multi_index(
        ((q - 1) * ci[:, None] + loc[None, :, 0], (q - 1) * cj[:, None] + loc[None, :, 1],
         (q - 1) * ck[:, None] + loc[None, :, 2]), tuple((q - 1) * n + 1))  # (cells, nodes per cell)
    used, node = np.unique(gnode, return_inverse=True)
    node = node.reshape(gnode.shape)
    ndof = 3 * len(used)
    nd = 3 * len(loc)
    # Assemble by node pairs (3x3 blocks): each cell adds q^6 blocks; equal node pairs
    # are summed after one sort of their keys, shared by K and M, in chunks (a 27-node
    # cell has 81^2 entries: all cells at once need not fit).
    nn = len(used)
    chunk = max(1, int(4e6 // nd**2))
    keys, kb, mb = [], [], []
    for s0 in range(0, len(active), chunk):
        nd_c = node[s0:s0 + chunk]
        key = (nd_c[:, :, None].astype(np.int64) * nn + nd_c[:, None, :]).ravel()
        mc = None if mom is None else mom[s0:s0 + chunk]
        Kc = cell_K(child[s0:s0 + chunk], mc).reshape(-1, 9)
        Mc = cell_M(child[s0:s0 + chunk], mc).reshape(-1, 1)
        key, Kc, Mc = _sum_blocks(key, Kc, Mc)
        keys.append(key)
        kb.append(Kc)
        mb.append(Mc)
    if len(keys) == 1:  # one chunk: its keys are unique already
        key, Kb, Mb = keys[0], kb[0], mb[0]
    else:
        key, Kb, Mb = _sum_blocks(np.concatenate(keys), np.concatenate(kb), np.concatenate(mb))
    indptr, bcol = _block_pattern(key, nn)
    K = sp.bsr_matrix((Kb.reshape(-1, 3, 3), bcol, indptr), shape=(ndof, ndof)).tocsr()
    M_node = sp.csr_matrix((Mb[:, 0], bcol, indptr), shape=(nn, nn))
    M = kron_identity3(M_node)

    interp = _point_interpolation(points, lo, n, hc, active, node, q, embed)
    info = {
        "element": ("hex20" if embed is not None else "hex27") if order == 2 else ("hex8-incompatible" if incompatible else "hex8"),
        "h": hc.tolist(),
        "grid": n.tolist(),
        "refine": r,
        "supersample": int(supersample),
        "voxel_moments": moments,
        "n_elements": int(len(active)),
        "n_nodes": int(len(used)),
        "fill_fraction": float(fill[active].mean()),
    }
    return Discretization(K=K, M=M, interp=interp, n_rigid=6, info=info, node_mass=M_node)


def _sum_blocks(key, *data):
    """Sort by ``key`` and sum the rows of each array in ``data`` over equal keys."""
    order = np.argsort(key, kind="stable")
    key = key[order]
    first = np.r_[True, key[1:] != key[:-1]]
    group = np.cumsum(first) - 1
    ng = int(group[-1]) + 1 if len(group) else 0
    return (key[first],) + tuple(_segment_sum(np.ascontiguousarray(d), order, group, ng) for d in data)


def _block_pattern(key, n_nodes: int):
    """Block-sparse pattern ``(indptr (n_nodes + 1,), block columns)`` of the sorted unique
    node-pair keys ``row n_nodes + col`` that :func:`_sum_blocks` returns."""
    brow = key // n_nodes
    return np.searchsorted(brow, np.arange(n_nodes + 1)), (key - brow * n_nodes).astype(np.int32)


@nb.njit(cache=True, nogil=True)
def _segment_sum_kernel(d, order, group, out):
    for p in range(order.shape[0]):
        src = order[p]
        g = group[p]
        for c in range(d.shape[1]):
            out[g, c] += d[src, c]


def _segment_sum(d, order, group, ng):
    out = np.zeros((ng, d.shape[1]))
    _segment_sum_kernel(d, order, group, out)
    return out


def _point_interpolation(points, lo, n, hc, active, node, q=2, embed=None):
    """Interpolation (3p, ndof) of each point from its (nearest active) cell's q^3 nodes."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, float).reshape(-1, 3)
    cell_idx = np.floor((pts - lo) / hc).astype(int)
    cell_idx = np.clip(cell_idx, 0, n - 1)
    flat = np.ravel_multi_index(tuple(cell_idx.T), tuple(n))
    pos = np.searchsorted(active, flat)
    pos = np.clip(pos, 0, len(active) - 1)
    ok = active[pos] == flat
    if not ok.all():
        # point in an empty cell: use the nearest active cell, clamping the coordinates
        centres = lo + (np.c_[np.unravel_index(active, tuple(n))] + 0.5) * hc
        _, near = cKDTree(centres).query(pts[~ok])
        pos[~ok] = near
    ijk = np.c_[np.unravel_index(active[pos], tuple(n))]
    u = np.clip((pts - lo) / hc - ijk, 0.0, 1.0)  # (p, 3) local coords in [0,1]
    W = _parent_weights(u, q)  # (p, q^3)
    if embed is not None:
        W = W @ embed
    p, m = W.shape
    # row 3 k + c (point k, component c) holds the m nodes of its cell at columns 3 j + c:
    # built as CSR directly (a cell's nodes are distinct, so there is nothing to sum)
    cols = 3 * node[pos][:, None, :] + np.arange(3)[None, :, None]  # (p, 3, m)
    vals = np.broadcast_to(W[:, None, :], cols.shape)
    ndof = 3 * (node.max() + 1)
    return sp.csr_matrix((vals.ravel(), cols.ravel(), np.arange(0, 3 * p * m + 1, m)), shape=(3 * p, ndof))
