"""The hand-off between a discretization (hex, tet, shell) and the eigensolver."""

from __future__ import annotations

from dataclasses import dataclass, field

import scipy.sparse as sp

__all__ = ["Discretization"]


@dataclass
class Discretization:
    """Sparse system of one object, ready for ``K phi = lambda M phi``.

    Attributes
    ----------
    K, M : (n, n) scipy.sparse.csr_matrix
        Symmetric stiffness [N/m] and mass [kg] matrices over the n degrees of freedom.
    interp : (3p, n) scipy.sparse.csr_matrix
        Displacement of the p surface sample points from the dofs, rows ordered
        (x0, y0, z0, x1, ...): ``u_points = interp @ phi``.
    n_rigid : int
        Rigid-body modes expected (6 for a free body, 0 if clamped).
    info : dict
        JSON-able description: element type, element size [m], element count, ...
    dofs_per_node : int
        3 (displacement x, y, z) or 6 (then rotation x, y, z): dof ``k`` of node ``i`` is
        ``dofs_per_node * i + k``, so translations are the dofs with ``k < 3``.
    node_mass : (n/3, n/3) scipy.sparse.csr_matrix or None
        The scalar node mass ``m`` with ``M = kron(m, I3)`` when the discretization built
        ``M`` that way (hex), else None (the eigensolver finds it from ``M``,
        :func:`.node_mass.node_mass`).
    """

    K: sp.csr_matrix
    M: sp.csr_matrix
    interp: sp.csr_matrix
    n_rigid: int = 6
    info: dict = field(default_factory=dict)
    dofs_per_node: int = 3
    node_mass: sp.csr_matrix | None = None

    @property
    def dofs(self) -> int:
        return self.K.shape[0]
