"""The criterion kinds added through the registry alone (`wcs.criteria.KINDS`): the largest
principal stress and the mean contact slip, each with adjoint gradients against central
finite differences (the rule of test_gradients.py: 1e-5 relative plus the FD noise floor),
and the schema, the adjoint and the report reading them from the one entry."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs
from test_gradients import TOL, VALIDATION, check_against_fd
from wcs.criteria import KINDS, _principal_kink
from wcs.errors import StudyError
from wcs.report.data import KIND_LABEL, KIND_UNITS

DATA = Path(__file__).resolve().parent / "data"


def all_kinds(criteria):
    doc = yaml.safe_load((DATA / "gradients-all-kinds.yaml").read_text())
    doc["criteria"] = criteria
    return doc


def test_principal_stress_gradient():
    study = wcs.load_study(all_kinds([
        {"name": "s1_core", "kind": "principal_stress", "regions": ["pad_core"]},
        {"name": "s1_edge", "kind": "principal_stress", "regions": ["pad_top"]}]))
    assert check_against_fd(study) < 1e-5


def test_principal_stress_value_is_the_area_mean_of_sigma_1():
    """Φ = Σ a_c σ₁,c / Σ a_c over the cells inside the box G_r (embedded in the mesh), σ₁ the
    larger eigenvalue of each cell's in-plane stress block (numpy's eigvalsh, not wcs's formula)."""
    study = wcs.load_study(all_kinds([{"name": "s1", "kind": "principal_stress", "regions": ["pad_core"]}]))
    ev = study.evaluate(study.nominal())
    assert ev.status == 0
    f = ev.fields
    p, t = f["coords"].values, f["cells"].values
    x0, y0, x1, y1 = 0.8, 1.1, 1.2, 1.4
    c = p[t].mean(axis=1)
    inside = (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)
    e1, e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert abs(area[inside].sum() - 0.4 * 0.3) < 1e-12            # the box is embedded exactly
    xx, yy, _, xy = f["stress"].values[inside].T
    s1 = np.linalg.eigvalsh(np.stack([np.stack([xx, xy], -1), np.stack([xy, yy], -1)], -2))[:, 1]
    expect = area[inside] @ s1 / area[inside].sum()
    assert abs(ev.phi["s1"] - expect) <= 1e-12 * np.abs(s1).max()     # round-off of two formulas


def test_principal_kink_where_the_principal_stresses_meet():
    s = np.array([[1.0, 2.0, -3.0], [1.0, 1.0, 1.0], [0.3, 0.0, 0.0], [0.0, 0.0, 1e-12]])
    assert _principal_kink(s).tolist() == [True, False, False]


def test_registry_feeds_schema_and_report():
    """The schema takes the new kinds, refuses a kind's missing scene block and a foreign
    option by key path, and the report has their units and labels, all from `KINDS`."""
    for name, units in (("principal_stress", "Pa"), ("contact_slip", "m")):
        assert KIND_UNITS[name] == units and KIND_LABEL[name] == KINDS[name].label
    doc = yaml.safe_load((VALIDATION.parent / "glued-layers.yaml").read_text())    # no contact
    roi = "soft_layer"
    doc["criteria"] = [{"name": "s", "kind": "contact_slip", "regions": [roi]}]
    with pytest.raises(StudyError, match="contact_slip needs a contact in the scene") as info:
        wcs.load_study(doc)
    assert info.value.path == "criteria.0.kind"
    doc["criteria"] = [{"name": "s", "kind": "principal_stress", "regions": [roi], "point": [0.0, 0.0]}]
    with pytest.raises(StudyError, match="'point' applies only to kind mean_normal_displacement"):
        wcs.load_study(doc)


def tresca_pad(criteria):
    doc = yaml.safe_load((VALIDATION / "tresca-pad.yaml").read_text())
    doc["scene"]["regions_of_interest"]["edge"] = {"box": [1.3, 0.99, 1.5, 1.01]}
    doc["uncertain"] = {"loads.pad_top.traction.0": [1.0e5, 2.5e5],
                        "contacts.interface.friction.slip_limit": [2.6e5, 4.0e5],
                        "materials.rubber.nu": [0.40, 0.48]}
    doc["criteria"] = criteria
    doc["solver"] = {"method": "monolithic", "tolerance": TOL}
    return wcs.load_study(doc)


def test_contact_slip_gradient_with_stuck_and_sliding_nodes():
    """Tresca pad: 11 of 51 interface nodes stick (slip ~1e-15, the kink of |s| at 0) and
    the rest slide; the stuck ones keep s = 0 on their active set, so the gradient is exact."""
    study = tresca_pad([{"name": "slip_edge", "kind": "contact_slip", "regions": ["edge"]},
                        {"name": "slip_all", "kind": "contact_slip", "regions": ["interface"]}])
    ev = study.evaluate(study.nominal())
    c, m = ev.state.contact, ev.state.contact.slip.size
    stuck = ev.state.raw.free[m:]
    assert stuck.sum() == 11 and np.abs(c.slip[stuck]).max() < 1e-14
    assert ev.phi["slip_all"] == c.weight @ np.abs(c.slip) / c.weight.sum()
    assert check_against_fd(study) < 1e-5


def test_contact_slip_held_node_is_smooth():
    """Frictionless patch: the node at x = 0 is held in x on both sides (slip ≡ 0 whatever the
    data, the kink of |s| never reached): not flagged, and the gradient matches FD."""
    doc = yaml.safe_load((VALIDATION / "contact-patch.yaml").read_text())
    doc["criteria"] = [{"name": "slip", "kind": "contact_slip", "regions": ["interface"]}]
    doc["solver"] = {"method": "monolithic", "tolerance": TOL}
    study = wcs.load_study(doc)
    ev = study.evaluate(study.nominal(), gradients=True)
    assert np.abs(ev.state.contact.slip).min() == 0.0 and not ev.nonsmooth
    assert check_against_fd(study) < 1e-5


def test_contact_slip_flags_a_sliding_node_at_zero_slip():
    """|s| has a kink at s = 0: on the frictionless patch's real model and state, a node that
    slides freely (frictionless: never stuck) set to s = 0 makes the partials non-smooth; the
    held node at x = 0 with s = 0 does not."""
    doc = yaml.safe_load((VALIDATION / "contact-patch.yaml").read_text())
    doc["criteria"] = [{"name": "slip", "kind": "contact_slip", "regions": ["interface"]}]
    study = wcs.load_study(doc)
    ev = study.evaluate(study.nominal())
    crit, model, state = ev.evaluator.criteria[0], ev.evaluator.model, ev.state
    partials = KINDS["contact_slip"].partials
    assert partials(crit, model, state, 0)[1] is False
    k = int(np.argmax(np.abs(state.contact.slip)))
    slip = state.contact.slip.copy()
    slip[k] = 0.0
    state = dataclasses.replace(state, contact=dataclasses.replace(state.contact, slip=slip))
    assert partials(crit, model, state, 0)[1] is True
