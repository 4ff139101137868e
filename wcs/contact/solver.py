r"""Node-to-node contact with Tresca or Coulomb friction: condensed semismooth Newton.

Problem (Dirichlet conditions already eliminated)::

    minimise  ½ uᵀKu − fᵀu + Σ_i w_i g_i |(Bt u)_i|   subject to  Bn u ≤ d.

Sign conventions. Multipliers λ = (λn, λt) enter the equilibrium as

    K u + Bnᵀ λn + Btᵀ λt = f,

so λn ≥ 0 is the nodal force pressing the bodies apart, λn ⊥ (d − Bn u) ≥ 0,
and λt is the subgradient of the friction energy: |λt_i| ≤ g_i w_i, and
λt_i = +g_i w_i sign((Bt u)_i) where the node slips ((Bt u)_i ≠ 0). The
friction force acting on the slipping body is −Btᵀλt, i.e. it opposes the
slip. Pressure p = λn / w, shear τ = λt / w.

Method. With a generalized inverse K⁺ and C = [Bn; Bt], u = K⁺(f − Cᵀλ) + Rα,
so the contact displacements are affine in (λ, α):

    r(λ, α) = C u − [d; 0] = q − Wλ + Gᵀα,   W = C K⁺ Cᵀ,  q = C K⁺ f − [d; 0],  Gᵀ = C R,

with the equilibrium of the rigid modes G λ = e, e = Rᵀ f. The conditions of
Hüeber–Stadler–Wohlmuth, C_n = λn − max(0, λn + c_n r_n) = 0 and
C_t = max(gw, |λt + c_t r_t|) λt − gw (λt + c_t r_t) = 0, are the projection
equations

    Φ(λ, α) = λ − Π_B(λ + c ⊙ r(λ, α)) = 0,   B = {λn ≥ 0, |λt,i| ≤ gw_i},

i.e. the optimality conditions of the dual QP min ½λᵀWλ − qᵀλ over B with
Gλ = e. Dimension d: each node has d − 1 tangent rows; Bt stacks them by
component (row j·m + i is tangent j of node i), and |λt,i| is the 2-norm of
node i's d − 1 components, so B is a box in 2D and a product of discs in 3D
(the dual problem is then a second-order-cone program). Semismooth Newton on Φ
is the primal–dual active set method: components with λ + c r inside B are
free (contact closed / stick: r_i = 0), the others are held at their
projection (open: λn = 0; slip: λt = gw z/|z|, z = λt + c r_t). In 2D the
projection onto the interval is piecewise constant (λt = ±gw); on a disc it
is not, and a slipping node's row is the linearization with the generalized
Jacobian of the disc projection, D = gw/|z| (I − z zᵀ/|z|²) (Hüeber, Stadler,
Wohlmuth, SIAM J. Sci. Comput. 30 (2008), the 3D semismooth Newton). Full
steps where the pattern determines the step (no slip on a disc), and an active
pattern seen before there is a cycle, after which every step is shortened until
the merit ‖Φ‖² decreases (Armijo), as a step with nodes slipping on discs always
is. `max_iter` restarts Newton from the dual QP's solution (`_newton`). The constants
c = 1 / diag(W) (for the tangents of a node the mean of its d − 1 diagonal
entries, one c per disc) turn displacements into forces node by node.

The Delassus operator W is, in 3D, minus the Schur complement of the bordered
matrix [[K⁺⁻¹, Cᵀ], [C, 0]] on its contact rows, which PARDISO returns during the
numeric factorization of that matrix, whose leading block is then a factor of
K⁺⁻¹ for the solves; in 2D it is C_S (K⁺)_SS C_Sᵀ from the inverse of the Schur
complement of K⁺⁻¹ on the contact DOFs S (see `wcs.linalg`, `factor_contact`). A
re-solve on the same pattern costs a numeric refactor, two solves and the dense
algebra of the contact rows.

Floating bodies (R given, KR = 0): K⁺ = (K + Σ_{j∈P} k_j e_j e_jᵀ)⁻¹ with P
a set of r DOFs on which R is nonsingular (pivoted QR of Rᵀ). It is an exact
generalized inverse, K K⁺ K = K: for b = Kx, x' = K⁺b satisfies
K x' + D x' = b, hence R_Pᵀ D_P x'_P = Rᵀ b = 0, x'_P = 0 and K x' = b; the
spring sizes k_j only set the conditioning, not the answer.

Over 500 lines for one method: the condensed semismooth Newton, the factorization of its condensed
system, the projections onto the friction sets, the step control and the certificate all work on the
same W, q, G and free set; split, they would pass those between modules.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from wcs import linalg
from wcs.contact.problem import ContactProblem
from wcs.contact.solvability import CLARABEL_TIGHT, rigid_load, unbalanced
from wcs.status import Status

OPEN, STICK, SLIP = 0, 1, 2


@dataclass
class ContactResult:
    """Solution and diagnostics. `active`: per node OPEN (0), STICK (1) or SLIP (2)."""

    u: np.ndarray | None
    lam_n: np.ndarray | None
    lam_t: np.ndarray | None
    status: Status
    message: str
    iterations: int = 0
    fixed_point_iterations: int = 0
    active: np.ndarray | None = None
    factor: "ContactFactor | None" = None
    alpha: np.ndarray | None = None  # rigid amplitudes; for UNSOLVABLE the unbalanced direction
    timings: dict = field(default_factory=dict)
    free: np.ndarray | None = None   # (d·m,) final Newton free set: closed normals, stuck tangents
    gw: np.ndarray | None = None     # (m,) final slip bounds g·w (+ F·λn for Coulomb)
    krylov_iterations: int = 0       # iterative method: Krylov iterations over all its Newton steps
    krylov_steps: tuple = ()         # iterative method: the Krylov iterations of each Newton step, in order


@dataclass
class ContactFactor:
    """A factor of K (or its regularization) and the Delassus operator W of the matrix it holds.

    Changed only by `update`, in place. `K_data` is the matrix the factor holds now: it is
    cleared before a refactor and set once the factor and W are complete, so a refactor that
    fails halfway (or is interrupted) leaves a record that matches no matrix, and a cache
    hit is decided by what the factor holds, never by a copy that can go stale."""

    factor: object
    pinned: np.ndarray  # DOFs regularized for the rigid modes (empty without R)
    S: np.ndarray       # contact DOFs (columns of C)
    C_S: np.ndarray | sp.csr_matrix  # C on those DOFs: sparse (bordered factor) or dense (`inverse_block`)
    W: np.ndarray | None = None
    K_data: np.ndarray | None = None  # values (on K's fixed pattern) of the factored matrix

    def holds(self, Kr: sp.csr_matrix, C_S) -> bool:
        return (self.K_data is not None and np.array_equal(self.K_data, Kr.data)
                and _same(self.C_S, C_S))

    def update(self, Kr: sp.csr_matrix, C: sp.csr_matrix) -> "ContactFactor":
        C_S = C[:, self.S] if _bordered(self.factor) else C[:, self.S].toarray()
        if not self.holds(Kr, C_S):
            self.K_data = None
            if _bordered(self.factor):
                self.factor.refactor(Kr, border=C)
            else:
                self.factor.refactor(Kr)
            self.C_S, self.W = C_S, delassus(self.factor, C_S)
            self.K_data = Kr.data.copy()
        return self


def _same(A, B) -> bool:
    """A = B entry by entry (both sparse, or both dense)."""
    if sp.issparse(A):
        return sp.issparse(B) and A.shape == B.shape and (A != B).nnz == 0
    return np.array_equal(A, B)


def _bordered(factor) -> bool:
    """A factor of the bordered matrix [[K, Cᵀ], [C, 0]] (`linalg.factorize(..., border=C)`)."""
    return getattr(factor, "border", None) is not None


def pinned_dofs(R: np.ndarray) -> np.ndarray:
    """r DOFs on which the rows of R form a well-conditioned r×r block (pivoted QR of Rᵀ)."""
    _, _, piv = sla.qr(R.T, mode="economic", pivoting=True)
    return np.sort(piv[: R.shape[1]])


def regularize(K: sp.spmatrix, pinned: np.ndarray) -> sp.csr_matrix:
    """K + Σ_{j∈pinned} K_jj e_j e_jᵀ on K's own pattern (added in place on the diagonal: a
    sparse sum would drop entries that happen to be zero and change the pattern — and with it
    the factorization's ordering — from one data set to the next). Its inverse is a
    generalized inverse of K."""
    K = sp.csr_matrix(K, dtype=float, copy=True)
    K.sum_duplicates()
    K.sort_indices()
    if len(pinned):
        where = np.zeros(len(pinned), dtype=int)
        for n, j in enumerate(pinned):            # the diagonal entry in row j's sorted columns
            a, b = K.indptr[j], K.indptr[j + 1]
            where[n] = a + np.searchsorted(K.indices[a:b], j)
            if where[n] == b or K.indices[where[n]] != j:
                raise ValueError("a pinned dof has no diagonal entry in K")
        K.data[where] += np.where(K.data[where] > 0, K.data[where], 1.0)
    return K


def delassus(factor, C_S) -> np.ndarray:
    """W = C K⁺ Cᵀ: from a factor of the bordered matrix, minus its Schur complement on the
    contact rows (`linalg`, border = C); from a factor with the dense inverse block (K⁺)_SS
    on the contact DOFs S, C_S (K⁺)_SS C_Sᵀ."""
    if _bordered(factor):
        return factor.delassus()
    Z = factor.inverse_block()
    W = C_S @ Z @ C_S.T
    return 0.5 * (W + W.T)


def factor_contact(K, C: sp.csr_matrix, R, reuse: ContactFactor | None, bordered: bool = True) -> ContactFactor:
    """Factor K (regularized when R is given) for W; `reuse` (same contact DOFs and pinned DOFs)
    is updated in place, keeping its analysis and its kind.

    bordered: K bordered by the contact rows C (W from the Schur complement on them); else K
    with the dense inverse block (K⁺)_SS on the contact DOFs S (W = C_S (K⁺)_SS C_Sᵀ). In 3D
    |S| ≈ 2 (1 + k) m is large (the tunnel at 9.3e4 unknowns: |S| ≈ 17000, 830 s and 11.9 GB
    a solve, mostly the dense inverse and the triple product); 2D keeps the block: its zones
    are small (2D Hertz at 1.2e5 unknowns, 446 rows: both 2.3 s) and its results are pinned to
    the bit (the bordered W moves them by up to 3e-12, enough to turn near-tied searches)."""
    pinned = pinned_dofs(R) if R is not None else np.zeros(0, dtype=int)
    return factor_regularized(regularize(K, pinned), C, pinned, reuse, bordered)


def factor_regularized(Kr: sp.csr_matrix, C: sp.csr_matrix, pinned: np.ndarray, reuse: ContactFactor | None,
                       bordered: bool = True) -> ContactFactor:
    """`factor_contact` of a K already regularized on the DOFs `pinned` (`regularize`)."""
    S = np.unique(C.indices)
    if reuse is not None and np.array_equal(reuse.S, S) and np.array_equal(reuse.pinned, pinned):
        return reuse.update(Kr, C)
    if bordered:
        f = linalg.factorize(Kr, spd=True, border=C)
        return ContactFactor(f, pinned, S, C[:, S], f.delassus(), Kr.data.copy())
    f = linalg.factorize(Kr, spd=True, block=S)
    C_S = C[:, S].toarray()
    return ContactFactor(f, pinned, S, C_S, delassus(f, C_S), Kr.data.copy())


def free_rigid_motion(G: np.ndarray, held: np.ndarray) -> np.ndarray | None:
    """A rigid motion that the active constraints leave free at a solution: β ≠ 0 with
    (C R)_H β = 0 on the rows H that hold (closed or touching normals, stuck tangents with a
    positive slip bound), normalised to max|β| = 1; None when (C R)_H has full column rank.

    Along such a β, u + tRβ is a solution too for small t: open nodes stay open, slipping
    nodes keep their sign (a frictionless tangent never holds), and the energy does not
    change, since the equilibrium of the rigid modes Rᵀ(f − Cᵀλ) = 0 makes the load's work
    equal the friction's. Touching normals without pressure (a body resting under no load)
    count as holding: lifting off is then free too, but the position along the contact is
    determined, and only a motion that keeps every touching node touching is reported.
    The columns of C R are scaled to unit norm over all contact rows; a singular value
    below 1e-8 of the largest counts as zero (a determined direction, e.g. a curved contact
    side, gives at least the sine of the angle between its normals)."""
    r = G.shape[0]
    if r == 0:
        return None
    scale = np.maximum(np.linalg.norm(G, axis=1), 1e-300)
    A = G[:, held].T / scale
    # V of A's SVD, not U: a thin one (the full U of the ~5000 held rows cost 85 ms a solve)
    sv, vt = (np.linalg.svd(A, full_matrices=A.shape[0] < r)[1:] if A.shape[0] else (np.zeros(0), np.eye(r)))
    rank = int(np.sum(sv > 1e-8 * sv[0])) if sv.size and sv[0] > 0 else 0
    if rank == r:
        return None
    beta = vt[rank] / scale
    return beta / beta[np.argmax(np.abs(beta))]


def project(z, lo, hi, k=1):
    """Π_B(z): the normals clipped at lo = 0, each node's k tangent components (rows j·m + i)
    onto the disc of radius hi (the same on a node's components). For k = 1 this is the clip
    onto [−gw, gw] to the bit: the norm of one component is its absolute value and z/|z| = ±1."""
    out = np.clip(z, lo, hi)
    m = len(z) // (1 + k)
    if k == 1:              # r ν = ±r where |z| (as the norm below takes it) passes r, else z: the same bits
        t, r = z[m:], hi[m:]
        out[m:] = np.where(np.sqrt(t * t) > r, np.copysign(r, t), t)
        return out
    t, r = z[m:].reshape(k, m), hi[m:m + m]
    norm = np.linalg.norm(t, axis=0)
    slip = norm > r
    nu = np.divide(t, norm, out=np.zeros_like(t), where=slip)
    out[m:] = np.where(slip, np.where(slip, r, 0.0) * nu, t).ravel()
    return out


def inside(z, lo, hi, k=1):
    """Components whose z lies inside B (the free set): z_n > 0, |z_t,i| < gw_i on each of the
    node's k tangent components."""
    m = len(z) // (1 + k)
    return np.concatenate([(z[:m] > lo[:m]) & (z[:m] < hi[:m]),
                           np.tile(np.linalg.norm(z[m:].reshape(k, m), axis=0) < hi[m:m + m], k)])


def disc_slips(z, hi, k):
    """Slipping nodes on a disc (k ≥ 2, |z_t,i| > gw_i > 0): their component indices (n, k) and
    the generalized Jacobian of the projection there, D = gw/|z| (I − ννᵀ), ν = z/|z| (n, k, k)."""
    if k == 1:              # no disc
        return np.zeros((0, 1), dtype=int), np.zeros((0, 1, 1))
    m = len(z) // (1 + k)
    t, r = z[m:].reshape(k, m), hi[m:m + m]
    norm = np.linalg.norm(t, axis=0)
    nodes = np.flatnonzero((norm > r) & (r > 0))
    nu = (t[:, nodes] / norm[nodes]).T
    D = (r[nodes] / norm[nodes])[:, None, None] * (np.eye(k) - nu[:, :, None] * nu[:, None, :])
    return m + nodes[:, None] + m * np.arange(k), D


def _across_slip(G, lam_t, free, k):
    """On a disc a slipping node holds the motion across its slip: the friction energy
    gw|s + tδ| is linear in t only for δ ∥ s, so a rigid motion changing the slip direction is
    no free motion. The rows ν⊥ᵀ(C R)_t of each node, ν = λt/|λt| (zero rows where the node
    sticks or opens); (r, m) for the two tangents of 3D, (r, 0) for k = 1."""
    m = len(lam_t) // k
    if k == 1:
        return np.zeros((G.shape[0], 0))
    t = lam_t.reshape(2, m)
    norm = np.linalg.norm(t, axis=0)
    slip = (~free[m:m + m]) & (norm > 0)
    nu = np.divide(t, norm, out=np.zeros_like(t), where=slip)
    return G[:, 2 * m:3 * m] * nu[0] - G[:, m:2 * m] * nu[1]


NULL_ROW = 1e-20     # W_ii below this share of the largest: a row of round-off (‖row‖ ~ 1e-10 relative)


def null_rows(W) -> np.ndarray:
    """The contact rows that act on nothing but round-off: W_ii ≤ NULL_ROW · max W_jj. (A 3D
    fault node held by supports on both sides keeps components ~1e-17 of its normal and
    tangents after the elimination: W_ii ~ 1e-41 against 1e-9, and c = 1/W_ii ~ 1e40 would
    swamp Newton's scaled residual.) Such a row is solved as an exactly null one (a node held
    on both sides in 2D): its λ is the least-squares zero and its gap is what the supports leave."""
    dW = np.diag(W)
    return dW <= NULL_ROW * max(dW.max(initial=0.0), 1e-300)


def scales(W, k=1):
    """c = 1 / diag(W), one c per disc (`disc_scales`; the rows that act: not `null_rows`)."""
    return disc_scales(np.diag(W), ~null_rows(W), k)


def disc_scales(dW, acting, k):
    """c = 1 / dW (dW: diag(W) or an estimate of it), on a node's k tangents 1 / the mean dW of
    those that act (one c per disc), and c = 1 on a row that does not act (its rows carry
    nothing). A tangent held by supports (a row of round-off, dW ≈ 0) is left out of the mean:
    in it, it halved dW and doubled the node's c, so that on the 3D tunnel at 3.9e4 unknowns the
    nodes on the rollers front and back predicted their slip reversed, then stuck at 2–7 g w,
    then slipped again (24 Newton steps of the iterative method on a data set of the box; 14
    without). A normal of round-off kept as c = 1/dW ~ 4e39 turned its gap's round-off (1e-21)
    into z_n ~ 1e18 and ‖Φ‖ with it, and the iterative Newton never stopped (a corner of the same
    tunnel, 200 steps)."""
    m = len(dW) // (1 + k)
    dW = np.where(acting, dW, 0.0)
    on = acting[m:].reshape(k, m)
    dW[m:] = np.tile(np.sum(dW[m:].reshape(k, m) * on, axis=0) / np.maximum(on.sum(axis=0), 1), k)
    return 1.0 / np.where(dW > 0, dW, 1.0)


def _newton(W, q, G, e, lo, hi, lam, alpha, tol, max_iter, free0=None, fallback=True, k=1):
    """Semismooth Newton (PDAS) for Φ(λ, α) = λ − Π_B(λ + c ⊙ r) = 0, Gλ = e.

    Each step solves the active-set system of the predicted free set exactly, so the
    iteration ends when a free set reproduces itself. In 2D a step is determined by its
    free set and the bound each other component is held at (λn = 0; λt = −gw or +gw), so
    that pattern seen before without convergence means a cycle (the free set alone is
    not: the same free set with a slip of the other sign is another step — counted as a
    cycle, it sent 14 % of granite's solves to the QP); such steps are full. On a disc
    (k = 2 tangent components) a slipping node's step depends on its slip direction too,
    and a pattern repeats while Newton converges, so no cycle is counted while a node
    slips on a disc; there the step is shortened until ‖Φ‖² + ‖Gλ − e‖² decreases
    (`_step_length`). Full steps cycled on the 3D tunnel at 3.9e4 unknowns with a slip
    limit varying over the fault: a dozen nodes flipping between stick at |λt| ≈ 13 gw and
    slip with their direction reversed, period 2, in 5 of 16 data sets to `max_iter`. From a
    cycle of full steps on, every step is shortened so: full steps cycled, period 2, on the 2D
    knee's femur, a floating body held sideways only by the 2 of its 140 contact nodes that
    stick at the bottom of the dishes — with every closed node slipping, its sideways balance
    rests on the normals' small lateral components alone and the step slid it by ±1–2 mm
    (10⁴ times the answer's), turning every slip the other way; the step is a descent
    direction of the merit on its own pattern (Φ + Φ′δ = 0 there), so the shortened steps end
    at the answer. At `max_iter` the convex dual QP min ½λᵀWλ − qᵀλ over B with Gλ = e is
    solved by an interior-point method and Newton restarts from it to polish the answer to
    `tol`. The prescribed first step (`free0`) is not a Newton step of Φ and is taken in
    full: shortened, it left the rigid amplitudes α of floating bodies at zero and the next
    prediction opened every contact.

    free0: the free set of the first step instead of the one predicted from λ
    (the cold start: all closed and stuck, i.e. the glued problem).
    k: tangent components per node (d − 1); lo, hi: the bounds of B per component.
    The stopping test is relative to the force scale max |Π_B(c q)| over the components B leaves
    room for (lo < hi), or to max|λ|: a normal row's open gap (c q < 0) carries no force (the
    M-projection of the stabilized Newmark predictor at h = 0.2 mm, Δt = 1 µs: a node 2.2 cm up
    the cylinder's arc made the scale 1.8e-3, and Newton stopped at λ = 0 with the first node
    1 µm into the block, c q = 1.4e-11); a Tresca tangent carries at most its bound g w
    (a base slid rigidly by 1000 m under a Tresca pad made its c q 5e13 against normal forces of
    7e5, and Newton stopped after 2 steps with the normals wrong); a frictionless tangent's c q is a displacement times
    a stiffness that no multiplier carries (a 3 m support translation on 3D Hertz made it
    2e4 times the normals' c q, and Newton stopped one step early at λn = −2.4e5). The
    iterate must also lie in B to tol × max|λ|: 1/W_ii ignores how the nodes share a load, so
    on a large fault c q is ~100 times the multipliers (the oblique 3D tunnel: 5.8e9 against
    4.7e7, growing as the mesh is refined; a warm Tresca shear patch at 9.6e4 unknowns: 8e5
    against 789), and a slipping node's Newton point has |λt| = √(gw² + a²) with its
    component a across the slip, which vanishes only in the limit: Newton stopped where |λt|
    still passed g w by 62 (1.3e-6 of max|λ|; 3.2e-3 on the patch), answers the certificate
    of `conditions_violated` refused.
    Returns (λ, α, free, iterations, converged).
    """
    c = scales(W, k)
    redundant = redundant_pairs(W, k)
    acting = np.any(W, axis=1)
    carried = hi > lo        # B degenerate (lo = hi: a frictionless tangent) carries no force
    carries = np.abs(np.clip(c * q, lo, hi))   # no more than B lets through: an open gap (c q < 0 ≤ λn) none
    force = max(carries[carried].max(initial=0.0), np.abs(e).max(initial=0.0), 1e-300)

    def residual(lam, alpha):
        z = lam + c * (q - W @ lam + G.T @ alpha)
        return z, lam - project(z, lo, hi, k), G @ lam - e

    def in_b(lam):          # λ in B to tol·max|λ|
        return np.abs(lam - project(lam, lo, hi, k)).max(initial=0.0) <= tol * np.abs(lam).max(initial=0.0)

    seen, damped = set(), False
    for it in range(max_iter + 1):
        z, phi, eq = residual(lam, alpha)
        scale = max(force, np.abs(lam).max(initial=0.0))
        ok = max(np.abs(phi).max(initial=0.0), np.abs(eq).max(initial=0.0)) <= tol * scale and in_b(lam)
        predicted = inside(z, lo, hi, k)
        if ok:          # the state of the answer itself, never the prescribed starting set
            return lam, alpha, predicted, it, True
        free = predicted if (it > 0 or free0 is None) else free0
        J, D = disc_slips(z, hi, k)
        slips = ~free[J[:, 0]]                                   # not stuck by the prescribed set
        J, D = J[slips], D[slips]
        key = np.where(free | ~carried, 0, np.where(z >= hi, 1, -1)).astype(np.int8).tobytes()   # frictionless: no sign
        if it == max_iter:
            break
        damped = damped or (key in seen and not len(J))     # full steps cycled: shortened from here on
        if free is predicted:   # the prescribed first set holds the others at warm values, not bounds
            seen.add(key)
        step = _newton_point(W, q, G, e, free, project(z, lo, hi, k), redundant, (J, D), c, acting)
        lam, alpha = (_step_length(residual, lam, alpha, *step, phi @ phi + eq @ eq)
                      if (len(J) or damped) and free is predicted else step)
    if not fallback:
        return lam, alpha, free, it, False
    qp = _dual_qp(W, q, G, e, lo, hi, force, k)
    if qp is None:
        return lam, alpha, free, it, False
    # the QP's λ projected onto B, as every start is: an interior-point answer lies outside B by
    # round-off, and at a body resting without load (λ ≈ 1e-9 of the force scale, the 3D Tresca patch
    # unloaded) that is more than tol × max|λ| (`in_b`), so its polish never stopped
    lam2, alpha2, free2, n, ok = _newton(W, q, G, e, lo, hi, project(qp[0], lo, hi, k), qp[1], tol, max_iter,
                                         fallback=False, k=k)
    return lam2, alpha2, free2, it + n, ok


ARMIJO = 1e-4          # sufficient decrease of the merit θ = ‖Φ‖² + ‖Gλ − e‖², per unit of step length
MIN_STEP = 2.0 ** -10  # the shortest step tried before the full one is taken


def _step_length(residual, lam, alpha, lam1, alpha1, merit):
    """The Newton step (λ, α) → (λ1, α1) shortened by halving until the merit θ = ‖Φ‖² + ‖Gλ − e‖²
    decreases enough, θ(t) ≤ (1 − 2 ARMIJO t) θ(0) (Armijo); the full step where none down to
    `MIN_STEP` does. Φ is smooth on the pattern the step was computed on and the step solves
    Φ + Φ′ δ = 0 there, so dθ/dt = −2θ at t = 0: a descent direction (the semismooth Newton
    method globalized on the natural merit function)."""
    t, lt, at = 1.0, lam1, alpha1
    while True:
        _, phi, eq = residual(lt, at)
        if phi @ phi + eq @ eq <= (1.0 - 2.0 * ARMIJO * t) * merit:
            return lt, at
        if t <= MIN_STEP:
            return lam1, alpha1
        t *= 0.5
        lt, at = lam + t * (lam1 - lam), alpha + t * (alpha1 - alpha)


def _dual_qp(W, q, G, e, lo, hi, force, k=1):
    """The condensed dual problem as a dense convex QP (Clarabel): (λ, α), or None. With discs
    (k = 2) the tangential bounds are second-order cones |λt,i| ≤ gw_i: an SOCP.

    Scaled to O(1) data: λ = s μ with the force scale s, objective divided by s²·max|W|.
    The equality's dual y (∇f + Gᵀy = 0 in the scaled problem) gives α = −s·max|W|·y
    (the solver's convention Wλ − q = Gᵀα on free components). Tolerances 1e-12: at
    Clarabel's default 1e-8 the multipliers of the knee (stiffness contrast 600) were off by
    1e-5 of the force scale, and Newton restarted from there cycled again. Clarabel is called
    directly (as the solvability LP): through cvxpy the restart cost its import, 0.6 s of CPU
    the first time in a process, and ~25 % more a call (0.055 s against 0.044 s on the pad
    at 8.6e4 unknowns, 244 rows)."""
    import clarabel
    n, s, wmax = W.shape[0], force, np.abs(W).max()
    m = n // (1 + k)
    r = G.shape[0]
    box = n if k == 1 else m                 # the components bounded one by one
    flo, fhi = np.flatnonzero(np.isfinite(lo[:box])), np.flatnonzero(np.isfinite(hi[:box]))
    discs = np.flatnonzero(np.isfinite(hi[m:m + m])) if k > 1 else np.zeros(0, dtype=int)
    # A x + z = b with z in the cones: G μ = e/s; −μ ≤ −lo/s, μ ≤ hi/s; (gw/s, μt of the disc) ∈ SOC
    rows = [sp.csr_matrix(G), -sp.eye(n, format="csr")[flo], sp.eye(n, format="csr")[fhi]]
    b = [e / s, -lo[flo] / s, hi[fhi] / s]
    cones = ([clarabel.ZeroConeT(r)] if r else []) + [clarabel.NonnegativeConeT(len(flo) + len(fhi))]
    for i in discs:
        rows.append(sp.csr_matrix((-np.ones(k), (np.arange(1, k + 1), m + i + m * np.arange(k))), shape=(k + 1, n)))
        b.append(np.r_[hi[m + i] / s, np.zeros(k)])
        cones.append(clarabel.SecondOrderConeT(k + 1))
    Wn = W / wmax
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    for key, v in CLARABEL_TIGHT.items():
        setattr(settings, key, v)
    sol = clarabel.DefaultSolver(sp.triu(0.5 * (Wn + Wn.T), format="csc"), -q / (s * wmax),
                                 sp.vstack(rows, format="csc"), np.concatenate(b), cones, settings).solve()
    if sol.status not in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved):
        return None
    return np.asarray(sol.x) * s, -s * wmax * np.asarray(sol.z[:r])


