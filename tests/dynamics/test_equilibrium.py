"""A static contact solution is an equilibrium: started from it (`initial: static`, [101]) under
the same constant loads the levels stay there, in both schemes — every level a contact solve
of an increment that is round-off against the displacement it is taken from (the
certificate of `conditions_violated` measures the penetration against both)."""
import numpy as np
import pytest
import yaml

from tests.support.bad_studies import demo_doc
from wcs.dynamics.history import simulate
from wcs.model.evaluation import Evaluator
from wcs.study import load_study


def at_rest(doc, scheme, dt):
    doc.pop("uncertain", None)
    doc.pop("limits", None)
    doc.pop("sweep", None)
    for m in doc["scene"]["materials"].values():
        m["density"] = 2000.0
    doc["dynamics"] = {"end_time": 5 * dt, "time_step": dt, "scheme": scheme, "initial": "static"}
    study = load_study(doc)
    hist = simulate(Evaluator(study))
    u = np.array(hist.displacement)
    return np.abs(u - u[0]).max() / np.abs(u[0]).max(), max(hist.kinetic), hist


@pytest.mark.parametrize("scheme, patch", [("seed", "contact-patch"), ("stabilized", "contact-patch"),
                                           ("stabilized", "mortar-patch")])
def test_the_contact_patch_stays_in_its_static_state(scheme, patch):
    """The contact patch (pressure p through a frictionless contact: p at every contact node,
    exactly; on nonmatching meshes by the dual mortar, [101, (24)–(26)]): 5 levels from its
    static state keep it, pressure p to round-off."""
    with open(f"studies/validation/{patch}.yaml") as fh:
        doc = yaml.safe_load(fh)
    moved, kinetic, hist = at_rest(doc, scheme, 1e-4)
    assert moved < 1e-9
    assert np.asarray(hist.phi["pressure"]) == pytest.approx(1.0e6, rel=1e-9)


def test_the_static_state_of_the_demo_stays_put():
    """The two-blocks demo (pressure, weight, Tresca friction on the interface): 5 levels."""
    doc = demo_doc()
    doc["scene"]["mesh"] = {"size": 0.2}
    moved, kinetic, hist = at_rest(doc, "seed", 1e-4)
    assert moved < 1e-9
    for values in hist.phi.values():
        assert np.asarray(values) == pytest.approx(values[0], rel=1e-8)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["seed", "stabilized"])
def test_the_static_state_of_a_3d_patch_stays_put(scheme):
    """3D (tetrahedra, two tangents per node): block on block, 2 MPa through the contact."""
    with open("studies/validation/block-on-block-3d.yaml") as fh:
        doc = yaml.safe_load(fh)
    moved, kinetic, hist = at_rest(doc, scheme, 1e-4)
    assert moved < 1e-9
    assert np.asarray(hist.phi["pressure"]) == pytest.approx(2.0e6, rel=1e-9)
