"""BDDC preconditioner of the Newton steps' operators (`solver.iterative.preconditioner: bddc`).

Balancing domain decomposition by constraints (PETSc's PCBDDC) needs each subdomain's own
(Neumann) stiffness matrix, not only the assembled one: K = Σ_s R_sᵀ K_s R_s, K_s assembled
over the cells of subdomain s, R_s the restriction to its dofs. A Newton step's operator is
Zᵀ K Z plus the diagonal of K on the eliminated pivots P (`wcs.contact.iterative._eliminated`),
K itself Tᵀ K_dofs T after the supports' and glued interfaces' elimination T. Both are sums
over the subdomains: Tᵀ K T = Σ_s T_sᵀ K_s T_s with T_s the rows of T on s's dofs, on the
unknowns those rows touch (`transformed`; Z is node-local, a node's pivots eliminated by its own
unknowns, so a subdomain's part of a step mostly keeps its own unknowns), and diag(K)_P =
Σ_s diag(K_s)_P. The interface dofs are held by
several subdomains: that is MATIS's local-to-global map with repeated entries, so all
subdomains of this process are one local matrix (block diagonal, `setISAllowRepeated`).

Constraints: vertices, edge and face averages of each displacement component (PCBDDC's fields,
`components`) and the rigid modes (the near-nullspace), the edges' imposed by a change of basis
(`use_change_of_basis`), the interface weighted by deluxe scaling (`use_deluxe_scaling`: on the
glued step of the 3D patch at 1.1e4 unknowns, 8 parts, 43 CG iterations with the default
multiplicity scaling, 14 with deluxe, 10 with the rigid modes too). A floating subdomain without
enough primal vertices (four columns of a cube: no vertex inside) leaves its Neumann matrix
singular and PCBDDC's set-up fails (PC failed); the solve is then set up again with the faces'
constraints by a change of basis too (`FACES`), which holds there but costs on the patch 27 s
of set-up against 6 s (so it is not the first choice). The set-up taken depends on the
matrices alone; `faces` counts the solves that took the second.

In the iterative method (`solver.iterative.preconditioner: bddc`, `wcs.contact.iterative.Krylov`)
the data set's subdomains (`model_parts`: K(c)'s over each part's cells, reduced by the supports'
and glued interfaces' T) are made once a solve, and each Newton step's operator from them
(`Parts.of`, `step_parts`). On a group of ranks (`solver.ranks_per_evaluation`) rank r of k
holds the subdomains `wcs.group.rows(parts, k, r)` (the same cut as on one rank: `parts_of`),
the matrices of those alone, and the unknowns of every subdomain (a spring row goes to the same
subdomain on every layout); the MATIS spans the group's communicator, its rows A's
(`wcs.contact.distributed.Layout`), each rank's subdomains its local matrix. The preconditioner
is the same on every layout, so the answers agree to CG's tolerance. Cost: each rank's
subdomains are one local matrix, so PCBDDC's dense work, the coarse basis functions (a Neumann
solve for each primal constraint) and the deluxe scaling's Schur complements, spans them at
once and its set-up grows faster than the unknowns: 14x, 17x, 36x GAMG's CPU time at 1.1e4,
2.6e4, 8.0e4 unknowns of the 3D patch on one process; on two ranks the same CPU time summed
over them (68 s at 8.0e4 on one and on two; GAMG 1.7 s and 2.5 s), each rank half the memory
(tests/bench/test_bench_bddc.py).
"""
from __future__ import annotations

import dataclasses
import itertools
import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from wcs import linalg

OPTIONS = {"pc_bddc_use_faces": "true", "pc_bddc_use_change_of_basis": "true",
           "pc_bddc_use_deluxe_scaling": "true"}
FACES = {"pc_bddc_use_change_on_faces": "true"}     # the faces' constraints by a change of basis too
MAX_IT = 2000
REBUILD_ITERATIONS = 200      # a set-up's cost in CG iterations (`wcs.contact.iterative.Krylov`'s rule): 7.4 s against
#                               0.036 s an iteration at 2.6e4 unknowns, 400 at 8.0e4 (tests/bench/test_bench_bddc.py)
_PREFIX = itertools.count()