def redundant_pairs(W: np.ndarray, k: int = 1) -> np.ndarray:
    """Tangent rows parallel to their node's normal row (rollers on both sides of the node:
    both rows act on one relative motion), one flag per tangent row (j·m + i): the 2×2 block
    of W on the pair is singular, det ≤ 1e-10 W_nn W_tt (an angle below 1e-5 rad between the
    rows in the W-metric)."""
    m = W.shape[0] // (1 + k)
    node, row = np.tile(np.arange(m), k), m + np.arange(k * m)
    dn, dt, nt = np.diag(W)[node], np.diag(W)[row], W[node, row]
    return dn * dt - nt * nt <= 1e-10 * dn * dt


def _newton_point(W, q, G, e, free, fixed_values, redundant, disc=None, c=None, acting=None):
    """Solve the active-set system: λ_A fixed, r_F(λ, α) = 0 and Gλ = e for (λ_F, α).

    disc: (J, D) for nodes slipping on a disc, their tangent components J (n, k) and the
    Jacobians D of the projection there (`disc_slips`); their rows are the linearized
    projection λ_J − D(λ_J + c r_J) = Π(z)_J (D z = 0), unknowns beside the free ones. These
    rows are O(1) beside W's O(1/c) (1e-9 on a rock tunnel): partial pivoting takes them as
    pivots for other nodes' columns and the solution loses about six digits (on the 3D tunnel
    Newton stalled at 2e-10 of the force scale against the tolerance 1e-10 and ran to
    `max_iter`); one step of iterative refinement on the residual M x − rhs restores them.

    The system [[W_FF, −G_Fᵀ], [G_F, 0]] is singular where constraints are redundant: a
    node of `redundant_pairs` that is closed and stuck carries a pair (λn, λt) of which
    only one combination acts, and its tangential equation is a multiple of its normal one.
    In floating point the system is then merely ill-conditioned (cond ~1e17) and an LU
    solve puts ~1e23 along the redundant combination, which flips the next prediction (a
    cycle). Such a tangent's equation (κ times the normal one, κ = W_nt / W_nn) is dropped
    with λt = 0, and the pair is then moved along the null direction (κ, −1) to the minimum
    norm split λn + κλt = const: λ = (λn, 0) / (1 + κ²) · (1, κ) — the least-squares
    solution at the cost of one LU (one tangent per node is taken to be so tied). On a disc
    (k = 2) the split is left at λt = 0 instead, the one that keeps |λt,i| ≤ gw_i most
    feasible: the minimum norm split puts κλn/(1 + κ²) on the tangent, beyond gw on a fault
    node held by a roller, and Newton then cycled between stick and slip there. A free row
    that is exactly zero (a node held by supports on both sides, a row of round-off made null
    by `null_rows`) is left out with λ = 0, the least-squares value: on the 3D tunnel 154 of
    789 rows are such (most of them tangents along the axis, held by rollers front and back),
    and least squares over the whole system cost ~1.4 s a step against ~0.1 s for the LU. A
    system singular otherwise is solved by least squares. α is scaled by max|W| so that both
    blocks are of one size.

    In 3D (k = 2) the system is solved in its symmetric form (`_disc_frame_step`) by a
    Cholesky factorization, the LU above only where that is not positive definite.
    """
    n_t = len(redundant)
    m = len(free) - n_t
    k = n_t // m if m else 1
    tied = np.zeros_like(free)
    tied[m:] = redundant & np.tile(free[:m], k) & free[m:]
    unknown = free.copy()
    acting = np.any(W, axis=1) if acting is None else acting     # (rows of W not all zero: W's, once per Newton)
    null = free & ~acting                    # a free row acting on nothing: λ = 0 (least squares)
    if disc is not None and len(disc[0]):
        unknown[disc[0].ravel()] = True
    solve = unknown & ~tied & ~null
    F = np.flatnonzero(solve)
    lam = np.where(unknown, 0.0, fixed_values)
    r = G.shape[0]
    step = _disc_frame_step(W, q, G, e, F, lam, fixed_values, disc, c) if k == 2 else None
    if step is not None:
        lam, alpha = step
        return _tied_split(W, lam, tied, m, k), alpha
    s = max(np.abs(W).max(initial=0.0), 1e-300)
    f = len(F)
    M = np.zeros((f + r, f + r))          # [[W_FF, −s G_Fᵀ], [s G_F, 0]]
    M[:f, :f] = W[np.ix_(F, F)]
    M[:f, f:] = -s * G[:, F].T
    M[f:, :f] = s * G[:, F]
    rhs = np.concatenate([q[F] - W[F] @ lam, s * (e - G @ lam)])
    if disc is not None and len(disc[0]):
        J, D = disc
        P = np.searchsorted(F, J)                               # their rows and columns in M
        cD = c[J[:, :1, None]] * D
        rows = np.einsum("sij,sjc->sic", cD, M[P])
        rows[np.arange(len(J))[:, None, None], np.arange(k)[None, :, None], P[:, None, :]] += np.eye(k) - D
        M[P], rhs[P] = rows, np.einsum("sij,sj->si", cD, rhs[P]) + fixed_values[J]
    try:
        if disc is not None and len(disc[0]):          # one LU for the solve and its refinement
            lu, piv, info = sla.lapack.dgetrf(M)
            if info != 0:
                raise np.linalg.LinAlgError
            x = sla.lapack.dgetrs(lu, piv, rhs)[0]
            x += sla.lapack.dgetrs(lu, piv, rhs - M @ x)[0]
        else:
            x = np.linalg.solve(M, rhs)
        if not np.all(np.isfinite(x)):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        x = np.linalg.lstsq(M, rhs, rcond=None)[0]
        if disc is not None and len(disc[0]):
            x += np.linalg.lstsq(M, rhs - M @ x, rcond=None)[0]
    lam[F] = x[: len(F)]
    return _tied_split(W, lam, tied, m, k), s * x[len(F):]


