"""A 3D fault node held by supports on both sides (the tunnel fault's edge on the right face,
where u_x and u_z are given) keeps a normal row of round-off after the supports are eliminated
(1e-31 to 1e-15 of the others: the plane's normal as the mesh gives it). The contact solver holds
such a row as a null row; everything else must too (`wcs.contact.zone.held_rows`). Before,
that node, open with a gap of 1e-19, flagged every evaluation of the 3D tunnel non-smooth (so
its search ended `heuristic` with "local ascent: kkt after 0 steps" and no drivers), and
`tied_rows` tied its tangent to the round-off normal with κ ~ 1e17, reporting a contact force
of 1e36 N there."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
import yaml

import wcs
from wcs.contact.zone import canonical_split, held_rows, tied_rows
from wcs.app.problem import build_problem
from wcs.search.archive import Archive
from wcs.model.sensitivity import contact_nonsmooth

TUNNEL_3D = Path(__file__).resolve().parents[2] / "studies" / "tunnel-fault-3d.yaml"


def test_a_row_of_round_off_acts_on_nothing_and_ties_nothing():
    # node 0: a normal and a tangent at right angles; node 1: a unit normal held by the supports
    # but for round-off (1e-17 left on the unknowns) and a tangent along it (the held node's rows
    # after the elimination: only the tangent acts). Full rows on (u0, u1, u2, held DOF).
    full_n = sp.csr_matrix(np.array([[0.6, 0.8, 0.0, 0.0], [1e-17, 0.0, 0.0, 1.0]]))
    full_t = sp.csr_matrix(np.array([[0.8, -0.6, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]))
    Bn, Bt = full_n[:, :3], full_t[:, :3]
    held = np.r_[held_rows(Bn, full_n), held_rows(Bt, full_t)]
    assert held.tolist() == [False, True, False, False]
    tied, kappa = tied_rows(Bn, Bt, held)
    assert not tied.any() and not kappa.any()                    # before: tied, κ = 1e17
    # a tangential force of 1 N stays a tangential force (before: 1e17 N reported as normal)
    n, t, moved, _ = canonical_split(np.zeros(2), np.array([0.0, 1.0]), np.zeros(2), tied, kappa, 1.0, held)
    assert n.tolist() == [0.0, 0.0] and t.tolist() == [0.0, 1.0] and not moved.any()


def held_node_state(lam_t_norm: float, slip: float):
    """One 3D node (k = 2) whose normal row is round-off: open with a gap of round-off, its
    tangents acting (stuck |λt| < gw, or slipping), next to a closed node well inside."""
    m, k = 2, 2
    Bn = sp.csr_matrix(np.array([[0.0, 0.0, 1.0, 0.0], [3e-31, 0.0, 0.0, 0.0]]))
    Bt = sp.csr_matrix(np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0], [0, 1.0, 0, 1.0]]))
    held = np.r_[held_rows(Bn, sp.csr_matrix(np.abs(Bn.toarray()) + np.array([[0, 0, 0, 0], [0, 0, 1.0, 0]]))),
                 np.zeros(4, dtype=bool)]     # node 1's normal: unit on a held DOF, 3e-31 left
    model = SimpleNamespace(Bn_r=Bn, Bt_r=Bt, held=held, tied=tied_rows(Bn, Bt, held))
    stuck = slip == 0.0
    free = np.array([True, False, True, stuck, True, stuck])      # closed, open; stuck tangents
    raw = SimpleNamespace(lam_n=np.array([1.0e6, 0.0]), free=free, gw=np.array([1.0e6, 1.0e6]),
                          lam_t=np.array([1.0e5, lam_t_norm, 0.0, 0.0]))
    contact = SimpleNamespace(gap=np.array([0.0, 1e-19]), slip=np.array([0.0, slip, 0.0, 0.0]))
    return model, SimpleNamespace(raw=raw, contact=contact, u=np.full(4, 1e-2)), m, k


@pytest.mark.parametrize("lam_t_norm, slip, flagged", [(3.0e5, 0.0, False), (1.0e6, 0.0, True), (1.0e6, 1e-12, True)],
                         ids=["stuck inside the disc", "stuck at the disc", "slipping at s = 0"])
def test_a_held_normal_is_no_switch_but_its_acting_tangent_is(lam_t_norm, slip, flagged):
    """The held node's normal cannot switch (its gap is what the supports leave); its tangent
    acts, so a stick/slip switch there is one (before: every such node flagged as a weakly
    open normal, and its tangents' switches hidden behind the normal's round-off)."""
    model, state, _, _ = held_node_state(lam_t_norm, slip)
    assert contact_nonsmooth(model, state) is flagged


def fault_block():
    """The 3D tunnel's fault block without the tunnel, meshed at 7 m (73 fault nodes): its fault
    node at (60, 5, 40) on the right face (u_x, u_z given) has a normal row of 3.5e-31."""
    doc = yaml.safe_load(TUNNEL_3D.read_text())
    scene = doc["scene"]
    scene["mesh"] = {"size": 7.0}
    for body in scene["bodies"].values():
        for region in body["regions"]:
            del region["shape"]["minus"]
    for name in ("tunnel_roof", "tunnel_floor", "tunnel_west", "tunnel_east"):
        del scene["boundaries"][name]
    scene["regions_of_interest"] = {"top": {"boundary": "top_west"},
                                    "ring_hanging": {"ball": {"center": [0, 5, 0], "radius": 20.0}, "body": "hanging"},
                                    "ring_footwall": {"ball": {"center": [0, 5, 0], "radius": 20.0}, "body": "footwall"}}
    doc["criteria"] = [{"name": "settle", "kind": "mean_normal_displacement", "regions": ["top"]},
                       {"name": "shear", "kind": "shear_stress_intensity", "regions": ["ring_hanging", "ring_footwall"]}]
    doc["uncertain"]["contacts.fault.friction.slip_limit"] = [0.5e6, 1.5e6]
    for key in ("limits", "output", "search"):
        doc.pop(key)
    return wcs.load_study(doc)


def test_the_held_fault_node_of_a_3d_block_leaves_its_corner_certified():
    """At the gradient-sign corner of Φ = the top's settlement: the evaluation is smooth, the
    nodal forces are bounded by the load (≈ 1.3e10 N in all), the certificate is corner-kkt,
    and the adjoint derivatives of the two largest drivers agree with one-sided differences into
    the box taken here (step 1e-5 of the interval: the error O(h) of a smooth Φ, 1e-4 allowed)."""
    study = fault_block()
    box = study.parameters
    nominal = study.evaluate(study.nominal(), gradients=True)
    g0 = np.asarray(nominal.grad["settle"])
    corner = np.where(g0 > 0, box.upper, box.lower)
    ev = study.evaluate(corner, gradients=True)
    model = ev.evaluator.model
    assert model.held.any()                                      # the case: a held node's row of round-off
    assert ev.status == 0 and not ev.nonsmooth                   # before: non-smooth at every data set
    assert np.abs(ev.state.contact.force_n).max() < 2e10         # before: 1e36 N at the held node
    problem = build_problem(study, ev.evaluator)
    archive = Archive(problem, budget=1)
    ask = archive.ask([archive.space.to_z(corner)], "corner")
    next(ask)
    with pytest.raises(StopIteration):
        ask.send([SimpleNamespace(x=corner, phi=ev.phi, status=0, grad=ev.grad, nonsmooth=ev.nonsmooth)])
    assert archive.certify("settle", tol=1e-6)[0] == "corner-kkt"   # before: heuristic (non-smooth)
    g = np.asarray(ev.grad["settle"])
    width = box.upper - box.lower
    for i in np.argsort(-np.abs(g) * width)[:2]:
        h = 1e-5 * width[i] * (1 if corner[i] == box.lower[i] else -1)
        x = corner.copy()
        x[i] += h
        q = (study.evaluate(x).phi["settle"] - ev.phi["settle"]) / h
        assert q == pytest.approx(g[i], rel=1e-4), box.names[i]
        assert q * np.sign(h) < 0                                 # Φ falls moving inward: the KKT sign