def bisection(points: np.ndarray, parts: int) -> np.ndarray:
    """The part (0..parts−1) of each point (dim, n) by recursive coordinate bisection: the
    longest extent is cut at the quantile that gives both halves their share of the parts."""
    out = np.zeros(points.shape[1], dtype=int)

    def split(idx, first, count):
        if count == 1 or len(idx) == 0:
            out[idx] = first
            return
        x = points[:, idx]
        axis = int(np.argmax(x.max(axis=1) - x.min(axis=1)))
        order = idx[np.argsort(x[axis], kind="stable")]
        left = count // 2
        cut = int(round(len(idx) * left / count))
        split(order[:cut], first, left)
        split(order[cut:], first + left, count - left)

    split(np.arange(points.shape[1]), 0, parts)
    return out


def subdomain_stiffness(t: np.ndarray, local, group: np.ndarray, coefficients, cells: np.ndarray):
    """(dofs, K_s): a subdomain's own stiffness Σ_cells c[group(cell)] · K_cell over its cells
    only (`wcs.fem.affine.CellAffineOperator`'s sum restricted to them; local: its cell matrices,
    made chunk by chunk), on the dofs of those cells."""
    from wcs.fem.affine import CHUNK
    c = np.asarray(coefficients, dtype=float).reshape(-1, local.npieces)[group]
    b, n = local.block, t.shape[0]
    rows, cols, vals = [], [], []
    for s in range(0, len(cells), CHUNK):
        e = cells[s:s + CHUNK]
        cell = np.einsum("ek,keabij->eaibj", c[e], local.of(e))              # (e, n, b, n, b)
        dof = (b * t[:, e].T[:, :, None] + np.arange(b)).reshape(len(e), n * b)   # (e, n·b)
        rows.append(np.repeat(dof, n * b, axis=1).ravel())
        cols.append(np.tile(dof, (1, n * b)).ravel())
        vals.append(cell.ravel())
    dofs, inverse = np.unique(np.concatenate(rows), return_inverse=True)
    cols = np.searchsorted(dofs, np.concatenate(cols))
    K_s = sp.csr_matrix((np.concatenate(vals), (inverse, cols)), shape=(len(dofs), len(dofs)))
    K_s.sum_duplicates()
    return dofs, K_s


def transformed(dofs: np.ndarray, K_s: sp.spmatrix, T: sp.spmatrix, diagonal=None):
    """(dofs', T_sᵀ K_s T_s + diag(K_s) on `diagonal`): a subdomain's part of Tᵀ K T (+ diag(K)
    on the unknowns `diagonal`, the step's pivots, `wcs.contact.iterative._eliminated`), T_s
    the rows of T on its dofs, on the columns they touch (dofs'; a row of T that refers to
    another subdomain's unknowns, a glued slave's master or a contact pivot's, adds that unknown
    to this subdomain's: Σ_s of the parts is Tᵀ K T exactly). T square where diagonal is given."""
    Ts, held, local = _touched(dofs, T, diagonal)
    out = Ts[:, local].T @ K_s @ Ts[:, local]
    at = np.searchsorted(local, dofs[held])
    out = out + sp.csr_matrix((sp.csr_matrix(K_s).diagonal()[held], (at, at)), shape=out.shape)
    return local, out.tocsr()


def _touched(dofs, T, diagonal=None):
    """(T_s, held, dofs'): the rows T_s of T on `dofs`, the positions in dofs of the unknowns
    `diagonal`, and the unknowns `transformed` puts its part on."""
    Ts = sp.csr_matrix(T)[dofs]
    Ts.eliminate_zeros()
    held = np.zeros(0, dtype=int) if diagonal is None else np.flatnonzero(np.isin(dofs, diagonal))
    return Ts, held, np.union1d(np.unique(Ts.indices), dofs[held])


