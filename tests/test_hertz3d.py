"""3D contact solved with the dual mortar rows (issue 13, item 3): the nonmatching block-on-block
patch test and Hertz (a sphere on a block, frictionless), each with the plain node-to-surface
projection beside it — built here only as the baseline that shows why mortar is needed.

The solve is a minimal direct one: P1 tetrahedra (`wcs.fem.affine`), supports eliminated, the
contact solver `wcs.contact.solver.solve_contact` on the rows. Hertz uses a quarter model
(rollers on x = 0 and y = 0) of the lower quarter-hemisphere of radius R on a quarter block,
meshed by gmsh with a size field graded from the contact point (the 3D study format has no
refinement zones yet), the load P/4 as a uniform pressure on the hemisphere's flat top (the
sphere is held in z by the contact alone: a rigid mode of the solve).

Hertz ([Johnson, Contact Mechanics, §4.2]): a = (3PR / 4E*)^{1/3}, p0 = 3P / (2πa²),
p(r) = p0 √(1 − r²/a²), 1/E* = 2(1 − ν²)/E for two bodies of one material. The FE contact
radius is the a of the least-squares fit of p² = p0² − (p0/a)² r² to the nodal pressures at
r ≤ 0.7 a (the profile is smooth there; the edge is resolved only to h)."""
import gmsh
import numpy as np
import pytest
import scipy.sparse as sp

from wcs.contact.mortar3d import jump_rows, mortar_integrals3d, oriented_facets, tangents, triangle_normals
from wcs.contact.solver import solve_contact
from wcs.fem.affine import CellAffineOperator, elastic_cell_matrices
from wcs.scene.mesher3d import build_mesh3d
from wcs.scene.session import Session
from wcs.study import load_scene

E, NU = 1.0, 0.3
LAM, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))


# ---------------------------------------------------------------- rows and a direct solve


def mortar_rows(x, slave_tri, master_tri):
    """(Bn, Bt, gap, weight, slave) of the dual mortar (`wcs.contact.mortar3d`)."""
    mi = mortar_integrals3d(x, slave_tri, master_tri)
    C = mi.C
    n = mi.normal
    return _rows(C, n, -np.einsum("ij,ij->i", C @ x, n), mi.D, mi.slave)


def node_to_surface_rows(x, slave_tri, master_tri):
    """The baseline: each slave node projected along the master normal onto the master triangle
    that contains it (the nearest if several), weight = its tributary area (a third of its
    slave triangles), row u_j − Σ_l φ^m_l(y_j) u_l along the master normal."""
    snodes, loc = np.unique(slave_tri, return_inverse=True)
    _, sarea = triangle_normals(x, slave_tri)
    weight = np.bincount(loc.ravel(), np.repeat(sarea / 3, 3), snodes.size)
    mn, _ = triangle_normals(x, master_tri)
    xm = x[master_tri]                                             # (M, 3, 3)
    rows, cols, vals, normal, keep = [], [], [], [], []
    for j, s in enumerate(snodes):
        d = np.einsum("mi,mi->m", x[s] - xm[:, 0], mn)             # signed distance to each plane
        y = x[s] - d[:, None] * mn
        T = np.stack([xm[:, 1] - xm[:, 0], xm[:, 2] - xm[:, 0]], axis=2)       # (M, 3, 2)
        l12 = np.einsum("mij,mj->mi", np.linalg.pinv(T), y - xm[:, 0])        # (M, 2)
        bary = np.column_stack([1 - l12.sum(axis=1), l12])
        inside = np.flatnonzero((bary >= -1e-9).all(axis=1) & (np.abs(d) < 0.5))
        if inside.size == 0:
            continue
        f = inside[np.argmin(np.abs(d[inside]))]
        keep.append(j)
        normal.append(-mn[f])
        r = len(keep) - 1
        rows += [r] * 4
        cols += [s, *master_tri[f]]
        vals += [1.0, *(-bary[f])]
    keep = np.asarray(keep)
    C = sp.csr_matrix((vals, (rows, cols)), shape=(keep.size, x.shape[0]))
    n = np.asarray(normal)
    return _rows(C, n, -np.einsum("ij,ij->i", C @ x, n), weight[keep], snodes[keep])