def _tied_split(W, lam, tied, m, k):
    """A tied pair (`_newton_point`) moved to the minimum norm split of its normal force; on a
    disc (k = 2) left at λt = 0. Newton's own bookkeeping: what a solution reports at such a
    node is the solver-independent split of `wcs.contact.zone.canonical_split`."""
    if k > 1 or not tied.any():
        return lam
    pair = np.flatnonzero(tied[m:] & (np.diag(W)[:m] > 0))
    node = pair % m
    kappa = W[node, m + pair] / np.diag(W)[node]
    lam[node], lam[m + pair] = lam[node] / (1 + kappa**2), kappa * lam[node] / (1 + kappa**2)
    return lam


def _disc_frame_step(W, q, G, e, F, lam, fixed_values, disc, c):
    """The active-set system of `_newton_point` for k = 2 in the slip frame of each disc node,
    where it is symmetric: (λ, α) or None where its matrix is not positive definite.

    A node slipping on a disc has D = γ(I − ννᵀ), γ = gw/|z| ∈ (0, 1), ν = Π(z)/gw. Its
    linearized rows λ − D(λ + c r) = Π(z) say along ν: νᵀλ = gw, and across it, τ = ν rotated
    by 90°: (1 − γ) τᵀλ − γ c τᵀr = 0, i.e. τᵀ(Wλ − Gᵀα)_J + δ a = τᵀq_J with a = τᵀλ,
    δ = (1 − γ)/(γ c). With V the columns of the unknowns (the free rows F′ = F without the
    disc rows, one τ per disc node), λ = λ₀ + V y (λ₀: the fixed values, gw ν on the discs):

        [[VᵀWV + diag(δ), −(GV)ᵀ], [GV, 0]] [y; α] = [Vᵀ(q − Wλ₀); e − Gλ₀],

    the same equations as the unsymmetric form (each disc row pair is a rotation of them,
    the τ row divided by γc > 0). VᵀWV + diag(δ) is the Delassus operator of the unknown
    directions: a Cholesky factorization, half an LU's work, and one unknown less per disc
    node; α from the r × r Schur complement on it. None also where that is singular (the
    least-squares solve of `_newton_point` takes such a system)."""
    J, D = disc if disc is not None else (np.zeros((0, 2), dtype=int), np.zeros((0, 2, 2)))
    plain = np.setdiff1d(F, J.ravel())
    nu = fixed_values[J] / np.linalg.norm(fixed_values[J], axis=1, keepdims=True)   # (n_s, 2)
    tau = np.c_[-nu[:, 1], nu[:, 0]]
    ns = len(J)
    gamma = np.trace(D, axis1=1, axis2=2)                     # (k − 1) γ, k = 2
    delta = (1.0 - gamma) / (gamma * c[J[:, 0]]) if ns else np.zeros(0)
    p = len(plain)
    rows = np.r_[plain, J[:, 0], J[:, 1]]     # V's nonzero rows: I on plain, diag(τ_0), diag(τ_1) on the discs

    def right(A):                             # A[:, rows] V
        return np.c_[A[:, :p], A[:, p:p + ns] * tau[:, 0] + A[:, p + ns:] * tau[:, 1]]

    lam0 = lam.copy()
    lam0[J] = fixed_values[J]                                 # gw ν
    # Vᵀ W V, its upper triangle only (what the Cholesky factorization reads), written in place
    H = np.empty((p + ns, p + ns))
    H[:p, :p] = _take(W, plain, plain)
    A = _take(W, rows, J[:, 0]) * tau[:, 0]                   # (W V) on the disc columns
    A += _take(W, rows, J[:, 1]) * tau[:, 1]
    H[:p, p:] = A[:p]
    H[p:, p:] = tau[:, :1] * A[p:p + ns] + tau[:, 1:] * A[p + ns:]
    H[np.arange(p, p + ns), np.arange(p, p + ns)] += delta
    b = right((q - W @ lam0)[None, rows]).ravel()
    try:
        cho = sla.cho_factor(H, check_finite=False, overwrite_a=True)
    except np.linalg.LinAlgError:
        return None
    GV = right(G[:, rows])
    alpha = np.zeros(G.shape[0])
    y = sla.cho_solve(cho, b, check_finite=False)
    if G.shape[0]:
        X = sla.cho_solve(cho, GV.T, check_finite=False)      # H⁻¹ (GV)ᵀ
        try:                                                  # singular: a rigid mode no row holds
            alpha = np.linalg.solve(GV @ X, e - G @ lam0 - GV @ y)
        except np.linalg.LinAlgError:
            return None
        y = y + X @ alpha
    if not np.all(np.isfinite(y)):
        return None
    lam0[plain] += y[:p]
    lam0[J] += y[p:, None] * tau
    return lam0, alpha


