"""The criterion kinds added through the registry alone (`wcs.model.criteria.KINDS`): the largest
principal stress and the mean contact slip, each with adjoint gradients against central
finite differences (the rule of tests/model/test_gradients.py: 1e-5 relative plus the FD noise floor),
and the schema, the adjoint and the report reading them from the one entry."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs
from tests.model.test_gradients import TOL, VALIDATION, check_against_fd
from wcs.model.criteria import KINDS, _principal_kink
from wcs.errors import StudyError
from wcs.report.data import KIND_LABEL, KIND_UNITS

DATA = Path(__file__).resolve().parents[1] / "data"


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


def test_contact_pressure_peak_is_the_largest_nodal_pressure_in_the_region():
    """Φ = max over the contact nodes in G_r of the results' `contact_pressure` (a direct max over
    the fields a results file holds, with the nodes picked by their coordinates), and above the
    mean over the same region."""
    study = tresca_pad([{"name": "peak_edge", "kind": "contact_pressure_peak", "regions": ["edge"]},
                        {"name": "peak_all", "kind": "contact_pressure_peak", "regions": ["interface"]},
                        {"name": "mean_edge", "kind": "contact_pressure", "regions": ["edge"]}])
    ev = study.evaluate(study.nominal())
    assert ev.status == 0
    p, x = ev.fields["contact_pressure"].values, ev.fields["contact_coords"].values
    in_edge = (x[:, 0] >= 1.3 - 1e-9) & (x[:, 0] <= 1.5 + 1e-9) & (np.abs(x[:, 1] - 1.0) <= 0.01)
    assert in_edge.sum() >= 3
    assert ev.phi["peak_edge"] == p[in_edge].max()
    assert ev.phi["peak_all"] == p.max()
    assert ev.phi["peak_edge"] > ev.phi["mean_edge"]
    assert KIND_UNITS["contact_pressure_peak"] == "Pa"


def test_contact_pressure_peak_gradient_against_finite_differences():
    """The maximising node's pressure λ_k / w_k, differentiated by the adjoint as Φ6 is: central
    differences agree (the rule of tests/model/test_gradients.py) on the pad under its edge and overall."""
    study = tresca_pad([{"name": "peak_edge", "kind": "contact_pressure_peak", "regions": ["edge"]},
                        {"name": "peak_all", "kind": "contact_pressure_peak", "regions": ["interface"]}])
    assert check_against_fd(study) < 1e-5


def test_contact_pressure_peak_is_not_differentiable_where_the_maximising_node_ties():
    """Two nodes at the peak pressure (to round-off): the maximum's derivative is one-sided, so
    the partials say not differentiable; one node a little below (1e-4 of the peak) and it is
    differentiable again."""
    study = tresca_pad([{"name": "peak", "kind": "contact_pressure_peak", "regions": ["interface"]}])
    ev = study.evaluate(study.nominal())
    crit, model, state = ev.evaluator.criteria[0], ev.evaluator.model, ev.state
    partials = KINDS["contact_pressure_peak"].partials
    P, tie = partials(crit, model, state, 0)
    c = state.contact
    k = int(np.argmax(c.pressure))
    assert tie is False and np.flatnonzero(P.lam_n).tolist() == [k] and P.lam_n[k] == 1.0 / c.weight[k]
    j = int(np.argsort(c.pressure)[-2])
    for share, expect in ((1.0 - 1e-12, True), (1.0 - 1e-4, False)):
        force = c.force_n.copy()
        force[j] = share * c.pressure[k] * c.weight[j]
        s = dataclasses.replace(state, contact=dataclasses.replace(c, force_n=force))
        assert partials(crit, model, s, 0)[1] is expect


def test_criteria_name_their_reduction_in_the_terminal_and_the_report(tmp_path, capsys):
    """`contact_pressure` is a mean, `contact_pressure_peak` the largest nodal value: `wcs solve`
    and `wcs check` print each criterion with its reduction and region, the report's table too."""
    doc = yaml.safe_load((VALIDATION / "tresca-pad.yaml").read_text())
    doc["scene"]["regions_of_interest"]["edge"] = {"box": [1.3, 0.99, 1.5, 1.01]}
    doc["criteria"] = [{"name": "mean_p", "kind": "contact_pressure", "regions": ["interface"]},
                       {"name": "peak_p", "kind": "contact_pressure_peak", "regions": ["interface", "edge"]}]
    path = tmp_path / "pad.yaml"
    path.write_text(yaml.safe_dump(doc))
    from wcs.cli import main
    from wcs.report import data, html
    assert main(["solve", str(path), "-o", str(tmp_path / "pad.nc")]) == 0
    out = capsys.readouterr().out
    assert "mean_p = " in out and "(mean contact pressure (Φ6) over interface)" in out
    assert "(the largest over interface, edge of the largest nodal contact pressure over each)" in out
    assert main(["check", str(path)]) == 0
    assert "mean_p: mean contact pressure (Φ6) over interface (contact_pressure) [Pa]" in capsys.readouterr().out
    page = html.Report(data.load(tmp_path / "pad.nc")).limits()          # the table, without the figures
    assert '<td class="criterion-what">mean contact pressure (Φ6) over interface</td>' in page
    assert "largest nodal contact pressure over each" in page