def components(T: sp.spmatrix, dim: int) -> np.ndarray:
    """The displacement component of each unknown w of u = T w (dof = dim·node + component):
    the component of the first dof its column of T moves."""
    T = sp.csc_matrix(T)
    return T.indices[T.indptr[:-1]] % dim


UNKNOWNS_PER_PART = 2500      # subdomain size: the 3D patch at 8e4 unknowns took 201 s of set-up with 16 parts, 72 s with 32


def parts_of(unknowns: int, ranks: int = 1) -> int:
    """How many subdomains BDDC cuts `unknowns` into (`UNKNOWNS_PER_PART` each, at least 2 and
    at least one a rank: the same cut on one rank and on a group of fewer ranks than parts)."""
    return max(2, ranks, round(unknowns / UNKNOWNS_PER_PART))


@dataclasses.dataclass(frozen=True)
class Parts:
    """A data set's subdomains: each one's reduced unknowns (`dofs`, all subdomains), the
    subdomains this process holds (`owned`, a range; None: all) with their own parts of the
    reduced stiffness Kr = Tᵀ K(c) T (`stiffness`, in that order; Σ_s R_sᵀ K_s R_s = Kr over
    all s), each unknown's displacement component and the near-nullspace (n, r)."""
    dofs: tuple
    stiffness: tuple
    components: np.ndarray
    near_nullspace: np.ndarray | None
    owned: range | None = None

    def of(self, Z, P, springs=None, pin=None) -> Bddc:
        """The BDDC of a Newton step's operator Zᵀ Kt Z + diag(Kr)_P (+ its own diagonal again on
        the pinned unknowns `pin`: `wcs.contact.iterative._pinned`), Kt = Kr + Qᵀ diag(s) Q with
        the disc springs (Q, s) (`springs`; None: Kt = Kr), on the owned subdomains: `step_parts`."""
        dofs, local = step_parts(self.dofs, self.stiffness, Z, P, springs, pin, self.owned)
        return Bddc(dofs, local, self.components, self.near_nullspace)


def model_parts(mesh, operator, T: sp.spmatrix, coefficients, near_nullspace, parts: int, owned=None) -> Parts:
    """The `Parts` of K(c) (`operator`: the model's `CellAffineOperator`, coefficients c) on the
    reduced unknowns of u = T w, the cells cut by `bisection` of their centroids; the matrices
    of the `owned` parts only (a range; None: all), the unknowns of every part."""
    part = bisection(mesh.p[:, mesh.t].mean(axis=1), parts)
    owned = range(parts) if owned is None else owned
    dofs, stiffness = [], []
    for s in range(parts):
        cells = np.flatnonzero(part == s)
        if s in owned:
            d, K_s = transformed(*subdomain_stiffness(mesh.t, operator.local, operator.group, coefficients, cells), T)
            stiffness.append(K_s)
        else:
            b = operator.local.block
            d = _touched(np.unique(b * mesh.t[:, cells][..., None] + np.arange(b)), T)[2]
        dofs.append(d)
    return Parts(tuple(dofs), tuple(stiffness), components(T, mesh.p.shape[0]), near_nullspace, owned)