def _range(index: np.ndarray):
    """The slice of an ascending run of consecutive indices, else None."""
    if len(index) and index[-1] - index[0] == len(index) - 1 and np.all(np.diff(index) == 1):
        return slice(int(index[0]), int(index[-1]) + 1)
    return None


def _take(W: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """W[rows][:, cols], a view where both are runs (every contact closed and every node on a
    disc slipping: the rows of W in its own order; a gather of W's 4311 rows by 1437 columns
    was a third of a Newton step on the 3D shear patch)."""
    r, c = _range(rows), _range(cols)
    if r is not None and c is not None:
        return W[r, c]
    if r is not None:
        return W[r][:, cols]
    if c is not None:
        return W[rows, c]
    return W[np.ix_(rows, cols)]


def _first_free_set(warm, gw, k=1):
    """Free set of the first Newton step: the warm result's active set, else all closed and stuck.

    Predicting it from the warm multipliers instead (λ + c r with the new data) marks most
    stuck nodes as slipping, since the old λ leaves slips ~ the data change; the warm set
    is usually exact and converges in one step. Open nodes (where Tresca friction still
    acts) stick if their old |λt| was below the bound.
    """
    if warm is None or warm.active is None:
        return np.r_[np.ones(len(gw), dtype=bool), np.tile(gw > 0, k)]
    open_ = warm.active == OPEN
    stick = (warm.active == STICK) | (open_ & (np.linalg.norm(warm.lam_t.reshape(k, -1), axis=0) < gw))
    return np.r_[~open_, np.tile(stick & (gw > 0), k)]


def _states(free, m, gw):
    """Node states from the final free set: open / stick / slip."""
    closed, stick = free[:m], free[m:m + m] & (gw > 0)
    return np.where(~closed, OPEN, np.where(stick, STICK, SLIP))


CERTIFICATE = 1e-6     # relative size of a contact condition's violation that refuses an answer


def conditions_violated(u, gap_error, lam_n, lam_t, gw, k=1, tol=0.0, reference=0.0) -> str:
    """What of the contact conditions an answer breaks ("" if none), checked on the answer
    itself rather than on Newton's scaled residual: penetration Bn u − d ≤ ε_u, pressure
    λn ≥ −ε_λ and friction |λt,i| ≤ g_i w_i + ε_λ, with ε_u = `CERTIFICATE` × the largest
    displacement or gap and ε_λ = `CERTIFICATE` × the largest multiplier or g w — or `tol`
    (the solve's tolerance) in place of `CERTIFICATE` where the user asked for less. (A
    convergence test relative to the largest scaled residual passes an answer whose rows are
    badly scaled against each other, e.g. a near-null row with a huge c = 1/W_ii.) reference: the
    size of the displacement u is an increment of (`ContactProblem.reference`), part of ε_u's scale."""
    m = lam_n.size
    eps = max(CERTIFICATE, tol)
    eu = eps * max(np.abs(u).max(initial=0.0), np.abs(gap_error).max(initial=0.0), reference, 1e-300)
    finite_gw = gw[np.isfinite(gw)]
    el = eps * max(np.abs(lam_n).max(initial=0.0), np.abs(lam_t).max(initial=0.0),
                   finite_gw.max(initial=0.0), 1e-300)
    lt = np.sqrt((lam_t.reshape(k, m) ** 2).sum(axis=0)) if m else np.zeros(0)
    if gap_error.max(initial=0.0) > eu:
        return f"non-penetration (Bn u − d up to {gap_error.max():.3e})"
    if lam_n.min(initial=0.0) < -el:
        return f"λn ≥ 0 (down to {lam_n.min():.3e})"
    if np.any(lt > gw + el):
        return f"|λt| ≤ g w (by up to {(lt - gw).max():.3e})"
    return ""


class _TrescaNewton:
    """The Tresca problems of one condensed system (W, q, G, e) by semismooth Newton
    (`_newton`), for the bounds a law gives (`wcs.contact.laws.TrescaSolve`): each started
    from the last one's (λ, α), projected onto the new bounds; the first from the warm
    result's active set (`_first_free_set`). `qp`: a Newton that reaches its step budget restarts from the dual QP."""

    def __init__(self, W, q, G, e, lam, alpha, warm, tol, max_iter, qp, k):
        self.W, self.q, self.G, self.e, self.lam, self.alpha = W, q, G, e, lam, alpha
        self.warm, self.tol, self.max_iter, self.k = warm, tol, max_iter, k
        self.options = {"k": k} if qp else {"fallback": False, "k": k}
        self.free = None

    def __call__(self, gw):
        k, m = self.k, len(gw)
        lo = np.r_[np.zeros(m), -np.tile(gw, k)]
        hi = np.r_[np.full(m, np.inf), np.tile(gw, k)]
        free0 = _first_free_set(self.warm, gw, k) if self.free is None else None
        self.lam, self.alpha, self.free, n, ok = _newton(self.W, self.q, self.G, self.e, lo, hi,
                                                         project(self.lam, lo, hi, k), self.alpha, self.tol,
                                                         self.max_iter, free0, **self.options)
        return self.lam[:m], ok, n


def solve_contact(K, f, Bn, Bt, d, w, g=None, F=None, R=None, *, tol=1e-10, max_iter=100,
                  warm: ContactResult | None = None, factor: ContactFactor | None = None,
                  factored: ContactFactor | None = None,
                  tol_fp=1e-8, max_fp_iter=50, checked: bool = False, qp: bool = True,
                  reference: float = 0.0) -> ContactResult:
    """Tresca (g) or Coulomb (F) contact by condensed semismooth Newton; see the module docstring.

    warm:   a previous result on the same mesh; its multipliers start the Newton
            iteration and its factor is refactored (same pattern) unless `factor` is given.
            The factor object is updated in place.
    factored: what the caller vouches solves with K (regularized on `pinned_dofs(R)` when R
            is given) and holds W of these contact rows (`.factor.solve`, `.W`) — made once for
            many solves with the same K and rows (a DD pair's per data set), or from the
            factors of K's units (`wcs.contact.units`): used as it is, with no regularization
            of K, comparison or refactor (`factor_contact`'s per-call work); `factor` and
            `warm`'s factor are then not used, nor is K.
    Coulomb: slip limit g + F p (both may be given: contacts of either law in one zone);
            fixed point over Tresca problems started from the all-stick (glued) solution
            — which also holds a floating body that only friction keeps in place — or
            from the warm pressures, until ‖Δp‖ ≤ tol_fp ‖p‖ (at most max_fp_iter solves).
    A solution along which a rigid mode of R is left free (`free_rigid_motion`) is not
    unique: status NOT_UNIQUE, `alpha` the free motion, no u.
    checked: the caller has already found the load balanced on R (`unbalanced_rigid_motion`
            depends on f only through Rᵀf): the linear program is not run again.
    qp:     False: a Newton at its step budget is not restarted from the dual QP (cvxpy) but reported
            (CONTACT_NOT_CONVERGED).
    reference: the size of the displacement u is an increment of (`ContactProblem.reference`).
    """
    return solve_condensed(ContactProblem(K, f, Bn, Bt, d, w, g, F, R, warm, reference=reference),
                           tol=tol, max_iter=max_iter,
                           factor=factor, factored=factored, tol_fp=tol_fp, max_fp_iter=max_fp_iter,
                           checked=checked, qp=qp)


def solve_condensed(problem: ContactProblem, *, tol=1e-10, max_iter=100, factor: ContactFactor | None = None,
                    factored=None, tol_fp=1e-8, max_fp_iter=50, checked: bool = False,
                    qp: bool = True) -> ContactResult:
    """`solve_contact` of a `ContactProblem`: its law (`wcs.contact.laws`) drives the
    semismooth Newton of the condensed system over Tresca problems (`_TrescaNewton`); the
    problem's `scale` is in `factored` (`wcs.contact.units`), K is then not used."""
    t0 = time.perf_counter()
    timings = {}
    K, f, Bn, Bt, d, w, R, warm = (problem.K, problem.f, problem.Bn, problem.Bt, problem.d, problem.w,
                                   problem.R, problem.warm)
    m, k, C, law = problem.m, problem.k, problem.C, problem.law
    coulomb = law.coulomb
    gw = law.start(warm.lam_n if warm is not None else None, np.inf)     # Coulomb: all stick, or warm

    if R is not None and not coulomb and not checked:
        found = unbalanced(f, Bn, Bt, gw, R)
        timings["solvability"] = time.perf_counter() - t0
        if found is not None:
            value, alpha = found
            return ContactResult(None, None, None, Status.UNSOLVABLE,
                                 f"unbalanced load on a floating body: fᵀv − j(v) = {value:.3e} > 0 "
                                 f"for the admissible rigid motion v = Rα, α = {np.array2string(alpha, precision=4)}",
                                 alpha=alpha, timings=timings)

    t = time.perf_counter()
    try:
        cf = factored if factored is not None else \
            factor_contact(K, C, R, factor if factor is not None else (warm.factor if warm else None), k > 1)
        u0 = cf.factor.solve(f)
    except linalg.FactorizationError as exc:
        return ContactResult(None, None, None, Status.SINGULAR, f"factorization failed: {exc}", timings=timings)
    timings["factor"] = time.perf_counter() - t

    t = time.perf_counter()
    W = cf.W
    q = C @ u0 - np.r_[d, np.zeros(k * m)]
    G = (C @ R).T if R is not None else np.zeros((0, (1 + k) * m))
    null = null_rows(W)
    if null.any():                 # rows of round-off: exactly null, as a node held on both sides
        W = W.copy()               # (the factor's W stays as it is: it serves later solves)
        W[null], W[:, null], G[:, null] = 0.0, 0.0, 0.0
        q[null] = -np.r_[d, np.zeros(k * m)][null]
    e = rigid_load(R, f) if R is not None else np.zeros(0)
    lam = np.zeros((1 + k) * m) if warm is None or warm.lam_n is None else np.r_[warm.lam_n, warm.lam_t]
    alpha = np.zeros(G.shape[0]) if warm is None or warm.alpha is None else warm.alpha
    newton = _TrescaNewton(W, q, G, e, lam, alpha, warm, tol, max_iter, qp, k)
    driven = law.drive(newton, gw, tol_fp, max_fp_iter)
    lam, alpha, free = newton.lam, newton.alpha, newton.free
    gw, ok, fp_ok, iters, fp_iters = (driven.gw, driven.ok, driven.settled, driven.iterations,
                                      driven.fixed_point_iterations)
    timings["newton"] = time.perf_counter() - t

    if not ok and coulomb and R is not None:     # friction F p may be too weak to hold a floating body
        found = unbalanced(f, Bn, Bt, np.where(np.isfinite(gw), gw, 0.0), R)
        if found is not None:
            value, a = found
            return ContactResult(None, None, None, Status.UNSOLVABLE,
                                 f"unbalanced load on a floating body held by Coulomb friction: "
                                 f"fᵀv − j(v) = {value:.3e} > 0 at the last pressures, α = "
                                 f"{np.array2string(a, precision=4)}", iterations=iters,
                                 fixed_point_iterations=fp_iters, alpha=a, timings=timings)
    beta = None
    if ok and R is not None:
        r = q - W @ lam + G.T @ alpha                     # C u − [d; 0]: −gap on the normal rows
        touching = np.abs(r[:m]) <= tol * max(np.abs(r).max(), 1e-300)
        held = free | np.r_[touching, np.zeros(k * m, bool)]
        beta = free_rigid_motion(np.c_[G, _across_slip(G, lam[m:], free, k)], np.r_[held, np.ones(m * (k > 1), bool)])
    if beta is not None:
        return ContactResult(None, None, None, Status.NOT_UNIQUE,
                             f"the solution is not unique: the rigid motion v = Rβ, β = "
                             f"{np.array2string(beta, precision=4)}, moves no closed or stuck contact node",
                             iters, fp_iters, alpha=beta, timings=timings)
    u = cf.factor.solve(f - C.T @ lam) + (R @ alpha if R is not None else 0.0)
    status, message = Status.SOLVED, "converged"
    violation = conditions_violated(u, Bn @ u - d, lam[:m], lam[m:], gw, k, tol, problem.reference) if ok else ""
    if violation:
        status, message = Status.CONTACT_NOT_CONVERGED, (
            f"semismooth Newton stopped at an answer that violates {violation}: not reported")
    elif not ok:
        status, message = Status.CONTACT_NOT_CONVERGED, (
            f"semismooth Newton did not converge in {max_iter} iterations" if qp else
            f"semismooth Newton did not converge ({iters} iterations: an active set cycled or the budget of "
            f"{max_iter} ran out; no dual QP restart)")
    elif not fp_ok:
        status = Status.FIXED_POINT_NOT_CONVERGED
        message = f"Coulomb fixed point did not converge in {max_fp_iter} iterations"
    timings["total"] = time.perf_counter() - t0
    return ContactResult(u, lam[:m], lam[m:], status, message, iters, fp_iters, _states(free, m, gw), cf,
                         alpha if R is not None else None, timings, free=free, gw=gw)