@pytest.mark.slow
def test_contact_pressure_peak_gradient_in_3d_on_the_tunnels_fault():
    """3D (tetrahedra, two tangents per node, Tresca on the fault): the peak over the fault is
    one node's (not tied, not non-smooth) and its adjoint gradient matches central differences
    (measured: 1e-8 relative on E, nu, the rock's weight and the west load)."""
    doc = yaml.safe_load((VALIDATION.parent / "tunnel-fault-3d.yaml").read_text())
    doc.pop("limits", None)
    doc["scene"]["regions_of_interest"]["fault_roi"] = {"boundary": "fault_f"}
    doc["criteria"] = [{"name": "peak", "kind": "contact_pressure_peak", "regions": ["fault_roi"]}]
    doc["uncertain"] = {k: doc["uncertain"][k] for k in list(doc["uncertain"])[:4]}
    study = wcs.load_study(doc)
    ev = study.evaluate(study.nominal())
    assert ev.phi["peak"] == ev.fields["contact_pressure"].values.max()
    assert check_against_fd(study) < 1e-5


def test_distance_to_graded_triangles_is_the_minimum_over_all_of_them():
    """The nearest-facet search of the contact criteria, classed by triangle size, finds exactly
    the minimum over every triangle on a face graded 100x (3D Hertz from a .msh: one search radius
    for all triangles made it an all-pairs search, 64 s of a 72 s solve) wherever it is within the
    point's cap (half, exactly or twice the minimum), and inf elsewhere."""
    from types import SimpleNamespace

    from wcs.model.regions import _distance_to_facets, _triangle_distances
    rng = np.random.default_rng(1)
    n = 1500
    c = rng.uniform(-1, 1, (n, 3))
    c[:, 2] = 0.0
    size = 0.002 + 0.2 * np.linalg.norm(c, axis=1) ** 3
    tri = c[:, None, :] + size[:, None, None] * rng.normal(size=(n, 3, 3))
    mesh = SimpleNamespace(p=tri.reshape(-1, 3).T, facets=np.arange(3 * n).reshape(n, 3).T)
    x = rng.uniform(-1, 1, (200, 3)) * [1.0, 1.0, 0.05]
    brute = np.array([_triangle_distances(np.repeat(xi[None], n, 0), tri).min() for xi in x])
    cap = brute * rng.choice([0.5, 1.0, 2.0], len(x))
    expected = np.where(cap >= brute, brute, np.inf)
    assert np.isfinite(expected).sum() > 100 and np.isinf(expected).sum() > 30
    assert np.array_equal(_distance_to_facets(mesh, np.arange(n), x, cap), expected)
