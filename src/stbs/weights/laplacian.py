"""Cotangent Laplacian ``L`` and lumped mass matrix ``M`` of a simplicial mesh.

Both are assembled from the same per-element quantities, vectorised over elements:
for a linear element with corners ``x_0 .. x_k`` (k = 2 for triangles in 2D or 3D,
k = 3 for tetrahedra), edge matrix ``D = [x_1 - x_0, .., x_k - x_0]`` (d x k) and Gram
matrix ``G = D^T D``, the hat-function gradients satisfy
``grad(phi_i) . grad(phi_j) = (B G^-1 B^T)_ij`` with ``B = [-1 .. -1; I_k]``, and the
element stiffness is ``K_e = |e| B G^-1 B^T`` with ``|e| = sqrt(det G) / k!``.
For a triangle this is the familiar ``K_ij = -cot(theta_k) / 2``; for a tetrahedron
``K_ij = -l_kl cot(theta_kl) / 6`` (``theta_kl``: the dihedral angle at the opposite edge).

Sign convention (libigl's ``cotmatrix``): ``L = -sum_e K_e`` is **negative
semi-definite**, with positive off-diagonal entries on well-shaped meshes and rows
summing to zero.

Degenerate elements: an element whose measure is at most ``eps`` times the
``k``-th power of its longest edge (zero area, zero volume, repeated vertices) has no
finite cotangent weights. ``degenerate="raise"`` (the default) names the first such
element; ``degenerate="skip"`` leaves it out of both ``L`` and ``M`` (it has zero
measure, so ``M`` is unchanged; ``L`` loses the unbounded terms, which is exactly
what removing the element from the mesh does).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp

from .. import _checks
from ._deprecate import renamed

__all__ = ["cotmatrix", "massmatrix", "element_measures", "DEGENERATE_EPS", "MASS_TYPES"]

#: Relative measure below which an element counts as degenerate (see module doc).
DEGENERATE_EPS = 1e-12
#: Lumped mass matrix types.
MASS_TYPES: tuple[str, ...] = ("default", "voronoi", "barycentric")
_DEGENERATE = ("raise", "skip")


def _mesh(V, Ele, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate ``V`` (n, d) and elements ``Ele`` (e, 3) or (e, 4) indexing into it."""
    V = _checks.vertices(V)
    Ele = _checks.index_array(name, Ele, ndim=2)
    n, d = V.shape
    if Ele.shape[1] not in (3, 4):
        raise ValueError(f"{name} must have shape (f, 3) for triangles or (t, 4) for "
                         f"tetrahedra, got {Ele.shape}")
    if Ele.shape[1] == 4 and d != 3:
        raise ValueError(f"{name}: tetrahedra need 3D vertices, but V has shape {V.shape}")
    if Ele.size and (Ele.min() < 0 or Ele.max() >= n):
        bad = int(Ele.min()) if Ele.min() < 0 else int(Ele.max())
        raise ValueError(f"{name} must hold vertex indices in 0..{n - 1}, got {bad}")
    return V, Ele


