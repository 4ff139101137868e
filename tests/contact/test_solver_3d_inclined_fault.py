"""The 3D semismooth Newton where it used to give up: the 3D tunnel crossed by an inclined Tresca
fault (a coarse copy of the 3D tunnel-fault scene, the 2D section extruded along y between two
y-rollers: most tangent rows along y act on round-off only, and the fault's nodes on the x-roller
have their tangent along the fault parallel to their normal) and a heated Coulomb pad. Before the
disc rows of the active-set system were written in displacement units, both ran to the iteration
budget (200 with the dual-QP restart) at a residual of ~2e-10 against the tolerance 1e-10.

Reference: the primal SOCP in cvxpy (Clarabel, gaps 1e-12, `wcs.contact.qp`). The multipliers are
not unique there (rows acting on round-off, normal and tangent rows on one motion), so the
displacements are compared, to 1e-6 relative (above both solvers' stopping tests, as in
tests/contact/test_patch_3d.py), and the contact forces f − K u to 1e-5 of the largest: on the tunnel the
two answers' energies agree to 1e-12 and their forces at one fault node differ by 1.5e-6 of the
largest force (K amplifies the reference's interior-point error in u).
"""
import warnings

import numpy as np
import pytest

from wcs.contact.qp import solve_contact_qp
from wcs.contact.solver import conditions_violated
from wcs.model.evaluation import Evaluator
from wcs import load_study

from tests.model.test_adjoint_3d import pad_on_base_study


def _plane(point, normal):
    return {"plane": {"point": point, "normal": normal}}


def tunnel_fault_3d(size=16.0, fine=2.0, length=4.0) -> dict:
    """The tunnel of radius 5 m crossed by the fault of normal (−2, 0, 3) through its axis,
    a slice of `length` along the axis y on rollers front and back; overburden pressures on
    the top, the right side pushed in, the left side on a roller; Tresca slip limit 1 MPa."""
    def region(name, xlo, xhi, normal):
        return {"name": name, "material": "rock",
                "shape": {"box": [xlo, 0, -60, xhi, length, 60],
                          "intersect": [{"halfspace": {"point": [0, 0, 0], "normal": normal}}],
                          "minus": [{"cylinder": {"start": [0, -1, 0], "end": [0, length + 1, 0], "radius": 5.0}}]}}
    y0, y1 = length / 2 - 1, length / 2 + 1
    return {
        "study": "tunnel-fault-3d",
        "scene": {
            "dimension": 3,
            "mesh": {"size": size, "grading": 0.3,
                     "refine": [{"cylinder": {"start": [0, 0, 0], "end": [0, length, 0], "radius": 7.0}, "size": fine},
                                {"boundary": "fault_h", "size": 2 * fine}]},
            "materials": {"rock": {"E": 5.2e9, "nu": 0.18, "density_weight": 2.45e4}},
            "bodies": {"hanging": {"regions": [region("hanging_west", -60, 0, [2, 0, -3]),
                                               region("hanging_east", 0, 60, [2, 0, -3])]},
                       "footwall": {"regions": [region("footwall_rock", -60, 60, [-2, 0, 3])]}},
            "boundaries": {
                "left": _plane([-60, 0, 0], [1, 0, 0]), "right": _plane([60, 0, 0], [1, 0, 0]),
                "bottom": _plane([0, 0, -60], [0, 0, 1]),
                "front": _plane([0, 0, 0], [0, 1, 0]), "back": _plane([0, length, 0], [0, 1, 0]),
                "top_west": {"box": [-60, 0, 60, 0, length, 60]}, "top_east": {"box": [0, 0, 60, 60, length, 60]},
                "fault_h": {"body": "hanging", **_plane([0, 0, 0], [-2, 0, 3])},
                "fault_f": {"body": "footwall", **_plane([0, 0, 0], [-2, 0, 3])},
                "tunnel_roof": {"box": [-3.6, y0, 3.4, 3.6, y1, 5.1]}},
            "supports": {"right": {"u": [-2.5e-2, None, 0.0]}, "left": {"normal": 0.0},
                         "bottom": {"u": [None, None, 0.0]},
                         "front": {"u": [None, 0.0, None]}, "back": {"u": [None, 0.0, None]}},
            "loads": {"top_west": {"pressure": 0.5e7}, "top_east": {"pressure": 1.0e7}},
            "contacts": {"fault": {"slave": "fault_h", "master": "fault_f", "friction": {"slip_limit": 1.0e6}}},
            "regions_of_interest": {"roof": {"boundary": "tunnel_roof"}}},
        "uncertain": {"materials.rock.E": [4.4e9, 6.0e9]},
        "criteria": [{"name": "convergence", "kind": "mean_normal_displacement", "regions": ["roof"]}],
    }


