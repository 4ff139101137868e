"""The domain decomposition (wcs.dd) in 3D: `solver.method: dd` with `fallback: false` against
the monolithic solver on tetrahedral scenes (frictionless, Tresca with the disc, a body held by
the contact alone along z, the shipped 3D tunnel), the pairs' linearisation across a 3D slip,
and the CLI."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

import wcs
from wcs.dd import solver as dds

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"
STRICT = {"method": "dd", "tolerance": 1e-10, "fallback": False}


def study(name, solver, size=None):
    doc = yaml.safe_load((STUDIES / name).read_text())
    if size is not None:
        doc["scene"]["mesh"]["size"] = size
    doc["solver"] = solver
    return wcs.load_study(doc)


def assert_agree(a, b, rel=1e-6):
    """Same status, displacements and nodal contact forces λn, λt ((d − 1) m, both tangents) to
    `rel` relative: both stop at 1e-10, 1e-6 leaves the interface problem's conditioning 1e4
    (the 2D acceptance of tests/dd/test_method_dd.py)."""
    assert a.status == b.status == 0, b.message
    ca, cb = a.state.contact, b.state.contact
    assert cb.force_t.shape == ca.force_t.shape == (2 * ca.force_n.size,)
    for x, y in ((b.state.u, a.state.u), (cb.force_n, ca.force_n), (cb.force_t, ca.force_t)):
        assert np.linalg.norm(x - y) <= rel * max(np.linalg.norm(y), 1e-300) or not np.any(y) and not np.any(x)


def dd_and_monolithic(name, size, subdomains):
    mono = study(name, {"method": "monolithic", "tolerance": 1e-10}, size)
    dd = study(name, {**STRICT, "dd": {"subdomains": subdomains}}, size)
    return mono.evaluate(mono.nominal()), dd.evaluate(dd.nominal()), dd


def test_frictionless_block_held_by_the_contact_alone_along_z():
    """block-on-block-3d: the block's only free rigid motion (z) is held by the contact, so the
    partition keeps it whole in its pair; the patch test's pressure 2 MPa at every node."""
    a, b, dd = dd_and_monolithic("validation/block-on-block-3d.yaml", 0.25, 6)
    assert_agree(a, b)
    assert b.state.solver.startswith("dd: ") and "interface Newton converged in" in b.message
    model = dd._evaluator.model
    assert [m.shape[1] for m in model.free_modes.values()] == [0, 1]
    part = dds.decomposition(model, model.options).part
    block = model.smesh.bodies.index("block")
    assert np.all(np.isin(np.flatnonzero(model.smesh.cell_body == block),
                          np.flatnonzero(np.isin(part.subdomain, part.pairs[0]))))
    z = model.zone
    np.testing.assert_allclose(b.state.contact.force_n / z.weight, 2.0e6, rtol=1e-8)


def test_tresca_shear_patch_slips_on_the_disc():
    """tresca-shear-patch-3d: every contact node slips along x at the slip limit G = 0.3 MPa;
    dd and monolithic agree, λt is the limit along x on both tangents' components."""
    a, b, dd = dd_and_monolithic("validation/tresca-shear-patch-3d.yaml", 0.25, 6)
    assert_agree(a, b)
    z = dd._evaluator.model.zone
    lam_t = b.state.contact.force_t.reshape(2, -1)                      # (tangent, node)
    traction = np.einsum("jn,njd->nd", lam_t, z.tangents) / z.weight[:, None]
    np.testing.assert_allclose(np.linalg.norm(traction, axis=1), 3.0e5, rtol=1e-8)
    assert np.abs(traction[:, 0]).min() > 0.999 * 3.0e5                 # along x


def test_pair_linearised_across_a_3d_slip_is_the_derivative():
    """Interface Newton's J_k holds closed and stuck rows; a node slipping on the disc adds the
    stiffness across its slip, gw/|s| (`PairUnit.across_slip`). With it the pair's Schur
    complement is the derivative of S_p(V) (central differences, 1e-6), without it off by
    6e-4–3e-3 — and Newton on the patch needs 3 steps instead of 5 (linear convergence)."""
    s = study("validation/tresca-shear-patch-3d.yaml", {}, 0.25)
    model = s._evaluator.model
    c = model.nominal
    _, Kr, rhs, u0 = model.reduced_system(c, None)
    opts = {"tolerance": 1e-10, "dd": {"subdomains": 6}}
    res = dds.solve_dd(model, model.scene, Kr, rhs, u0, opts, coefficients=c)
    assert res.status == dds.DDOutcome.CONVERGED and res.info["newton"] <= 3, res.message     # 5 without
    z = model.zone
    d, bound = z.gap - z.Bn @ u0, c.slip * z.weight
    p = dds.decomposition(model, opts).pairs[0]
    V, rows = res.info["w"][p.dofs[p.B]], p.rows
    _, local = p.tresca(V, d[rows], bound[rows], 1e-12, 200)
    springs = p.across_slip()
    assert springs[0].size == rows.size                                # every node slips
    J = p.held_schur(np.flatnonzero(local.free), springs)
    J0 = p.held_schur(np.flatnonzero(local.free))
    rng = np.random.default_rng(0)
    for _ in range(2):
        dv = rng.standard_normal(V.size)
        h = 1e-4 * np.linalg.norm(V) / np.linalg.norm(dv)
        (gp, rp), (gm, rm) = (p.tresca(V + t * dv, d[rows], bound[rows], 1e-12, 200) for t in (h, -h))
        assert np.array_equal(rp.free, local.free) and np.array_equal(rm.free, local.free)
        fd = (gp - gm) / (2 * h)
        assert np.linalg.norm(J @ dv - fd) <= 1e-6 * np.linalg.norm(fd)
        assert np.linalg.norm(J0 @ dv - fd) >= 1e-4 * np.linalg.norm(fd)


