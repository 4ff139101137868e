"""Trust in every contact number.

- the value of a data set does not depend on what was solved before it — not on a failed
  solve, not on an exception in the middle of one: bitwise the value of a fresh evaluator.
- the contact solve does not give up where a solution exists (data sets of granite-crack
  on which the semismooth Newton used to end with status 1), checked against the cvxpy QP.
- a floating body whose position the contact does not determine is a status, not a number.
- the cold start: the nominal data are solved once, and cvxpy is not imported by a Newton solve.
"""
import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.support import scenes
import wcs
import wcs.contact.solver as cs
import wcs.contact.methods as methods
from wcs.model.coefficients import flatten
from wcs.model.evaluation import Evaluator
from wcs.model.model import Model

ROOT = Path(__file__).resolve().parents[2]


def coarse(name, size, refine):
    """A shipped study with a coarser mesh (the numbers of a data set do not matter here)."""
    doc = yaml.safe_load((ROOT / "studies" / f"{name}.yaml").read_text())
    doc["scene"]["mesh"]["size"] = size
    for r in doc["scene"]["mesh"].get("refine", []):
        r["size"] = refine
    return wcs.load_study(doc, base_dir=ROOT / "studies")


def fresh(ev, **options):
    """An evaluator that has solved nothing: a new model on the same mesh (the criteria hold
    geometry only)."""
    new = copy.copy(ev)
    new.model = Model(ev.study.scene, ev.smesh, ev.study.solver.model_copy(update=options))
    return new


def small_pad(doc):
    doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05}]}


def _tresca_pad(doc):
    small_pad(doc)
    doc["uncertain"]["materials.rubber.E"] = [0.8e7, 1.2e7]


def _coulomb_pad(doc):
    small_pad(doc)
    doc["scene"]["contacts"]["interface"]["friction"] = {"coefficient": 0.4}
    doc["uncertain"] = {"loads.pad_top.traction.0": [0.0, 4.0e5], "materials.rubber.E": [0.8e7, 1.2e7],
                        "contacts.interface.friction.coefficient": [0.3, 0.5]}


SCENES = {   # a study and the box each parameter is drawn from where it is not the study's own
    "granite-crack": (lambda tmp: coarse("granite-crack", 1.0, 0.3), {}),
    "tresca-pad": (lambda tmp: scenes.load("tresca-pad", _tresca_pad),
                   {"loads.pad_top.traction.0": (1.0e5, 4.5e5)}),           # beyond g L: unsolvable
    "coulomb-pad": (lambda tmp: scenes.load("tresca-pad", _coulomb_pad), {}),
    "thermal-two-blocks": (lambda tmp: coarse("two-blocks-demo", 0.1, 0.04), {}),
}


def data_sequence(study, upper, rng, widen):
    """One data set per entry of `upper`: all moduli and Poisson ratios at the upper (True)
    or all at the lower ends of their intervals (two stiffnesses, so that a stiffness comes
    back), everything else uniform in the (widened) box; never the nominal data."""
    names = list(study.parameters.names)
    lo, hi = np.array(study.parameters.lower, float), np.array(study.parameters.upper, float)
    for k, name in enumerate(names):
        if name in widen:
            lo[k], hi[k] = widen[name]
    corner = np.array([n.startswith("materials.") and n.rsplit(".", 1)[1] in ("E", "nu") for n in names])
    out = []
    for up in upper:
        x = lo + (hi - lo) * rng.random(lo.size)
        x[corner] = (hi if up else lo)[corner]
        out.append(x)
    return out


def poisoned_pattern(stiffness, failed, solved):
    """Whether some data set follows, with no solve in between, a failure after a solve of
    its own stiffness, the failure having the other stiffness (the history that once changed a value)."""
    last = None
    for k in range(len(stiffness)):
        if last is not None and stiffness[k] == stiffness[last] and any(
                failed[j] and stiffness[j] != stiffness[last] for j in range(last + 1, k)):
            return True
        if solved[k]:
            last = k
    return False


