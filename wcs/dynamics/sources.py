"""Point sources of seismic waves (a scene's `sources:` block), the seed's volume forces
"simulated by nonzero volume forces" at a point [101, §2]: a force, or a moment tensor, at a point
x₀, times a Ricker wavelet in time.

    sources: {quake: {point: [x, y], force: [fx, fy], wavelet: {ricker: {frequency: f, delay: t0}}}}
    sources: {quake: {point: [x, y], moment: [[mxx, mxy], [myx, myy]], wavelet: ...}}

The load vector at time t is r(t) f with f the nodal loads below (dof = d·node + component):

- a point force F: f_a = F φ_a(x₀), the P1 shape functions of the cell containing x₀ (the
  Dirac δ(x − x₀) F tested with φ_a). Σ_a f_a = F and Σ_a x_a ⊗ f_a = x₀ ⊗ F, exactly.
- a moment tensor M: the equivalent body force f = −M·∇δ(x − x₀) (Aki & Richards,
  Quantitative Seismology, 2002, §3.3) tested with φ_a gives f_a = +M ∇φ_a(x₀), i.e.
  f_{a,i} = M_ij ∂_j φ_a(x₀) (Komatitsch & Tromp 1999, GJI 139: the source term M : ∇w(x_s)).
  Σ_a f_a = 0 (no resultant) and Σ_a f_a ⊗ x_a = M exactly (P1 reproduces x): an isotropic
  M = M₀ I with M₀ > 0 pushes outward (an explosion); the torque of the forces is the
  antisymmetric part of M (2D: M_yx − M_xy), zero for a symmetric (seismic) moment tensor.
  ∇φ_a jumps across cells: a point on a cell face takes the mean of the cells that hold it.

A point outside the mesh (or in a hole), or on the interface of two bodies (their nodes are
distinct: whose is the force?), is a StudyError naming the source.
"""
from __future__ import annotations

import numpy as np

from ..errors import StudyError
from ..fem.affine import gradients
from ..scene.spec import Source, ricker

INSIDE = 1e-10                          # a barycentric coordinate >= -INSIDE: the point is in the (closed) cell


def wavelet(source: Source, t) -> np.ndarray:
    """The source's time factor at the times t."""
    w = source.wavelet.ricker
    return ricker(t, w.frequency, w.delay)


def containing_cells(p: np.ndarray, t: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells (closed simplices, columns of t) holding the point x0, and the point's barycentric
    coordinates in each ((k, d+1): the P1 shape function values φ_a(x0) at the cell's nodes)."""
    near = np.arange(t.shape[1])
    for i in range(p.shape[0]):                                   # the cells whose box holds x0, by coordinate
        x = p[i, t[:, near]]
        lo, hi = x.min(axis=0), x.max(axis=0)
        pad = INSIDE * (hi - lo)
        near = near[(lo - pad <= x0[i]) & (x0[i] <= hi + pad)]
    Xn = p[:, t[:, near]]                                         # (d, d+1, k)
    J = np.moveaxis(Xn[:, 1:] - Xn[:, :1], -1, 0)                 # (k, d, d): columns x_a - x_0
    lam = np.linalg.solve(J, (x0[:, None] - Xn[:, 0]).T[..., None])[..., 0]
    bary = np.hstack([1.0 - lam.sum(axis=1, keepdims=True), lam])
    inside = bary.min(axis=1) >= -INSIDE
    return near[inside], bary[inside]


def point_force_vector(p, t, cells, bary, force) -> np.ndarray:
    """(d nnodes,) f_a = F φ_a(x0), the mean over the holding cells (φ is continuous: they agree)."""
    d = p.shape[0]
    f = np.zeros(d * p.shape[1])
    for c, phi in zip(cells, bary):
        np.add.at(f, (d * t[:, c][:, None] + np.arange(d)).ravel(), np.outer(phi, force).ravel() / len(cells))
    return f


def moment_tensor_vector(p, t, cells, moment) -> np.ndarray:
    """(d nnodes,) f_a = M ∇φ_a(x0), the mean over the holding cells (∇φ jumps between them)."""
    d = p.shape[0]
    grad, _ = gradients(p, t[:, cells])                           # (k, d+1, d): ∇φ_a per cell
    f = np.zeros(d * p.shape[1])
    M = np.asarray(moment, dtype=float)
    for c, g in zip(cells, grad):
        np.add.at(f, (d * t[:, c][:, None] + np.arange(d)).ravel(), (g @ M.T).ravel() / len(cells))
    return f


def source_vector(sm, source: Source, path: str) -> np.ndarray:
    """(d nnodes,) the nodal loads of a source (peak value; times `wavelet(source, t)` in time) on
    the meshed scene `sm`; StudyError at `path` (e.g. `scene.sources.quake`) when its point has
    the wrong dimension, lies outside the mesh or on the interface of two bodies."""
    p, t = sm.mesh.p, sm.mesh.t
    d = p.shape[0]
    x0 = np.asarray(source.point, dtype=float)
    if x0.size != d:
        raise StudyError(f"the point has {x0.size} coordinates, the scene is {d}D", path=f"{path}.point")
    cells, bary = containing_cells(p, t, x0)
    if cells.size == 0:
        box = ", ".join(f"[{a:g}, {b:g}]" for a, b in zip(p.min(axis=1), p.max(axis=1)))
        raise StudyError(f"the point {source.point} lies outside the mesh (in no cell; the mesh spans {box})",
                         path=f"{path}.point")
    bodies = np.unique(sm.cell_body[cells])
    if bodies.size > 1:
        names = " and ".join(sm.bodies[b] for b in bodies)
        raise StudyError(f"the point {source.point} lies on the interface of bodies {names}: move it into one body",
                         path=f"{path}.point")
    if source.force is not None:
        return point_force_vector(p, t, cells, bary, np.asarray(source.force, dtype=float))
    return moment_tensor_vector(p, t, cells, source.moment)