def _element_data(V: np.ndarray, Ele: np.ndarray):
    """Per-element measure, hat-gradient Gram ``B G^-1 B^T`` and degeneracy flags."""
    k = Ele.shape[1] - 1
    X = V[Ele]                                          # (e, k+1, d)
    D = X[:, 1:, :] - X[:, :1, :]                       # (e, k, d), rows are edges
    G = np.einsum("eid,ejd->eij", D, D)                 # (e, k, k)
    if k == 2:
        adj = np.empty_like(G)
        adj[:, 0, 0], adj[:, 1, 1] = G[:, 1, 1], G[:, 0, 0]
        adj[:, 0, 1] = adj[:, 1, 0] = -G[:, 0, 1]
        # |D0 x D1|^2 computed directly is more accurate than the Gram determinant
        # for thin elements; in 2D it is the squared signed area.
        if D.shape[2] == 2:
            cross2 = (D[:, 0, 0] * D[:, 1, 1] - D[:, 0, 1] * D[:, 1, 0]) ** 2
        else:
            cross2 = np.sum(np.cross(D[:, 0], D[:, 1]) ** 2, axis=1)
        det = cross2
        measure = 0.5 * np.sqrt(cross2)
    else:
        vol6 = np.abs(np.einsum("ei,ei->e", D[:, 0], np.cross(D[:, 1], D[:, 2])))
        det = vol6**2
        measure = vol6 / 6.0
        # adjugate of the symmetric 3x3 Gram matrix
        adj = np.empty_like(G)
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            for j in range(3):
                j1, j2 = (j + 1) % 3, (j + 2) % 3
                adj[:, j, i] = G[:, i1, j1] * G[:, i2, j2] - G[:, i1, j2] * G[:, i2, j1]
    # longest edge of each element, for the relative degeneracy test
    pairs = [(a, b) for a in range(k + 1) for b in range(a + 1, k + 1)]
    lmax = np.zeros(Ele.shape[0])
    for a, b in pairs:
        lmax = np.maximum(lmax, np.linalg.norm(X[:, a] - X[:, b], axis=1))
    degenerate = measure <= DEGENERATE_EPS * lmax**k
    safe = np.where(degenerate, 1.0, det)
    Ginv = adj / safe[:, None, None]
    # B G^-1 B^T with B = [-1 .. -1; I]: pad G^-1 with the row/column sums.
    H = np.empty((Ele.shape[0], k + 1, k + 1))
    H[:, 1:, 1:] = Ginv
    H[:, 0, 1:] = -Ginv.sum(axis=1)
    H[:, 1:, 0] = -Ginv.sum(axis=2)
    H[:, 0, 0] = Ginv.sum(axis=(1, 2))
    return measure, H, degenerate


def _handle_degenerate(Ele, degenerate, how: str, name: str) -> np.ndarray:
    _checks.choice("degenerate", how, _DEGENERATE)
    if np.any(degenerate):
        if how == "raise":
            i = int(np.flatnonzero(degenerate)[0])
            kind = "triangle" if Ele.shape[1] == 3 else "tetrahedron"
            raise ValueError(
                f"{name}: {kind} {i} (vertices {Ele[i].tolist()}) is degenerate (zero "
                f"{'area' if Ele.shape[1] == 3 else 'volume'}; {int(degenerate.sum())} such "
                f"elements); fix the mesh or pass degenerate='skip' to leave them out")
    return ~degenerate


@renamed("E", "Ele")
def element_measures(V, Ele) -> np.ndarray:
    """Unsigned areas (triangles) or volumes (tetrahedra) of the elements.

    Parameters
    ----------
    V : (n, d) float
    Ele : (e, 3) or (e, 4) int
        Triangles or tetrahedra (the keyword ``E=`` is deprecated).

    Returns
    -------
    (e,) float64
    """
    V, Ele = _mesh(V, Ele, "Ele")
    return _element_data(V, Ele)[0]


@renamed("E", "Ele")
def cotmatrix(V, Ele, *, degenerate: Literal["raise", "skip"] = "raise") -> sp.csc_array:
    """Cotangent Laplacian (negative semi-definite, as libigl's ``cotmatrix``).

    Parameters
    ----------
    V : (n, d) float
        Vertex positions, d = 2 or 3.
    Ele : (f, 3) int or (t, 4) int
        Triangles (2D, or a surface in 3D) or tetrahedra (3D). The keyword ``E=`` is
        deprecated (``E`` means endpoint weights).
    degenerate : {"raise", "skip"}
        What to do with zero-measure elements (see the module docstring).

    Returns
    -------
    L : (n, n) scipy.sparse.csc_array, float64
        Symmetric, rows sum to zero; ``-L`` is the assembled FEM stiffness matrix.
        Triangles: ``L_ij = (cot a_ij + cot b_ij) / 2``; tetrahedra:
        ``L_ij = sum l_kl cot(theta_kl) / 6`` over the tetrahedra sharing edge ij.

    Raises
    ------
    ValueError
        For bad shapes or indices, or a degenerate element with ``degenerate="raise"``.

    Examples
    --------
    The right triangle (0, 0), (1, 0), (0, 1): the 45-degree corners weigh the legs
    with cot(45) / 2 = 1/2, the right angle weighs the hypotenuse with cot(90) = 0.

    >>> import numpy as np
    >>> V = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> L = cotmatrix(V, np.array([[0, 1, 2]]))
    >>> np.round(L.toarray(), 12) + 0.0
    array([[-1. ,  0.5,  0.5],
           [ 0.5, -0.5,  0. ],
           [ 0.5,  0. , -0.5]])
    """
    V, Ele = _mesh(V, Ele, "Ele")
    measure, H, deg = _element_data(V, Ele)
    keep = _handle_degenerate(Ele, deg, degenerate, "Ele")
    Ele, K = Ele[keep], -(measure[keep, None, None] * H[keep])
    s = Ele.shape[1]
    rows = np.repeat(Ele, s, axis=1).ravel()
    cols = np.tile(Ele, (1, s)).ravel()
    n = V.shape[0]
    L = sp.csc_array((K.ravel(), (rows, cols)), shape=(n, n))
    L.sum_duplicates()
    return L


