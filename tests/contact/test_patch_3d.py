"""3D node-to-node contact on matching faces: the patch test, a Tresca shear patch with its
closed form, and the monolithic semismooth Newton against the cvxpy second-order-cone reference.

Tolerances: in the two patches the exact solution is piecewise linear (uniform stress in each
block, a uniform slip jump), so P1 with node-to-node rows reproduces it to round-off (1e-8
and 1e-6 relative leave orders of magnitude for the conditioning of a few thousand unknowns
and the Newton tolerance 1e-10). The cvxpy reference (Clarabel, gaps 1e-12) agrees with the
Newton to 1e-6 relative: the brief's tolerance, above both solvers' stopping tests.
"""
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from wcs.cli import main
from wcs.contact.qp import solve_contact_qp
from wcs.model.evaluation import Evaluator
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
PATCH = ROOT / "studies" / "validation" / "block-on-block-3d.yaml"


def solve(d):
    ev = Evaluator(load_study(d))
    res = ev.evaluate(ev.study.nominal())
    assert res.status == 0, res.message
    return ev, res


def test_the_3d_contact_patch_passes_the_pressure_uniformly():
    """Rollers, frictionless matching faces, two materials: τ_zz = −p in both blocks and the
    contact pressure is p at every contact node; the block is held only by the contact along z."""
    d = yaml.safe_load(PATCH.read_text())
    p = float(d["scene"]["loads"]["block_top"]["pressure"])
    ev, res = solve(d)
    c = res.state.contact
    assert ev.model.zone.discretization == ["node-to-node"]
    assert [m.shape[1] for _, m in ev.model.floating] == [1]        # the block's z-translation
    assert len(c.pressure) == len(np.unique(ev.smesh.boundary_nodes("block_bottom")))
    assert np.abs(c.pressure - p).max() < 1e-8 * p
    assert np.abs(c.gap).max() < 1e-8 * p / 5e9
    s = res.state.stress
    assert np.abs(s[2] + p).max() < 1e-8 * p
    assert np.abs(np.delete(s, 2, axis=0)).max() < 1e-8 * p
    assert c.weight.sum() == pytest.approx(1.0, rel=1e-12)          # tributary areas: the face
    fields = res.fields
    assert fields["contact_coords"].shape == (len(c.pressure), 3)
    assert fields["contact_tangents"].shape == (len(c.pressure), 2, 3)
    assert fields["contact_shear"].dims == ("contact_node", "tangent")


def test_a_slave_face_larger_than_its_master_keeps_the_nodes_on_the_master_face():
    """The base's whole top as the slave under a block of a quarter of its area: the slave nodes
    off the block are dropped, the tributary areas add up to the block's face, and the contact
    transmits the load on the block."""
    d = yaml.safe_load(PATCH.read_text())
    scene = d["scene"]
    scene["bodies"]["block"]["regions"][0]["shape"]["box"] = [0, 0, 0, 0.5, 0.5, 0.5]
    scene["contacts"]["interface"] = {"slave": "base_top", "master": "block_bottom"}
    ev, res = solve(d)
    z = ev.model.zone
    x = ev.smesh.mesh.p
    kept, dropped = z.pairs[0].slave, z.pairs[0].dropped
    assert np.all(x[:2, kept] <= 0.5 + 1e-12) and np.all(x[:2, dropped].max(axis=0) > 0.5)
    assert z.weight.sum() == pytest.approx(0.25, rel=1e-12)
    assert res.state.contact.force_n.sum() == pytest.approx(float(scene["loads"]["block_top"]["pressure"]) * 0.25,
                                                            rel=1e-10)


SHEAR = ROOT / "studies" / "validation" / "tresca-shear-patch-3d.yaml"
E_BASE, E_BLOCK, G, P, DELTA, H = 2.0e10, 5.0e9, 3.0e5, 1.0e6, 1.0e-3, 0.5      # the numbers of SHEAR


def shear_patch(**friction) -> dict:
    """SHEAR (its comment gives the closed form), with another friction law if given."""
    d = yaml.safe_load(SHEAR.read_text())
    if friction:
        d["scene"]["contacts"]["interface"]["friction"] = friction
    return d


def test_the_tresca_shear_patch_is_the_closed_form():
    """Slip s = δ − γ_block H − γ_base H (γ = G/μ), contact pressure P, shear G along the slip on
    every node; the friction force on the slave (−τ_t, wcs's τ_t being the multiplier λt/w, the
    force the slave exerts on the master) is opposite to its slip."""
    ev, res = solve(shear_patch())
    c = res.state.contact
    mu_base, mu_block = E_BASE / 2, E_BLOCK / 2
    slip = DELTA - G / mu_block * H - G / mu_base * H
    tangents = ev.model.zone.tangents
    assert np.array_equal(tangents[:, 0], np.tile([1.0, 0.0, 0.0], (len(c.pressure), 1)))
    s, tau = c.by_node(c.slip), c.shear                                 # (m, 2) along the two tangents
    assert np.abs(c.pressure - P).max() < 1e-6 * P
    assert np.abs(s - [slip, 0.0]).max() < 1e-6 * slip
    assert np.abs(tau - [G, 0.0]).max() < 1e-6 * G
    assert np.all(res.state.raw.active == 2)                            # every node slips
    assert np.linalg.norm(tau, axis=1) == pytest.approx(G, rel=1e-6)    # |τ_t| = g where it slips
    cos = np.einsum("ij,ij->i", -tau, s) / (np.linalg.norm(tau, axis=1) * np.linalg.norm(s, axis=1))
    assert np.all(cos < -1 + 1e-9)                                      # friction on the slave opposes the slip
    stress = res.state.stress
    assert np.abs(stress[2] + P).max() < 1e-6 * P and np.abs(stress[4] - G).max() < 1e-6 * G