def step_parts(dofs, stiffness, Z, P, springs=None, pin=None, owned=None):
    """The owned subdomains' unknowns and parts of a Newton step's operator (`Parts.of`; owned:
    a range of the subdomains, None: all; stiffness: theirs): each one's stiffness `transformed`
    by Z with diag(K_s) on the pivots P; each spring row of Q (a slipping node's,
    `wcs.contact.iterative._Stepper._slip`) to the subdomain that holds the first unknown its
    row of Q Z touches, the first such subdomain of all (the others it touches join that
    subdomain: `_joined`); on the pinned unknowns each part's own diagonal again (Σ_s of them
    is A's)."""
    owned = range(len(dofs)) if owned is None else owned
    out = {j: transformed(dofs[j], K_s, Z, P) for j, K_s in zip(owned, stiffness)}
    if springs is not None:
        Q, s = springs
        QZ = sp.csr_matrix(Q @ Z)
        QZ.eliminate_zeros()
        owner = np.full(Z.shape[1], -1)
        for j in reversed(range(len(dofs))):
            owner[out[j][0] if j in out else _touched(dofs[j], Z, P)[2]] = j
        first = owner[QZ.indices[QZ.indptr[:-1]]]
        if np.any(first < 0):
            raise ValueError("a spring row of the step touches no subdomain's unknowns")
        for j in np.unique(first):
            if j not in out:
                continue
            rows = QZ[first == j]
            cols = np.unique(rows.indices)
            spring = rows[:, cols].T @ sp.diags(s[first == j]) @ rows[:, cols]
            out[j] = _joined(*out[j], cols, spring)
    if pin is not None and len(pin):
        for j, (d, L) in out.items():
            held = np.flatnonzero(np.isin(d, pin))
            out[j] = (d, (L + sp.csr_matrix((L.diagonal()[held], (held, held)), shape=L.shape)).tocsr())
    return [out[j][0] for j in owned], [out[j][1] for j in owned]


def _joined(dofs, A, more, B):
    """(dofs ∪ more, A + B) of two matrices on the unknowns dofs and more (sorted, unique)."""
    union = np.union1d(dofs, more)
    a, b = np.searchsorted(union, dofs), np.searchsorted(union, more)
    A, B = sp.coo_matrix(A), sp.coo_matrix(B)
    out = sp.csr_matrix((np.r_[A.data, B.data], (np.r_[a[A.row], b[B.row]], np.r_[a[A.col], b[B.col]])),
                        shape=(len(union), len(union)))
    out.sum_duplicates()
    return union, out


def _aij(A, PETSc):
    A = sp.csr_matrix(A)
    return PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType),
                                                A.data), comm=PETSc.COMM_SELF)


class SetupFailure(Exception):
    """PCBDDC could not be set up on these subdomain matrices (`Bddc.build`)."""