@pytest.mark.slow
def test_hertz_3d_by_dual_mortar():
    """hertz-3d (3D dual mortar, the sphere held along z by the contact alone) at a coarse
    contact zone (h = 0.05, 2e3 unknowns): dd agrees with monolithic."""
    doc = yaml.safe_load((STUDIES / "validation/hertz-3d.yaml").read_text())
    for body in doc["scene"]["bodies"].values():
        body["mesh"]["refine"] = [{"ball": {"center": [0, 0, 0], "radius": 0.2}, "size": 0.05}]
    runs = []
    for solver in ({"method": "monolithic", "tolerance": 1e-10}, {**STRICT, "dd": {"subdomains": 6}}):
        doc["solver"] = solver
        s = wcs.load_study(doc)
        runs.append(s.evaluate(s.nominal()))
    assert s._evaluator.model.zone.discretization == ["mortar"]
    assert_agree(*runs)
    assert "interface Newton converged in" in runs[1].message


@pytest.mark.slow
def test_tunnel_fault_3d_at_its_nominal_data():
    """The shipped 3D tunnel (Tresca on the inclined fault, 1.9e4 unknowns) at its mesh: dd
    (8 subdomains) agrees with monolithic. Measured: interface Newton 6 steps, 86 PCG
    iterations, 10 PCG1 (10 steps, 141 PCG iterations without the springs across the slip)."""
    a, b, _ = dd_and_monolithic("tunnel-fault-3d.yaml", None, 8)
    assert_agree(a, b)
    assert "interface Newton converged in" in b.message


@pytest.mark.slow
def test_cli_runs_a_3d_study_by_the_decomposition(tmp_path):
    """`wcs run` at budget 2 with `solver.method: dd` (fallback false): every evaluation
    solved, the worst pressure that of the monolithic run."""
    doc = yaml.safe_load((STUDIES / "validation/block-on-block-3d.yaml").read_text())
    doc["scene"]["mesh"]["size"] = 0.25
    doc["search"] = {"budget": 2}
    out = {}
    for method in ("dd", "monolithic"):
        doc["solver"] = {**STRICT, "method": method, "dd": {"subdomains": 6}}
        path = tmp_path / f"{method}.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        nc = tmp_path / f"{method}.nc"
        run = subprocess.run([str(Path(sys.executable).with_name("wcs")), "run", str(path), "-o", str(nc), "--quiet",
                              "--no-mesh-check"], env={**os.environ, "PYTHONPATH": str(ROOT)},
                             capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr
        with xr.open_dataset(nc) as ds:
            assert (ds["status"].values == 0).all()
            out[method] = ds["worst_value"].values.copy()
    np.testing.assert_allclose(out["dd"], out["monolithic"], rtol=1e-6)


def test_a_decomposition_that_is_one_pair_solves_without_falling_back(capfd):
    """A scene so small that the partition keeps both bodies in one pair (the mortar patch:
    no interface DOFs, the DD is the pair's local contact solve): it solves with
    `fallback: false` and agrees with the monolithic solver. Before, the empty Neumann matrix
    went to LAPACK (`dpotrf` of order 0: info −4, and dsyrk printed "illegal value") and
    every evaluation fell back to monolithic."""
    dd = study("validation/mortar-patch-3d.yaml", STRICT)
    from wcs.model.evaluation import Evaluator
    ev = Evaluator(dd)
    assert dds.decomposition(ev.model, ev.model.options).nif == 0
    got = ev.evaluate(dd.nominal())
    mono = study("validation/mortar-patch-3d.yaml", {"method": "monolithic", "tolerance": 1e-10})
    assert got.message.startswith("solved (dd:"), got.message
    assert_agree(mono.evaluate(mono.nominal()), got)
    assert "illegal value" not in capfd.readouterr().err
