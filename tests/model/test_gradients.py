"""Adjoint gradients against central finite differences, for every criterion kind
(Φ1–Φ6, von Mises) and every parameter kind (Lamé and E/ν moduli, expansion,
conductivity, specific gravity, pressure, traction, body force, support values
(component and roller), boundary temperature, heat source, reference
temperature, Tresca slip-limit profile, Coulomb coefficient).

Tolerance: 1e-5 relative, plus the finite differences' own noise floor
10·tol·|Φ|/h (the solver stops at a relative tolerance `tol`; a difference
quotient with step h cannot resolve derivatives below that)."""
from pathlib import Path

import numpy as np
import pytest
import yaml

import wcs

DATA = Path(__file__).resolve().parents[1] / "data"
VALIDATION = Path(__file__).resolve().parents[2] / "studies" / "validation"
TOL = 1e-13


def check_against_fd(study, rel=1e-5, step=1e-4):
    x0 = study.nominal()
    ev = study.evaluate(x0, gradients=True)
    assert ev.status == 0 and not ev.nonsmooth, ev.message
    lo, hi = study.parameters.lower, study.parameters.upper
    worst = 0.0
    for k, name in enumerate(study.parameters.names):
        h = step * (hi[k] - lo[k])
        xp, xm = x0.copy(), x0.copy()
        xp[k] += h
        xm[k] -= h
        fp, fm = study.evaluate(xp), study.evaluate(xm)
        for c, phi in ev.phi.items():
            fd = (fp.phi[c] - fm.phi[c]) / (2 * h)
            ad = ev.grad[c][k]
            noise = 10 * TOL * abs(phi) / h
            assert abs(ad - fd) <= rel * abs(fd) + noise, (name, c, ad, fd)
            if abs(fd) > 1e3 * noise:
                worst = max(worst, abs(ad - fd) / abs(fd))
    return worst


def test_every_criterion_and_parameter_kind():
    study = wcs.load_study(DATA / "gradients-all-kinds.yaml")
    assert check_against_fd(study) < 1e-5


def coulomb_pad(method="monolithic"):
    """The floating pad of studies/validation/tresca-pad.yaml with Coulomb friction F ∈ [0.3, 0.5]:
    closed nodes slipping and sticking, the pressure at an edge and the pad's shift."""
    doc = yaml.safe_load((VALIDATION / "tresca-pad.yaml").read_text())
    doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.04}]}
    doc["scene"]["contacts"]["interface"]["friction"] = {"coefficient": 0.4}
    doc["scene"]["regions_of_interest"]["edge"] = {"box": [1.3, 0.99, 1.5, 1.01]}
    doc["uncertain"] = {"contacts.interface.friction.coefficient": [0.3, 0.5],
                        "loads.pad_top.traction.0": [1.0e5, 3.0e5],
                        "materials.rubber.nu": [0.40, 0.48]}
    doc["criteria"] = [{"name": "edge_pressure", "kind": "contact_pressure", "regions": ["edge"]},
                       {"name": "shift", "kind": "mean_normal_displacement", "regions": ["pad_top"],
                        "direction": [1.0, 0.0]}]
    doc["solver"] = {"method": method, "tolerance": TOL}
    if method == "iterative":
        doc["solver"]["iterative"] = {"tolerance": 1e-12}
    return wcs.load_study(doc)


def test_coulomb_coefficient_and_floating_pad():
    assert check_against_fd(coulomb_pad()) < 1e-5


def test_linear_scene_without_contact():
    study = wcs.load_study(Path(__file__).resolve().parents[2] / "studies" / "glued-layers.yaml")
    assert check_against_fd(study) < 1e-5


def test_nonsmooth_point_is_flagged():
    """At a slip limit exactly equal to the stick force the active set is about to change."""
    doc = yaml.safe_load((VALIDATION / "contact-patch.yaml").read_text())
    doc["scene"]["loads"]["block_top"] = {"pressure": 0.0}       # contact just closed, zero pressure
    doc["uncertain"] = {"loads.block_top.pressure": [0.0, 1.0e6]}
    study = wcs.load_study(doc)
    ev = study.evaluate(study.nominal(), gradients=True)
    assert ev.status == 0 and ev.nonsmooth


def test_tunnel_with_redundant_contact_constraints():
    """The tunnel: fault ends held by supports on both sides (zero contact rows) and by rollers
    on both sides (tangent parallel to normal) make the active-set system singular; the
    multipliers are not unique there but the criteria's gradients are (least squares)."""
    doc = yaml.safe_load((Path(__file__).resolve().parents[2] / "studies" / "tunnel-fault.yaml").read_text())
    doc["solver"] = {"method": "monolithic", "tolerance": TOL}
    assert check_against_fd(wcs.load_study(doc)) < 1e-5