def floating(friction) -> dict:
    """A block lying free on a clamped base (held only by the contact along z and by friction in
    its plane: all six rigid motions of the block free), pressed and sheared by a tilted traction,
    materials of different Poisson ratios so that the edges slip first."""
    d = shear_patch(**friction)
    scene = d["scene"]
    d["uncertain"] = {"loads.block_top_load.traction.2": [-1.5e6, -0.5e6]}
    d["criteria"] = [{"name": "pressure", "kind": "contact_pressure", "regions": ["interface"]}]
    scene["materials"] = {"base": {"E": 2.0e10, "nu": 0.1}, "block": {"E": 5.0e9, "nu": 0.4}}
    scene["supports"] = {"base_bottom": {"u": [0.0, 0.0, 0.0]}}
    scene["loads"] = {"block_top_load": {"traction": [2.0e5, -1.0e5, -P]}}
    return d


@pytest.mark.parametrize("friction", [{"slip_limit": 3.0e5}, {"coefficient": 0.3}], ids=["tresca", "coulomb"])
def test_the_newton_agrees_with_the_cvxpy_socp_on_a_floating_block(friction):
    """The model's reduced system solved by the model (the semismooth Newton, from its first
    step: the block has all six rigid motions free) and by the SOCP reference at Clarabel
    tolerance 1e-12 (its own error floors near 1e-8 there)."""
    ev, res = solve(floating(friction))
    model, c = ev.model, res.state.coefficients
    assert [m.shape[1] for _, m in model.floating] == [6]
    z = model.zone
    _, Kr, rhs, u0 = model.reduced_system(c, None)
    ref = solve_contact_qp(Kr, rhs, model.Bn_r, model.Bt_r, z.gap - z.Bn @ u0, z.weight, g=c.slip,
                           F=c.coulomb if c.coulomb.any() else None, tol=1e-12)
    a = res.state.raw
    active = a.active
    assert (active == 2).any() and (active == 1).any()                  # a partial slip: a real test
    scale = np.abs(ref.lam_n).max()
    assert np.abs(a.lam_n - ref.lam_n).max() < 1e-6 * scale
    assert np.abs(a.lam_t - ref.lam_t).max() < 1e-6 * scale
    assert np.abs(a.u - ref.u).max() < 1e-6 * np.abs(ref.u).max()
    # the friction holds the block's in-plane load: Σ λt along x, y = the applied shear (Coulomb:
    # to 10 × the fixed point's tolerance 1e-8, as tests/contact/test_solver_3d.py bounds its slip limits)
    st = res.state.contact
    tangential = np.einsum("ik,ikj->j", st.by_node(st.force_t), z.tangents)
    assert tangential[:2] == pytest.approx([2.0e5, -1.0e5], rel=1e-7 if "coefficient" in friction else 1e-10)


def test_wcs_run_and_report_of_the_3d_patch(tmp_path):
    """`wcs run` of a 3D contact study end to end, then `wcs report`: the worst contact pressure
    and the worst von Mises stress in the base are both the largest pressure on the top (the
    patch passes it uniformly), found at that end of its range."""
    d = yaml.safe_load(PATCH.read_text())
    d["search"] = {"budget": 8}
    d["scene"]["mesh"]["size"] = 0.25
    study = tmp_path / "patch.yaml"
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    nc, html = tmp_path / "patch.nc", tmp_path / "patch.html"
    assert main(["run", str(study), "-o", str(nc), "--quiet", "--no-mesh-check"]) == 0   # tests/results/test_meshcheck_3d.py
    with xr.open_dataset(nc, engine="h5netcdf") as ds:
        assert np.all(ds["status"].values == 0)
        worst = dict(zip(map(str, ds["criterion"].values), ds["worst_value"].values))
        assert worst["pressure"] == pytest.approx(3.0e6, rel=1e-8)
        assert worst["stress"] == pytest.approx(3.0e6, rel=1e-8)
        assert float(ds["worst_x"].sel(criterion="pressure", param="loads.block_top.pressure")) == 3.0e6
        assert ds["worst_contact_tangents"].shape[-2:] == (2, 3)
        assert ds.attrs["mesh_check"] == "skipped (--no-mesh-check)"
    assert main(["report", str(nc), "-o", str(html), "--quiet"]) == 0
    assert html.stat().st_size > 0


@pytest.mark.parametrize("load, status, words", [
    ([1.0e5, 0.0, -P], 3, r"net load \(1e\+05, 0, -1e\+06\) N drives a rigid motion"),
    ([0.0, 0.0, -P], 7, r"translation \([-\d.e+]+, [-\d.e+]+, 0\) m with rotation \(0, 0, [-\d.e+]+\) rad "
                        r"about the axes through \(0.\d+, 0.\d+, 0.25\d*\)"),
])
def test_a_floating_block_without_friction_is_refused_with_its_3d_motion(load, status, words):
    """Frictionless, nothing holds the block in its plane: a tangential load is unbalanced
    (status 3, the net load named), a normal one leaves the in-plane motions free (status 7, a
    free motion named: in the plane, no lift, no tilt)."""
    d = floating({"slip_limit": 3.0e5})
    del d["scene"]["contacts"]["interface"]["friction"]
    d["uncertain"] = {"loads.block_top_load.traction.2": [-1.5e6, -0.5e6]}
    d["scene"]["loads"] = {"block_top_load": {"traction": load}}
    ev = Evaluator(load_study(d))
    res = ev.evaluate(ev.study.nominal())
    assert res.status == status
    assert re.search(words, res.message), res.message