@pytest.fixture
def inject(monkeypatch):
    """failing[key of the coefficients] = "stall" (Newton ends unconverged after the refactor)
    or "raise" (an exception in the middle of the solve, after the refactor)."""
    failing = {}
    solve_contact, newton = Model._solve_contact, cs._newton

    def broken(mode):
        def _newton(*a, **k):
            out = newton(*a, **k)
            if mode == "raise":
                raise RuntimeError("injected failure")
            return out[:4] + (False,)
        return _newton

    def patched(self, c, *a, **k):
        mode = failing.get(flatten(c)[0].tobytes())
        if mode is None:
            return solve_contact(self, c, *a, **k)
        monkeypatch.setattr(cs, "_newton", broken(mode))
        try:
            return solve_contact(self, c, *a, **k)
        finally:
            monkeypatch.setattr(cs, "_newton", newton)

    monkeypatch.setattr(Model, "_solve_contact", patched)
    return failing


def outcome(ev, x):
    try:
        e = ev.evaluate(x)
    except RuntimeError as exc:
        return ("raised", str(exc))
    return (e.status, tuple(e.phi[c.name] for c in ev.criteria))


def same(a, b):
    return a[0] == b[0] and (a[0] == "raised" or np.array_equal(a[1], b[1], equal_nan=True))


def check_history_independence(key, n, seed, inject, tmp_path):
    make, widen = SCENES[key]
    study = make(tmp_path)
    ev = Evaluator(study)
    rng = np.random.default_rng(seed)
    upper = list(rng.random(n) < 0.5)
    modes = [None if rng.random() < 0.6 else "stall" if rng.random() < 0.6 else "raise" for _ in range(n)]
    upper[:3] = [upper[0], not upper[0], upper[0]]     # that history once for certain: a solve,
    modes[:3] = [None, "stall", None]                  # a failure at the other stiffness, the first again
    xs = data_sequence(study, upper[:3], rng, {}) + data_sequence(study, upper[3:], rng, widen)
    for x, mode in zip(xs, modes):
        if mode:
            c = ev.map.coefficients(x)
            inject[flatten(c)[0].tobytes()] = mode
    seq = [outcome(ev, x) for x in xs]
    assert poisoned_pattern(upper, [m is not None for m in modes], [o[0] == 0 for o in seq])
    assert {o[0] for o in seq} - {0}
    for x, got in zip(xs, seq):
        want = outcome(fresh(ev), x)
        assert same(got, want), (x, got, want)


@pytest.mark.parametrize("key", list(SCENES))
def test_value_does_not_depend_on_history(key, inject, tmp_path):
    """Every data set of a seeded sequence that includes failing solves (injected after the
    refactor: Newton unconverged, or an exception; and unsolvable data) gives bitwise the
    status and criteria of a fresh evaluator."""
    check_history_independence(key, 8, 15, inject, tmp_path)


@pytest.mark.parametrize("name", ["heated-plate", "glued-layers"])
def test_value_without_contact_does_not_depend_on_history(name):
    """A contact-free scene (elastic and thermal direct solves, factors refactored in place):
    every data set of a random sequence gives bitwise a fresh evaluator's values (before: the
    LU's scaling and matching read the first data set's values, and the heated plate's shear
    differed from a fresh evaluator by up to 180 Pa², in its last bits)."""
    study = wcs.load_study(ROOT / "studies" / f"{name}.yaml")
    lo, hi = np.array(study.parameters.lower, float), np.array(study.parameters.upper, float)
    rng = np.random.default_rng(1)
    xs = [lo + (hi - lo) * rng.random(lo.size) for _ in range(5)]
    ev = Evaluator(study)
    seq = [ev.evaluate(x) for x in xs]
    for x, got in zip(xs, seq):
        want = Evaluator(study).evaluate(x)
        assert got.status == want.status == 0
        assert all(got.phi[k] == want.phi[k] for k in got.phi), (x, got.phi, want.phi)