class Bddc:
    """BDDC of an assembled SPD operator A from its subdomain matrices. dofs: the unknowns of
    each subdomain this process holds; local: each one's part of A (`transformed`,
    `step_parts`: Σ_s R_sᵀ local_s R_s = A over the subdomains of all the processes);
    near_nullspace: (n, r) rigid modes; components: each unknown's displacement component
    (PCBDDC's constraints are per component: its fields). `build` sets up CG + PCBDDC on one
    process or over the ranks of a group (`wcs.contact.iterative.Krylov` solves with it),
    `solve` one CG solve on this process (all subdomains its own)."""

    def __init__(self, dofs, local, components, near_nullspace=None):
        self.dofs, self.local, self.N, self.components = dofs, local, near_nullspace, np.asarray(components)
        self.timings = {"bddc_setup": 0.0, "cg": 0.0}
        self.faces = 0

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float):
        """x with ‖b − A x‖ ≤ rtol ‖b‖ (unpreconditioned norm): (x, iterations, converged)."""
        PETSc = linalg.petsc()
        t = time.perf_counter()
        Aa = _aij(A, PETSc)
        try:
            ksp, M = self.build(Aa, PETSc)
        except SetupFailure:
            Aa.destroy()
            return np.zeros(A.shape[0]), 0, False
        self.timings["bddc_setup"] += time.perf_counter() - t
        t = time.perf_counter()
        ksp.setOperators(Aa, M)
        ksp.setTolerances(rtol=rtol, atol=0.0, max_it=MAX_IT)
        x, rhs = Aa.createVecs()
        rhs.setArray(np.asarray(b, dtype=float))
        try:
            ksp.solve(rhs, x)
            out = x.getArray().copy()
            self.timings["cg"] += time.perf_counter() - t
            return out, ksp.getIterationNumber(), ksp.getConvergedReason() > 0
        finally:
            for o in (ksp, M, Aa, x, rhs):
                o.destroy()

    def build(self, A, PETSc, layout=None):
        """(ksp, M): CG (unpreconditioned residual norm) with PCBDDC set up on M, the MATIS of
        the subdomain matrices; A (PETSc AIJ) the operator, its rows split over the group by
        `layout` (`wcs.contact.distributed.Layout`; None: this process alone). Each process's
        subdomains are one local matrix of M (block diagonal), its local-to-global map their
        unknowns (repeated where subdomains share one), M's rows A's. Where the set-up with `OPTIONS`
        fails (a floating subdomain without primal vertices: module docstring) it is taken
        again with the faces' change of basis (`FACES`, counted in `faces`); SetupFailure where
        that fails too. PCBDDC records a local solver's failed factorization when it is first
        applied, not at its set-up: one application to a vector of ones tells (on a group, the
        worst of its ranks' reasons, so that all of them take the same way). A PETSc error in
        the set-up (MUMPS out of workspace for the deluxe scaling's Schur complements: error 76
        at 20 parts of 2.6e4 unknowns) is a failed set-up too."""
        why = ""
        for options in (OPTIONS, {**OPTIONS, **FACES}):
            try:
                ksp, M = self._build(A, options, PETSc, layout)
            except PETSc.Error as exc:
                why = f"PETSc error {exc.ierr}"
            else:
                x, y = A.createVecs()
                x.set(1.0)
                ksp.getPC().apply(x, y)
                for o in (x, y):
                    o.destroy()
                failed = int(ksp.getPC().getFailedReason())
                if layout is not None and layout.comm is not None:
                    from mpi4py import MPI
                    failed = layout.comm.allreduce(failed, op=MPI.MAX)
                if not failed:
                    return ksp, M
                why = f"PC failed reason {failed}"
                for o in (ksp, M):
                    o.destroy()
            self.faces += options is OPTIONS
        raise SetupFailure(f"BDDC's set-up failed ({why}), with and without the faces' change of basis")

    def _build(self, A, options, PETSc, layout):
        comm = PETSc.COMM_SELF if layout is None else layout.petsc
        sizes = A.getSizes()
        prefix = f"wcs_bddc{next(_PREFIX)}_"
        opts = PETSc.Options()
        for key, value in options.items():
            opts[prefix + key] = value
        held = np.concatenate(self.dofs) if self.dofs else np.zeros(0, dtype=int)
        lg = PETSc.LGMap().create(held.astype(PETSc.IntType), comm=comm)
        M = PETSc.Mat().create(comm=comm)
        M.setSizes(sizes)
        M.setType("is")
        M.setISAllowRepeated(True)
        M.setLGMap(lg, lg)
        local = _aij(sp.block_diag(self.local, format="csr"), PETSc)
        M.setISLocalMat(local)
        M.assemble()
        vecs = []
        if self.N is not None and self.N.shape[1]:
            Q, r, _ = sla.qr(np.asarray(self.N, dtype=float), mode="economic", pivoting=True)
            rank = int(np.sum(np.abs(np.diag(r)) > 1e-10 * abs(r[0, 0])))     # as GAMG's (`Krylov._build`)
            lo, hi = A.getOwnershipRange()
            vecs = [PETSc.Vec().createWithArray(Q[lo:hi, j].copy(), size=(hi - lo, sizes[0][1]), comm=comm)
                    for j in range(rank)]
            M.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=comm))
        ksp = PETSc.KSP().create(comm)
        ksp.setOptionsPrefix(prefix)
        ksp.setType("cg")
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.getPC().setType("bddc")
        held = self.components[held]
        fields = [PETSc.IS().createGeneral(np.flatnonzero(held == k).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
                  for k in np.unique(self.components)]
        ksp.getPC().setBDDCDofsSplittingLocal(fields)
        ksp.setOperators(A, M)
        ksp.setFromOptions()
        try:
            ksp.setUp()
        finally:
            for o in (local, lg, *vecs, *fields):
                o.destroy()
            for key in options:
                del opts[prefix + key]
        ksp.getPC().setReusePreconditioner(True)
        return ksp, M