def solve_and_compare(d):
    """The nominal solve (no warning on the way) against the SOCP reference on the model's
    reduced system; returns the Newton result."""
    ev = Evaluator(load_study(d))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = ev.evaluate(ev.study.nominal())
    assert res.status == 0, res.message
    model, c, a = ev.model, res.state.coefficients, res.state.raw
    z = model.zone
    _, Kr, rhs, u0 = model.reduced_system(c, model.solve_heat(c) if model.thermal else None)
    gap = z.gap - z.Bn @ u0
    with warnings.catch_warnings():       # Clarabel at 1e-12 may end OPTIMAL_INACCURATE: checked below
        warnings.simplefilter("ignore")
        ref = solve_contact_qp(Kr, rhs, model.Bn_r, model.Bt_r, gap, z.weight, g=c.slip,
                               F=c.coulomb if c.coulomb.any() else None, tol=1e-12)
    assert ref.status == 0, ref.message
    assert np.abs(a.u - ref.u).max() < 1e-6 * np.abs(ref.u).max()
    force, force_ref = rhs - Kr @ a.u, rhs - Kr @ ref.u                  # Cᵀλ: the contact forces
    assert np.abs(force - force_ref).max() < 1e-5 * np.abs(force_ref).max()
    m = len(a.lam_n)
    k = len(a.lam_t) // m
    assert conditions_violated(a.u, model.Bn_r @ a.u - gap, a.lam_n, a.lam_t, a.gw, k) == ""
    assert (model.Bn_r @ a.u - gap).max() <= 1e-9 * np.abs(a.u).max()    # no penetration
    return a


def test_the_3d_tunnel_fault_converges_and_matches_the_socp():
    a = solve_and_compare(tunnel_fault_3d())
    assert (a.active == 1).any() and (a.active == 2).any()           # stick and slip on the fault
    assert a.iterations <= 20


def test_a_heated_coulomb_pad_converges_and_matches_the_socp():
    """The pad of tests/model/test_adjoint_3d.py with a heat source 100× its own (1e4 W/m³): the
    expansion presses the pad's edges into slip in varying directions."""
    d = pad_on_base_study({"coefficient": 0.3})
    d["scene"]["thermal"]["sources"]["pad"] = 1.0e4
    d["uncertain"]["thermal.sources.pad"] = [0.5e4, 1.5e4]
    a = solve_and_compare(d)
    assert (a.active == 1).any() and (a.active == 2).any()


def test_unloaded_friction_held_block_is_reported_not_unique_not_a_solver_failure(tmp_path):
    """The 3D Tresca shear patch without its loads: the block, held on top in x and y only,
    rests on the base at zero contact force, and lifting it is free — the solution is not
    unique (exit 2 naming the body), not "the contact solver did not converge" (exit 1).
    Two causes, both of round-off: Rᵀf of the support's load was ~1e-16 of |R|ᵀ|f| and acted as
    a load pulling the block off (`rigid_load`), and the dual QP's answer (λ ≈ 1e-9 N) lay outside
    B by round-off, more than tol × max|λ|, so its Newton polish never stopped."""
    import yaml

    from wcs.cli import main
    doc = yaml.safe_load(open("studies/validation/tresca-shear-patch-3d.yaml"))
    doc["scene"]["loads"] = {}
    path = tmp_path / "unloaded.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    import contextlib
    import io
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["check", str(path), "--quiet"])
    assert code == 2, err.getvalue()
    assert "body 'block'" in err.getvalue() and "not unique" in err.getvalue()


def test_rigid_load_drops_round_off_only():
    from wcs.contact.solvability import rigid_load
    R = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, -1.0]])
    f = np.array([1e6, -1e6 + 1e-9, 3.0])      # mode 0: 3 + 1e-9 of a real load; mode 1: −1e6 − 3
    e = rigid_load(R, f)
    assert e[0] == pytest.approx(3.0 + 1e-9) and e[1] == pytest.approx(-1e6 - 3.0 + 1e-9)
    g = np.array([1e6, -1e6 + 1e-7, 0.0])       # mode 0: 1e-7 against |R|ᵀ|f| = 2e6, round-off size → 0
    assert rigid_load(R, g)[0] == 0.0 and rigid_load(R, g)[1] != 0.0