def _rows(C, n, gap, weight, slave):
    class P:                                   # the fields jump_rows reads
        pass
    P.C, P.normal, P.tangent = C, n, tangents(n)
    Bn, Bt = jump_rows(P)
    return Bn, Bt, gap, weight, slave


def direct_solve(x, t, fixed, force, rows, rigid=None):
    """u and λn of P1 elasticity (E, ν) on tets t with the DOFs `fixed` held at 0, nodal forces
    `force` (3n,), frictionless contact on `rows`; `rigid` (3n, r) the rigid modes left free."""
    ndof = 3 * x.shape[0]
    K = CellAffineOperator(t, x.shape[0], elastic_cell_matrices(x.T, t), np.zeros(t.shape[1], int))([[LAM, MU]])
    free = np.setdiff1d(np.arange(ndof), fixed)
    Bn, Bt, gap, w, _ = rows
    R = None if rigid is None else rigid[free]
    res = solve_contact(K[free][:, free], force[free], Bn[:, free], Bt[:, free], gap, w, R=R)
    assert res.status == 0, res.message
    u = np.zeros(ndof)
    u[free] = res.u
    return u, res.lam_n


# ---------------------------------------------------------------- patch test


def blocks(size_lower, size_upper):
    scene = {"dimension": 3, "materials": {"m": {"E": E, "nu": NU}},
             "bodies": {"lower": {"regions": [{"material": "m", "shape": {"box": [0, 0, -0.5, 1, 1, 0]}}],
                                  "mesh": {"size": size_lower}},
                        "upper": {"regions": [{"material": "m", "shape": {"box": [0, 0, 0, 1, 1, 0.5]}}],
                                  "mesh": {"size": size_upper}}},
             "boundaries": {"top": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "body": "lower"},
                            "bottom": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}, "body": "upper"}},
             "mesh": {"size": size_lower}}
    return build_mesh3d(load_scene(scene))


def patch(rows_of, slave, master, sm):
    """Pressed by u_z = −δ on z = 0.5, held by u_z = 0 on z = −0.5, rollers on x = 0 and y = 0:
    uniaxial stress, the contact pressure p = E δ / 1 on every node. Returns p_j / p − 1."""
    mesh = sm.mesh
    x = mesh.p.T
    delta = 1e-3
    fixed = np.concatenate([3 * np.flatnonzero(np.abs(x[:, 0]) < 1e-12),
                            3 * np.flatnonzero(np.abs(x[:, 1]) < 1e-12) + 1,
                            3 * np.flatnonzero(np.abs(np.abs(x[:, 2]) - 0.5) < 1e-12) + 2])
    top = np.flatnonzero(np.abs(x[:, 2] - 0.5) < 1e-12)
    # the prescribed u_z = −δ on top as a load on the free DOFs: f = −K[:, top] (−δ)
    K = CellAffineOperator(mesh.t, x.shape[0], elastic_cell_matrices(mesh.p, mesh.t),
                           np.zeros(mesh.t.shape[1], int))([[LAM, MU]])
    ub = np.zeros(3 * x.shape[0])
    ub[3 * top + 2] = -delta
    rows = rows_of(x, oriented_facets(mesh, sm.boundaries[slave]), oriented_facets(mesh, sm.boundaries[master]))
    Bn, Bt, gap, w, s = rows
    u, lam = direct_solve(x, mesh.t, fixed, -(K @ ub), (Bn, Bt, gap - Bn @ ub, w, s))
    return lam / w / (E * delta) - 1.0


@pytest.mark.parametrize("slave, master", [("bottom", "top"), ("top", "bottom")])
def test_patch_nonmatching_mortar_uniform(slave, master):
    """Block on block meshed 1:3 (the upper finer), either side slave: the dual mortar pressure
    is uniform and exact to 1e-8 on every slave node; the node-to-surface projection on the same
    meshes is not (its nodal forces are tributary areas, not the consistent ∫φ of the master)."""
    sm = blocks(0.25, 0.25 / 3)
    err = patch(mortar_rows, slave, master, sm)
    assert np.abs(err).max() < 1e-8
    nts = patch(node_to_surface_rows, slave, master, sm)
    assert np.abs(nts).max() > 1e-3
