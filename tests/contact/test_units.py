"""Contact on the units of the stiffness (`wcs.contact.units`): bodies whose Young's moduli
move independently share their factorizations, a Poisson ratio refactors its own body alone,
and the answers are those of the data (the shear patch's closed form, a fresh evaluator's bits).

Tolerances: the shear patch's exact solution is piecewise linear, which P1 reproduces to
round-off; 1e-6 relative is its closed-form test's (tests/contact/test_patch_3d.py), above the Newton
tolerance 1e-10 and the 12-digit rounding of the moduli's directions (5e-13)."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from wcs.contact.units import stiffness_units
from wcs.model.evaluation import Evaluator
from wcs import load_study

ROOT = Path(__file__).resolve().parents[2]
SHEAR = ROOT / "studies" / "validation" / "tresca-shear-patch-3d.yaml"
G, DELTA, H = 3.0e5, 1.0e-3, 0.5                 # the shear patch's slip limit, top motion, height


def patch(uncertain: dict) -> dict:
    d = yaml.safe_load(SHEAR.read_text())
    d["uncertain"] = uncertain
    return d


def parts(ev):
    """The factor each unit holds now and the values it factored (a refactor replaces K_data)."""
    return [(p.factor, p.K_data) for p in ev.model._cache.contact.parts]


def test_the_units_are_the_bodies_of_distinct_materials():
    ev = Evaluator(load_study(patch({"materials.block.E": [4e9, 6e9]})))
    m = ev.model
    dofs, regions = m.units.dofs, m.units.regions
    names = [m.smesh.regions[r[0]][0] for r in regions]
    assert sorted(names) == ["base", "block"] and all(len(r) == 1 for r in regions)
    assert np.array_equal(np.sort(np.concatenate(dofs)), np.arange(m.reduce.pattern.shape[0]))
    K = m.reduce.pattern.tocsr()
    for a, d in enumerate(dofs):                 # no stiffness entry couples two units
        other = np.setdiff1d(np.arange(K.shape[0]), d)
        assert K[d][:, other].nnz == 0
    one = patch({"materials.block.E": [4e9, 6e9]})
    one["scene"]["bodies"]["block"]["regions"][0]["material"] = "base"   # one material: one unit
    assert len(Evaluator(load_study(one)).model.units.dofs) == 1


def test_independent_young_moduli_keep_every_factorization_and_give_the_closed_form():
    ev = Evaluator(load_study(patch({"materials.block.E": [4e9, 6e9], "materials.base.E": [1.5e10, 2.5e10]})))
    assert ev.evaluate(ev.study.nominal()).status == 0
    held = parts(ev)
    for e_block, e_base in [(4e9, 2.5e10), (6e9, 1.5e10), (4.7e9, 2.2e10)]:
        r = ev.evaluate({"materials.block.E": e_block, "materials.base.E": e_base})
        assert r.status == 0, r.message
        assert all(f is f0 and k is k0 for (f, k), (f0, k0) in zip(parts(ev), held))   # no refactor
        slip = DELTA - G * H * (2 / e_block + 2 / e_base)                   # ν = 0: μ = E / 2
        s = r.state.contact.by_node(r.state.contact.slip)
        assert np.abs(s - [slip, 0.0]).max() < 1e-6 * slip
        fresh = Evaluator(ev.study).evaluate(r.x)
        assert np.array_equal(fresh.state.u, r.state.u)


def test_a_poisson_ratio_refactors_its_own_unit_alone():
    ev = Evaluator(load_study(patch({"materials.block.nu": [0.0, 0.3], "materials.base.E": [1.5e10, 2.5e10]})))
    assert ev.evaluate(ev.study.nominal()).status == 0
    (fb, kb), (fk, kk) = parts(ev)
    base = 0 if ev.model.smesh.regions[ev.model.units.regions[0][0]][0] == "base" else 1
    r = ev.evaluate({"materials.block.nu": 0.2, "materials.base.E": 1.7e10})
    assert r.status == 0, r.message
    now = parts(ev)
    assert now[base][1] is (kb, kk)[base]                       # the base: its factor kept (E alone)
    assert now[1 - base][1] is not (kb, kk)[1 - base]           # the block: refactored
    fresh = Evaluator(ev.study).evaluate(r.x)
    assert np.array_equal(fresh.state.u, r.state.u) and fresh.phi == r.phi


def test_stiffness_units_merge_components_of_one_material():
    """Three components (diagonal blocks), the first and third of one material: two units."""
    import scipy.sparse as sp
    K = sp.block_diag([np.ones((2, 2)), np.ones((3, 3)), np.ones((2, 2))]).tocsr()
    units = stiffness_units(K, [np.array([0, 1]), np.array([2, 4]), np.array([5, 6])], ["a", "b", "a"])
    assert [d.tolist() for d in units.dofs] == [[0, 1, 5, 6], [2, 3, 4]] and units.regions == ([0, 2], [1])


def test_a_product_with_k_over_the_moved_cells_is_the_assembled_product():
    ev = Evaluator(load_study(patch({"materials.block.E": [4e9, 6e9]})))
    m = ev.model
    coef = m.stiffness_coefficients(m.nominal)
    x = np.zeros(m.dim * m.nnodes)
    moved = np.random.default_rng(3).choice(m.nnodes, 20, replace=False)
    x[(3 * moved[:, None] + np.arange(3)).ravel()] = np.random.default_rng(4).standard_normal(60)
    K = m.K(coef)
    assert np.abs(m.K.apply(coef, x) - K @ x).max() <= 1e-13 * np.abs(K @ x).max()


def test_a_random_sequence_of_data_sets_gives_a_fresh_evaluators_bits():
    """Young's moduli, a Poisson ratio (two values, so that a direction comes back), the load and
    the slip limit drawn at random, one after another on one evaluator: each answer is a fresh
    evaluator's to the bit (units refactored, kept or rescaled in every order)."""
    ev = Evaluator(load_study(patch({"materials.block.E": [4e9, 6e9], "materials.base.E": [1.5e10, 2.5e10],
                                     "materials.block.nu": [0.0, 0.3], "materials.base.nu": [0.0, 0.3],
                                     "loads.block_top_load.pressure": [0.8e6, 1.2e6],
                                     "contacts.interface.friction.slip_limit": [2.5e5, 3.5e5]})))
    box = ev.study.parameters
    names = list(box.names)
    lo, hi = np.array(box.lower, float), np.array(box.upper, float)
    rng = np.random.default_rng(11)
    for i in range(6):
        x = lo + (hi - lo) * rng.random(lo.size)
        for k, name in enumerate(names):
            if name.endswith(".nu"):
                x[k] = [0.0, 0.2][rng.integers(2)]
        got = ev.evaluate(x)
        want = Evaluator(ev.study).evaluate(x)
        assert got.status == want.status == 0, (got.message, want.message)
        assert got.phi == want.phi and np.array_equal(got.state.u, want.state.u), i