def test_3d_value_with_a_held_or_scaled_factor_is_a_fresh_evaluators():
    """3D: a data set solved on the factor the previous one left (only a load changed: the
    factor is held; only E changed: the same K* at another scale) gives bitwise a fresh
    evaluator's answer. Before, a held factor left the contact rows C in the order the
    contact solver built them, while a refactor sorted them in place (`linalg._csr` shared
    the caller's arrays), so C u0 added up differently: the 3D tunnel's criteria differed
    from a fresh evaluator's by 2e-15 after a load-only change."""
    study = wcs.load_study(ROOT / "studies" / "tunnel-fault-3d.yaml")
    box = study.parameters
    lo, hi = np.array(box.lower, float), np.array(box.upper, float)
    names = list(box.names)
    x1 = lo + (hi - lo) * np.random.default_rng(5).random(lo.size)
    load, E = x1.copy(), x1.copy()
    load[names.index("loads.top_west.pressure")] = hi[names.index("loads.top_west.pressure")]
    E[names.index("materials.rock.E")] = hi[names.index("materials.rock.E")]
    ev = Evaluator(study)
    seq = [ev.evaluate(x) for x in (x1, load, E)]
    for got in seq[1:]:
        want = Evaluator(study).evaluate(got.x)
        assert got.status == want.status == 0
        assert all(got.phi[k] == want.phi[k] for k in got.phi), (got.phi, want.phi)
        assert np.array_equal(got.state.u, want.state.u)
    assert np.all(seq[2].state.scale != 1.0) and seq[2].state.stiffness is seq[0].state.stiffness   # E alone: one K*


@pytest.mark.slow
@pytest.mark.parametrize("key", list(SCENES))
def test_value_does_not_depend_on_history_long(key, inject, tmp_path):
    check_history_independence(key, 40, 151, inject, tmp_path)


def test_failed_solve_leaves_no_stale_factor():
    """A history that once changed a value: a solved data set, a failing one with another stiffness
    (the shared factor refactored for it), then the first stiffness again with other loads."""
    study = coarse("granite-crack", 1.0, 0.3)
    ev = Evaluator(study)
    x1 = study.nominal() * 1.02
    x2 = x1.copy()
    x2[0] = 6.9e10
    x3 = x1.copy()
    x3[2] *= 1.1
    assert ev.evaluate(x1).status == 0
    real = cs._newton
    cs._newton = lambda *a, **k: real(*a, **k)[:4] + (False,)
    try:
        assert ev.evaluate(x2).status == 1
    finally:
        cs._newton = real
    assert outcome(ev, x3) == outcome(fresh(ev), x3)


# ---- Newton does not give up where the QP solves ------------------------------------------

# data sets of studies/granite-crack.yaml (default mesh) on which the Newton solver of 17a7caa
# ended with status 1 "did not converge in 200 iterations"; two seeded random feasible
# points and two vertices of the Lipschitz polytope of the slip-limit profile
FORMERLY_FAILING = [
    [66552937494.86656, 0.2589895646722966, 11767017.534096418, 5990497.52967311, 1254641.530372679,
     1305153.9384181662, 1461030.5096185403, 1219322.6172612095, 1111699.7308754507, 1026955.5824937427],
    [52449861857.96516, 0.2762352604923999, 11440765.611163577, 4912539.459395536, 708472.6977879202,
     724372.0371551195, 790443.6674950118, 851153.1204510571, 568538.9718124211, 825402.1317503606],
    [5.1e10, 0.22, 8.0e6, 6.0e6, 1.5e6, 1.5e6, 1.5e6, 1069186.8154292398, 638373.6308584795, 1069186.8154292398],
    [5.1e10, 0.28, 8.0e6, 4.0e6, 1.5e6, 1.5e6, 1.5e6, 1.5e6, 1.5e6, 1069186.8154292398],
]


@pytest.fixture(scope="module")
def granite():
    return Evaluator(wcs.load_study(ROOT / "studies" / "granite-crack.yaml"))


def test_formerly_failing_granite_data_sets_solve_and_agree_with_qp(granite):
    """Clarabel stops at ~1e-10 relative duality gaps on this scaled program; 1e-6 leaves
    four orders of margin while a wrong active node moves the criteria by ≥1e-4."""
    ev = granite
    qp = fresh(ev, method="qp")
    for x in FORMERLY_FAILING:
        e, q = ev.evaluate(np.array(x)), qp.evaluate(np.array(x))
        assert e.status == 0 and q.status == 0, (e.message, q.message)
        for c in ev.criteria:
            assert e.phi[c.name] == pytest.approx(q.phi[c.name], rel=1e-6), c.name