MassType = Literal["default", "voronoi", "barycentric"]


@renamed("E", "Ele")
def massmatrix(V, Ele, *, type: MassType = "default",
               degenerate: Literal["raise", "skip"] = "raise") -> sp.dia_array:
    """Lumped (diagonal) mass matrix.

    Parameters
    ----------
    V : (n, d) float
    Ele : (f, 3) int or (t, 4) int
        Triangles or tetrahedra (the keyword ``E=`` is deprecated).
    type : {"default", "voronoi", "barycentric"}
        ``"barycentric"``: each element gives a third (triangles) or a quarter
        (tetrahedra) of its measure to each corner. ``"voronoi"`` (triangles only):
        Meyer et al.'s mixed Voronoi area, the Voronoi cell for non-obtuse triangles,
        else half the area to the obtuse corner and a quarter to the others.
        ``"default"`` is libigl's: voronoi for triangles, barycentric for tetrahedra.
    degenerate : {"raise", "skip"}

    Returns
    -------
    M : (n, n) scipy.sparse.dia_array, float64
        Diagonal; entries sum to the mesh's total area or volume. A vertex in no
        element gets mass 0.
    """
    _checks.choice("type", type, MASS_TYPES)
    V, Ele = _mesh(V, Ele, "Ele")
    if type == "default":
        type = "voronoi" if Ele.shape[1] == 3 else "barycentric"
    if type == "voronoi" and Ele.shape[1] != 3:
        raise ValueError("type='voronoi' needs triangles Ele (f, 3); use 'barycentric' for "
                         f"tetrahedra, got Ele with shape {Ele.shape}")
    measure, H, deg = _element_data(V, Ele)
    keep = _handle_degenerate(Ele, deg, degenerate, "Ele")
    Ele, measure, H = Ele[keep], measure[keep], H[keep]
    s = Ele.shape[1]
    if type == "barycentric":
        m = np.repeat(measure[:, None] / s, s, axis=1)
    else:
        # cot(theta_k) / 2 = -K_ij = -measure * H_ij for the corner k opposite edge ij.
        half_cot = -measure[:, None] * np.stack([H[:, 1, 2], H[:, 2, 0], H[:, 0, 1]], axis=1)
        X = V[Ele]
        l2 = np.stack([np.sum((X[:, (i + 1) % 3] - X[:, (i + 2) % 3]) ** 2, axis=1)
                       for i in range(3)], axis=1)     # l2[:, i]: edge opposite corner i
        # Voronoi part of corner i: (|e_ij|^2 cot theta_k + |e_ik|^2 cot theta_j) / 8
        m = np.empty_like(l2)
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            m[:, i] = 0.25 * (l2[:, k] * half_cot[:, k] + l2[:, j] * half_cot[:, j])
        # Obtuse (cot < 0) corners: the circumcentre leaves the triangle.
        obtuse = half_cot < 0
        any_obtuse = obtuse.any(axis=1)
        m[any_obtuse] = np.where(obtuse[any_obtuse], 0.5, 0.25) * measure[any_obtuse, None]
    diag = np.bincount(Ele.ravel(), weights=m.ravel(), minlength=V.shape[0])
    return sp.dia_array((diag[None, :], [0]), shape=(V.shape[0], V.shape[0]))
