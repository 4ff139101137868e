"""Nonmatching meshes: dual mortar contact and mortar gluing.

Patch tests (contact and glue) on nonmatching meshes, Hertz with a fine
cylinder on a coarse block, the seed's mortar Poisson example ([33]) with its
O(h) H¹ convergence, agreement with node-to-node on matching meshes, and the
plumbing: per-body mesh sizes, criteria, adjoint gradients, the results file."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
import skfem
import xarray as xr
import yaml
from skfem.models.poisson import laplace, unit_load

import wcs
from wcs.cli import main
from wcs.contact.mortar import sides_match
from wcs.geometry.mortar import mortar_integrals
from wcs.fem.gluing import build_glue, substitution
from wcs.scene.mesher2d import build_mesh

from tests.support.scenes import VALIDATION, load, solve, typed_scene  # noqa: F401 - shared scene helpers




# ---------------------------------------------------------------- the operator itself


def _two_sides(hs, hm, curved=False):
    scene = {"mesh": {"size": 0.5},                 # unused: each body has its own size
             "bodies": {"s": {"mesh": {"size": hs}, "regions": [{"material": "m", "shape": {"rectangle": [0, 1, 2, 1.5]}}]},
                        "m": {"mesh": {"size": hm}, "regions": [{"material": "m", "shape": {"rectangle": [0, 0, 2, 1]}}]}},
             "boundaries": {"S": {"body": "s", "segment": [[0, 1], [2, 1]]},
                            "M": {"body": "m", "segment": [[0, 1], [2, 1]]}}}
    sm = build_mesh(typed_scene(scene))
    return sm, sm.boundaries["S"], sm.boundaries["M"]


def test_dual_basis_is_biorthogonal_and_rows_reproduce_affine_fields():
    sm, S, M = _two_sides(0.13, 0.05)
    mi = mortar_integrals(sm.mesh, S, M)
    p = sm.mesh.p
    # every row: 1 on its slave node, the master coefficients sum to -1 (affine reproduction)
    assert np.allclose(mi.C.sum(axis=1), 0.0, atol=1e-13)
    assert np.allclose(mi.C @ p.T, 0.0, atol=1e-13)                  # coincident flat sides: no gap
    # D_jj is the tributary length (full coverage), sum = side length
    assert mi.D.sum() == pytest.approx(2.0, rel=1e-13)
    assert np.allclose(mi.normal, [0.0, -1.0])
    assert mi.dropped.size == 0 and not sides_match(sm.mesh, S, M)


def test_region_mesh_size():
    scene = {"mesh": {"size": 0.2},
             "bodies": {"b": {"regions": [
                 {"material": "m", "name": "coarse", "shape": {"rectangle": [0, 0, 1, 1]}},
                 {"material": "m", "name": "fine", "mesh": {"size": 0.05}, "shape": {"rectangle": [1, 0, 2, 1]}}]}}}
    sm = build_mesh(typed_scene(scene))
    n = np.bincount(sm.cell_region)
    assert n[1] > 4 * n[0]            # (0.2 / 0.05)² = 16 far from the interface; the coarse side grades


def test_per_body_sizes_make_nonmatching_sides():
    sm, S, M = _two_sides(0.3, 0.1)
    ns = np.unique(sm.mesh.facets[:, S]).size
    nm = np.unique(sm.mesh.facets[:, M]).size
    assert nm > 2 * ns                                                 # 1:3 sizes, nodes not shared
    sm2, S2, M2 = _two_sides(0.1, 0.1)
    assert not sides_match(sm.mesh, S, M)


# ---------------------------------------------------------------- contact patch test


@pytest.mark.parametrize("ratio", [3, 7])
@pytest.mark.parametrize("coarse", ["block", "base"])
def test_patch_test_on_nonmatching_meshes(ratio, coarse):
    fine = "base" if coarse == "block" else "block"

    def sizes(disc):
        def edit(doc):
            doc["scene"]["bodies"][fine]["mesh"] = {"size": 0.03}
            doc["scene"]["bodies"][coarse]["mesh"] = {"size": 0.03 * ratio}
            doc["scene"]["contacts"]["interface"]["discretization"] = disc
        return edit
    _, ev = solve("mortar-patch", sizes("auto"))
    c = ev.state.contact
    assert c.zone.discretization == ["mortar"]                       # auto: the sides do not match
    err_mortar = np.max(np.abs(c.pressure / 1.0e6 - 1.0))
    assert err_mortar <= 1e-8
    assert ev.phi["pressure"] == pytest.approx(1.0e6, rel=1e-10)      # Φ6 with the mortar weights
    assert c.weight.sum() == pytest.approx(2.0, rel=1e-12)
    _, ev_ns = solve("mortar-patch", sizes("node-to-node"))
    err_nts = np.max(np.abs(ev_ns.state.contact.pressure / 1.0e6 - 1.0))
    print(f"ratio 1:{ratio}, coarse {coarse}: mortar {err_mortar:.2e}, node-to-segment {err_nts:.2e}")
    assert err_nts > 5e-4 and err_nts > 1e4 * max(err_mortar, 1e-16)


# ---------------------------------------------------------------- Hertz, fine cylinder on a coarse block


HERTZ = dict(E=2.0e11, nu=0.3, R=1.0, p_top=1.0786e8)


def hertz_errors(h):
    def edit(doc):
        doc["scene"]["bodies"]["cylinder"]["mesh"]["refine"][0]["size"] = h
        doc["scene"]["bodies"]["block"]["mesh"]["refine"][0]["size"] = 3 * h
    _, ev = solve("hertz-mortar", edit)
    c = ev.state.contact
    assert c.zone.discretization == ["mortar"]
    P = 2 * HERTZ["p_top"] * HERTZ["R"]
    Es = HERTZ["E"] / (2 * (1 - HERTZ["nu"] ** 2))
    a = np.sqrt(4 * P * HERTZ["R"] / (np.pi * Es))
    p0 = 2 * P / (np.pi * a)
    x, F = c.zone.coords[:, 0], c.force_n
    width = 2 * np.sqrt((x**2 * F).sum() / F.sum())
    assert 2 * F.sum() == pytest.approx(P, rel=1e-9)          # normals of a flat master: vertical
    return c.pressure.max() / p0 - 1, width / a - 1


def test_hertz_fine_cylinder_on_coarse_block():
    # cylinder h = a/12, a/25 in the contact zone; block 3x coarser
    coarse, fine = hertz_errors(0.004), hertz_errors(0.002)
    print(f"Hertz mortar: coarse peak {coarse[0]:+.4f} width {coarse[1]:+.4f}; "
          f"fine peak {fine[0]:+.4f} width {fine[1]:+.4f}")
    assert max(map(abs, fine)) < 0.03
    assert abs(fine[0]) < abs(coarse[0]) and abs(fine[1]) < abs(coarse[1])


# ---------------------------------------------------------------- matching meshes


@pytest.mark.parametrize("name", ["contact-patch", "tresca-pad", "gap-closing", "stacked-layers"])
def test_mortar_equals_node_to_node_on_matching_meshes(name):
    evs = {}
    for disc in ("mortar", "node-to-node"):
        def edit(doc):
            for c in doc["scene"]["contacts"].values():
                c["discretization"] = disc
        _, evs[disc] = solve(name, edit)
    a, b = evs["mortar"].state, evs["node-to-node"].state
    assert a.contact.zone.discretization[0] == "mortar"
    scale = np.abs(b.u).max()
    assert np.abs(a.u - b.u).max() <= 1e-10 * scale
    np.testing.assert_array_equal(a.contact.nodes, b.contact.nodes)
    pscale = max(np.abs(b.contact.pressure).max(), 1.0)
    assert np.abs(a.contact.pressure - b.contact.pressure).max() <= 1e-10 * pscale
    assert np.abs(a.contact.zone.weight - b.contact.zone.weight).max() <= 1e-12
    assert np.abs(a.contact.zone.gap - b.contact.zone.gap).max() <= 1e-12
    for k in evs["node-to-node"].phi:
        assert evs["mortar"].phi[k] == pytest.approx(evs["node-to-node"].phi[k], rel=1e-10, abs=1e-300)


# ---------------------------------------------------------------- gluing


def test_glued_bodies_on_nonmatching_meshes_reproduce_the_closed_form():
    study, ev = solve("glued-mortar")
    s = ev.state.stress
    np.testing.assert_allclose(s[1], -1.0e6, rtol=1e-8)
    assert np.abs(s[3]).max() <= 1e-6 * 1.0e6
    lam_mu = lambda E, nu: E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))        # noqa: E731  λ + 2μ
    settle = 0.3 * 1e6 / lam_mu(3.0e10, 0.2) + 0.2 * 1e6 / lam_mu(2.1e11, 0.3)
    assert ev.phi["settlement"] == pytest.approx(settle, rel=1e-10)
    sm = build_mesh(study.scene)
    slave = np.unique(sm.mesh.facets[:, sm.boundaries["hard_bottom"]])
    master = np.unique(sm.mesh.facets[:, sm.boundaries["soft_top"]])
    assert master.size > 2 * slave.size                                   # really nonmatching


def test_glue_holds_a_body_without_supports():
    """A body held only by a glue is not 'floating': the glued cluster is held."""
    def edit(doc):
        doc["scene"]["supports"] = {"bottom": {"u": [0.0, 0.0]}}
        doc["scene"]["boundaries"]["bottom"]["body"] = "soft"
    _, ev = solve("glued-mortar", edit)
    assert ev.phi["settlement"] > 0


def test_glue_conducts_heat():
    """Two bodies glued on a nonmatching interface, hot bottom, cold top: linear temperature."""
    def edit(doc):
        sc = doc["scene"]
        for m in sc["materials"].values():
            m.update(conductivity=2.0, expansion=0.0)
        sc["thermal"] = {"reference": 293.0, "temperature": {"bottom": 373.0, "top": 273.0}}
        doc["criteria"] = [{"name": "t", "kind": "mean_temperature", "regions": ["soft_layer"]}]
    _, ev = solve("glued-mortar", edit)
    T, y = ev.state.T, ev.fields["coords"].values[:, 1]
    np.testing.assert_allclose(T, 373.0 - 200.0 * y, atol=1e-8)


# ---------------------------------------------------------------- the seed's mortar Poisson example


def _poisson_scene(hs, one_body=False):
    """The square (0,2)² as an L of three independently meshed subdomains (a geometrically
    nonconforming partition, seed [33] Fig. 2/5): A = (0,1)×(0,2), B = (1,2)×(0,1),
    C = (1,2)×(1,2); A's right side faces B and C (T-junction), C sits on B.
    −Δu = 30, u = 0 on x = 0 (Γ0), u = 1 on x = 2 (Γ1), no flux elsewhere."""
    sq = lambda x0, y0, x1, y1: {"rectangle": [x0, y0, x1, y1]}      # noqa: E731
    if one_body:
        bodies = {"all": {"regions": [{"material": "m", "shape": sq(0, 0, 2, 2)}]}}
        glue, extra = {}, {}
    else:
        bodies = {"A": {"mesh": {"size": hs[0]}, "regions": [{"material": "m", "shape": sq(0, 0, 1, 2)}]},
                  "B": {"mesh": {"size": hs[1]}, "regions": [{"material": "m", "shape": sq(1, 0, 2, 1)}]},
                  "C": {"mesh": {"size": hs[2]}, "regions": [{"material": "m", "shape": sq(1, 1, 2, 2)}]}}
        extra = {"A_right": {"body": "A", "segment": [[1, 0], [1, 2]]},
                 "B_left": {"body": "B", "segment": [[1, 0], [1, 1]]},
                 "C_left": {"body": "C", "segment": [[1, 1], [1, 2]]},
                 "B_top": {"body": "B", "segment": [[1, 1], [2, 1]]},
                 "C_bottom": {"body": "C", "segment": [[1, 1], [2, 1]]}}
        glue = {"g1": {"slave": "B_left", "master": "A_right"},
                "g2": {"slave": "C_left", "master": "A_right"},
                "g3": {"slave": "C_bottom", "master": "B_top"}}
    bnd = {"left": {"segment": [[0, 0], [0, 2]]}, "right": {"segment": [[2, 0], [2, 2]]}, **extra}
    return typed_scene({"mesh": {"size": min(hs)}, "bodies": bodies, "boundaries": bnd, "glue": glue})


def _poisson(scene):
    sm = build_mesh(scene)
    m = sm.mesh
    basis = skfem.Basis(m, skfem.ElementTriP1())
    K = laplace.assemble(basis)
    f = 30.0 * unit_load.assemble(basis)
    d0 = np.unique(m.facets[:, sm.boundaries["left"]])
    d1 = np.unique(m.facets[:, sm.boundaries["right"]])
    fixed = np.union1d(d0, d1)
    P, slave = substitution(build_glue(scene, sm, fixed), m.nvertices, 1)   # u = P v (weak continuity)
    keep = np.setdiff1d(np.arange(m.nvertices), slave)
    P = P[:, keep]
    free = np.setdiff1d(np.arange(keep.size), np.searchsorted(keep, fixed))
    v = np.zeros(keep.size)
    v[np.searchsorted(keep, d1)] = 1.0
    Pf = P[:, free]
    v[free] = spla.spsolve((Pf.T @ K @ Pf).tocsc(), Pf.T @ (f - K @ (P @ v)))
    return sm, P @ v


def _cell_gradients(m, u):
    x, y, t = m.p[0, m.t], m.p[1, m.t], m.t
    det = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0])
    du1, du2 = u[t[1]] - u[t[0]], u[t[2]] - u[t[0]]
    g = np.stack([(du1 * (y[2] - y[0]) - du2 * (y[1] - y[0])) / det,
                  (-du1 * (x[2] - x[0]) + du2 * (x[1] - x[0])) / det])
    return g, 0.5 * np.abs(det)


def _locate(m, X, k=12):
    """Cell of the mesh `m` holding each point X (2, n) (the most-inside of k candidates)."""
    from scipy.spatial import cKDTree
    _, cand = cKDTree(m.p[:, m.t].mean(axis=1).T).query(X.T, k=k)
    best, score = np.zeros(X.shape[1], dtype=np.int64), np.full(X.shape[1], -np.inf)
    for j in range(k):
        c = cand[:, j]
        a, b, d = (m.p[:, m.t[i, c]] for i in range(3))
        det = (b[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (b[1] - a[1])
        l1 = ((X[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (X[1] - a[1])) / det
        l2 = ((b[0] - a[0]) * (X[1] - a[1]) - (X[0] - a[0]) * (b[1] - a[1])) / det
        s = np.minimum(np.minimum(l1, l2), 1 - l1 - l2)
        better = s > score
        best[better], score[better] = c[better], s[better]
    return best


def _h1_error(sm, u, ref, uref, n=3):
    """|u − u_ref|_H¹: both gradients are piecewise constant; sampled on a barycentric
    lattice of n(n+1)/2 + n(n−1)/2 = n² equal-area subtriangles of every cell of `sm`."""
    g, area = _cell_gradients(sm.mesh, u)
    gr, _ = _cell_gradients(ref.mesh, uref)
    pts = [((i + 1 / 3) / n, (j + 1 / 3) / n) for i in range(n) for j in range(n - i)]
    pts += [((i + 2 / 3) / n, (j + 2 / 3) / n) for i in range(n) for j in range(n - i - 1)]
    t, p = sm.mesh.t, sm.mesh.p
    err = 0.0
    for l1, l2 in pts:
        X = p[:, t[0]] * (1 - l1 - l2) + p[:, t[1]] * l1 + p[:, t[2]] * l2
        d = g - gr[:, _locate(ref.mesh, X)]
        err += np.sum(area / len(pts) * (d**2).sum(axis=0))
    return np.sqrt(err)


def test_mortar_poisson_example_converges_as_h():
    ref, uref = _poisson(_poisson_scene([0.01] * 3, one_body=True))      # conforming, fine
    hs, errs = [0.2, 0.1, 0.05], []
    for h in hs:
        sm, u = _poisson(_poisson_scene([h, h / 2.3, h / 3.7]))             # three nonmatching meshes
        errs.append(_h1_error(sm, u, ref, uref))
        # weak continuity, not pointwise: but the jump is small and the solution sane
        assert -1e-9 <= u.min() and u.max() <= 16.0
    rates = np.log(np.array(errs[:-1]) / errs[1:]) / np.log(2)
    print("Poisson mortar: H1 errors", errs, "rates", rates)
    assert np.all(np.abs(rates - 1.0) <= 0.15), rates


# ---------------------------------------------------------------- plumbing: gradients, results file


def test_gradients_on_a_mortar_scene():
    from tests.model.test_gradients import TOL, check_against_fd

    def edit(doc):
        doc["solver"] = {"method": "monolithic", "tolerance": TOL}
        # Tresca friction and a tangential pull so that the tangential rows matter too
        doc["scene"]["contacts"]["interface"]["friction"] = {"slip_limit": 2.0e5}
        doc["scene"]["loads"]["block_top"] = {"traction": [1.0e5, -1.0e6]}
        doc["scene"]["supports"].pop("block_left")
        doc["scene"]["boundaries"]["block_right"] = {"segment": [[2.0, 1.0], [2.0, 1.6]]}
        doc["scene"]["supports"]["block_right"] = {"u": [0.0, None]}
        doc["scene"]["regions_of_interest"]["edge"] = {"box": [1.2, 0.99, 1.8, 1.01]}
        doc["uncertain"] = {"loads.block_top.traction.0": [0.5e5, 1.5e5],
                            "loads.block_top.traction.1": [-1.2e6, -0.8e6],
                            "materials.soft.E": [0.8e9, 1.2e9],
                            "contacts.interface.friction.slip_limit": [1.5e5, 2.5e5]}
        doc["criteria"] = [{"name": "pressure", "kind": "contact_pressure", "regions": ["edge"]},
                           {"name": "settlement", "kind": "mean_normal_displacement", "regions": ["top"],
                            "direction": [0.0, -1.0]}]
    study = load("mortar-patch", edit)
    worst = check_against_fd(study)
    print(f"mortar scene: worst relative gradient error {worst:.2e}")
    assert worst < 1e-5


def test_solve_writes_the_mortar_contact_to_the_results_file(tmp_path, capsys):
    out = tmp_path / "mp.nc"
    code = main(["solve", str(VALIDATION / "mortar-patch.yaml"), "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert set(ds["contact_pair"].values) == {"interface"}
        np.testing.assert_allclose(ds["contact_pressure"].values, 1.0e6, rtol=1e-8)


def test_study_schema_for_mortar_and_glue():
    from wcs.errors import StudyError

    def bad(edit):
        with pytest.raises(StudyError) as e:
            load("glued-mortar", edit)
        return str(e.value)
    assert "discretization" in bad(lambda d: d["scene"].__setitem__(
        "contacts", {"c": {"slave": "soft_top", "master": "hard_bottom", "discretization": "nts"}}))
    assert "glue" in bad(lambda d: d["scene"]["glue"]["interface"].__setitem__("master", "nowhere"))
    assert "glued" in bad(lambda d: d["scene"].__setitem__(
        "contacts", {"c": {"slave": "hard_bottom", "master": "soft_top"}}))
    assert "size" in bad(lambda d: d["scene"]["bodies"]["soft"].__setitem__("mesh", {"size": -1}))
    assert "boundary" in bad(lambda d: d["scene"]["bodies"]["soft"].__setitem__(
        "mesh", {"refine": [{"boundary": "nowhere", "size": 0.01}]}))