def test_redundant_crack_tip_is_not_a_nonsmooth_point(granite):
    """The crack tip on the roller (parallel normal and tangential rows) is closed, its slip
    is zero by the normal constraint and its tangential multiplier may sit at the bound: no
    active-set change is within reach there (the flag used to be set at the nominal data,
    which cost the `corner-kkt` certificates)."""
    ev = granite.evaluate(granite.study.nominal(), gradients=True)
    assert ev.status == 0 and not ev.nonsmooth


def test_gradients_with_the_crack_tip_closed_and_stuck(granite):
    """At this vertex the crack tip (parallel rows) is closed and stuck: the adjoint system
    is singular there. Adjoint against central differences (step 1e-5 of each interval:
    truncation ~1e-10, round-off ~1e-11/1e-5 of the value; 1e-5 of the largest component)."""
    study = granite.study
    x = np.array([5.1e10, 0.28, 1.2e7, 4.0e6] + [5.0e5] * 6)
    e = granite.evaluate(x, gradients=True)
    assert e.status == 0 and not e.nonsmooth
    span = np.array(study.parameters.upper) - np.array(study.parameters.lower)
    for c in granite.criteria:
        fd = []
        for k in range(x.size):
            h = np.zeros(x.size)
            h[k] = 1e-5 * span[k]
            fd.append((granite.evaluate(x + h).phi[c.name] - granite.evaluate(x - h).phi[c.name]) / (2 * h[k]))
        scaled = np.array(fd) * span
        assert np.abs(e.grad[c.name] * span - scaled).max() <= 1e-5 * np.abs(scaled).max(), c.name


def test_redundant_contact_rows_do_not_blow_up_the_newton_step():
    """A node held by rollers on both sides has parallel normal and tangential rows: closed
    and stuck, the active-set system is singular (in floating point: cond ~1e17) and only one
    combination of (λn, λt) acts. The step must not put an arbitrary amount along the
    redundant combination (on granite-crack that was ~1e23, which flipped the next
    prediction: a cycle): the minimum-norm split, nothing along v."""
    kappa = -np.tan(0.38)
    c0, c1, c2 = np.array([np.cos(0.38), 0.3, 0.1]), np.array([0.2, -1.0, 0.4]), np.array([0.5, 0.1, 1.0])
    C = np.array([c0, c1, kappa * c0, c2])              # rows n0, n1, t0, t1: t0 parallel to n0
    W = C @ np.diag([2.0, 3.0, 1.5]) @ C.T
    W[2, 2] *= 1 + 2**-52                               # one rounding of the assembly: cond 1.5e17
    lam_true = np.array([1.0, 0.5, 0.2, 2.0])
    q = W @ lam_true
    q[0] *= 1 + 2**-52
    redundant = cs.redundant_pairs(W)
    assert list(redundant) == [True, False]
    lam, _ = cs._newton_point(W, q, np.zeros((0, 4)), np.zeros(0), np.ones(4, bool), np.zeros(4), redundant)
    assert np.abs(W @ lam - q).max() <= 1e-14 * np.abs(q).max()      # it solves the system
    v = np.array([kappa, 0.0, -1.0, 0.0]) / np.hypot(kappa, 1.0)       # Cᵀ v = 0
    assert abs(v @ lam) <= 1e-12 * np.abs(lam).max()                 # minimum norm
    np.testing.assert_allclose(lam[0] + kappa * lam[2], lam_true[0] + kappa * lam_true[2], rtol=1e-12)


# ---- a free rigid mode is not an answer -------------------------------------------------------

def pad_on_base(tmp_path, shear, slip_limit):
    doc = yaml.safe_load((ROOT / "studies" / "validation" / "tresca-pad.yaml").read_text())
    small_pad(doc)
    sc = doc["scene"]
    sc["loads"]["pad_top"] = {"traction": [shear, -1.0e6]}
    sc["contacts"]["interface"]["friction"] = {"slip_limit": slip_limit}
    doc["uncertain"] = {"loads.pad_top.traction.1": [-2.0e6, -0.5e6]}
    path = tmp_path / f"pad-{shear:g}-{slip_limit:g}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return wcs.load_study(path)