def test_a_body_apart_from_the_contact_is_a_unit_of_its_own():
    """A third block, clamped and pressed, touching neither contact body: its unit reaches no
    contact row (its W block is zero); the patch keeps its closed form, the data their bits."""
    d = patch({"materials.third.E": [0.8e10, 1.2e10], "materials.block.E": [4e9, 6e9],
               "materials.third.nu": [0.2, 0.3]})
    sc = d["scene"]
    sc["materials"]["third"] = {"E": 1.0e10, "nu": 0.25}
    sc["bodies"]["third"] = {"regions": [{"material": "third", "shape": {"box": [2, 0, -0.5, 3, 1, 0]}}]}
    sc["boundaries"]["third_top"] = {"body": "third", "plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}}
    sc["loads"]["third_top"] = {"pressure": 1.0e6}
    ev = Evaluator(load_study(d))
    assert len(ev.model.units.dofs) == 3
    for x in [ev.study.nominal(), {"materials.third.E": 1.1e10, "materials.block.E": 4.5e9, "materials.third.nu": 0.22}]:
        r = ev.evaluate(x)
        assert r.status == 0, r.message
        e_block = dict(zip(ev.study.parameters.names, r.x))["materials.block.E"]
        slip = DELTA - G * H * (2 / e_block + 2 / 2.0e10)
        assert abs(r.phi["slip"] - slip) < 1e-6 * slip
        assert np.array_equal(Evaluator(ev.study).evaluate(r.x).state.u, r.state.u)


PAD = ROOT / "studies" / "validation" / "tresca-pad.yaml"


def pad(uncertain: dict, plane: str) -> dict:
    d = yaml.safe_load(PAD.read_text())
    d["uncertain"] = uncertain
    d["scene"]["plane"] = plane
    return d


@pytest.mark.parametrize("plane", ["strain", "stress"])
def test_2d_contact_is_solved_on_its_units_too(plane):
    """The Tresca pad (2D, the rubber pad floating on its steel base; plane stress's
    λ* = 2λμ/(λ + 2μ) is homogeneous in the moduli too): two units, the base's and
    the pad's. New Young's moduli keep both factorizations, a new Poisson ratio of the rubber
    refactors the pad alone; each answer is a fresh evaluator's to the bit and the contact
    problem of K(c) itself solved on one factor (`solve_contact` without the units) to 1e-10
    of max|u|, the Newton tolerance: the two differ by round-off only (another order of
    arithmetic, the moduli's directions rounded at 5e-13; measured 1-3e-13)."""
    from wcs.contact.solver import solve_contact

    ev = Evaluator(load_study(pad({"materials.rubber.E": [0.9e7, 1.1e7], "materials.steel.E": [2.0e11, 2.2e11],
                                   "materials.rubber.nu": [0.4, 0.48]}, plane)))
    m = ev.model
    assert ev.evaluate(ev.study.nominal()).status == 0
    names = [m.smesh.regions[r[0]][0] for r in m.units.regions]
    assert sorted(names) == ["base", "pad"]
    held = parts(ev)
    rubber = names.index("pad")
    for x, kept in [((1.05e7, 2.15e11, 0.45), (True, True)), ((0.93e7, 2.04e11, 0.45), (True, True)),
                    ((0.97e7, 2.18e11, 0.41), (rubber != 0, rubber != 1))]:
        r = ev.evaluate(dict(zip(["materials.rubber.E", "materials.steel.E", "materials.rubber.nu"], x)))
        assert r.status == 0, r.message
        assert [f is f0 and k is k0 for (f, k), (f0, k0) in zip(parts(ev), held)] == list(kept)
        fresh = Evaluator(ev.study).evaluate(r.x)
        assert fresh.phi == r.phi and np.array_equal(fresh.state.u, r.state.u)
        c = ev.map.coefficients(*ev.study.data_set(r.x))
        _, Kr, rhs, u0 = m.reduced_system(c, None)
        z = m.zone
        one = solve_contact(Kr, rhs, m.Bn_r, m.Bt_r, z.gap - z.Bn @ u0, z.weight, g=c.slip, R=m.R_r,
                            tol=m.options.tolerance)
        u = m.elim.T @ one.u + u0
        assert np.abs(u - r.state.u).max() <= 1e-10 * np.abs(u).max()