def test_frictionless_pad_without_shear_is_not_unique(tmp_path, capsys):
    study = pad_on_base(tmp_path, 0.0, 0.0)
    ev = study.evaluate(study.nominal())
    assert ev.status == 7 and np.isnan(ev.phi["shift"])
    assert "'pad'" in ev.message and "translation (1, 0)" in ev.message and "not unique" in ev.message
    from wcs.status import Status
    assert "not unique" in Status.NOT_UNIQUE.description
    from wcs.cli import main
    code = main(["solve", str(study.file), "-o", str(tmp_path / "o.nc")])
    err = capsys.readouterr().err
    assert code == 2 and "'pad'" in err and "not unique" in err and "Traceback" not in err


def test_sheared_pad_held_by_friction_is_solved(tmp_path):
    study = pad_on_base(tmp_path, 2.0e5, 3.0e5)
    ev = study.evaluate(study.nominal())
    assert ev.status == 0, ev.message
    assert ev.phi["shift"] > 0                                  # pushed along +x, held by stick


# ---- the cold start -------------------------------------------------------------------------

def test_nominal_data_are_solved_once(monkeypatch):
    calls = []
    real = methods.solve_condensed
    monkeypatch.setattr(methods, "solve_condensed", lambda *a, **k: calls.append(1) or real(*a, **k))
    study = coarse("granite-crack", 1.0, 0.3)
    ev = Evaluator(study)
    first = outcome(ev, study.nominal())
    assert len(calls) == 1
    assert outcome(ev, study.nominal() * 1.01)[0] == 0 and len(calls) == 2   # the anchor is there
    assert outcome(ev, study.nominal()) == first                              # and the same value again


def test_newton_solve_does_not_import_cvxpy():
    code = ("import sys, yaml, wcs; d = yaml.safe_load(open(sys.argv[1])); d['scene']['mesh']['size'] = 1.0\n"
            "for r in d['scene']['mesh']['refine']: r['size'] = 0.3\n"
            "s = wcs.load_study(d)\n"
            "assert s.evaluate(s.nominal() * 1.01).status == 0\n"
            "print('cvxpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(ROOT / "studies" / "granite-crack.yaml")],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


# ---- the warm evaluation's fixed costs ---------------------------------------------

def test_warm_2d_contact_solve_reuses_the_models_pinned_dofs(monkeypatch):
    """A warm 2D evaluation of a floating body takes the pinned DOFs of the rigid modes the model
    found once (a pivoted QR of R per solve was ~1 ms of 20 on the 1e4 pad) and gives the fresh
    evaluator's answer to the bit."""
    study = scenes.load("tresca-pad", _tresca_pad)
    ev = Evaluator(study)
    assert ev.evaluate(study.nominal()).status == 0
    x = study.nominal() * 1.02
    calls = []
    real = cs.pinned_dofs
    monkeypatch.setattr(cs, "pinned_dofs", lambda R: calls.append(1) or real(R))
    warm = outcome(ev, x)
    assert warm[0] == 0 and calls == []
    monkeypatch.undo()
    new = fresh(ev)
    assert outcome(new, study.nominal())[0] == 0
    assert same(outcome(new, x), warm)


def test_dual_qp_restart_does_not_import_cvxpy():
    """The tresca pad with a budget of 3 Newton steps: Newton restarts from the dual QP, solved
    by Clarabel directly: cvxpy's import was 0.6 s of CPU (2-3 s on the shared machine) of the
    first such evaluation in a process. (Its cycle at a low shear from the nominal data's active
    set, which restarted there with the default budget, now ends by Armijo-shortened steps.)"""
    code = ("import sys, yaml, wcs, wcs.contact.solver as cs\n"
            "calls, qp = [], cs._dual_qp\n"
            "cs._dual_qp = lambda *a, **k: calls.append(1) or qp(*a, **k)\n"
            "doc = yaml.safe_load(open(sys.argv[1]))\n"
            "doc['solver'] = {**doc.get('solver', {}), 'max_iterations': 3}\n"
            "s = wcs.load_study(doc, base_dir=sys.argv[2])\n"
            "assert s.evaluate(s.nominal()).status == 0\n"
            "e = s.evaluate({'loads.pad_top.traction.0': 1.0e5, 'contacts.interface.friction.slip_limit': 3.02e5})\n"
            "assert e.status == 0, e.message\n"
            "print(len(calls), 'cvxpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(ROOT / "studies" / "validation" / "tresca-pad.yaml"),
                          str(ROOT / "studies" / "validation")],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "2 False"          # one restart for each of the two data sets
