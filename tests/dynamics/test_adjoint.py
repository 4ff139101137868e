"""Adjoint gradients through time (`wcs.dynamics.adjoint`): the reverse sweep
over the levels' final active sets agrees with central differences of the reduced criteria to
1e-5 of each criterion's change across the box, for the max, final and mean reductions; where the
reduced history is not differentiable the gradient is left to finite differences and the
evaluation says why; `wcs run` uses it and its results file says so.

The finite differences: central, with the step 1e-4 of the box's width. On the two bars the
criteria are smooth in (E, ρ) on the active sets of the impact (the contact-pressure history is a
wave of speed √(E/ρ)), so the truncation error is ≈ h² J'''/6 ≈ 1e-8 of the change across the box
and the contact solves' round-off (relative tolerance 1e-8 of values ≈ the change) divided by
the step 1e-4 is ≈ 1e-4 × 1e-8 / 1e-4: both far below the 1e-5 asserted (measured: ≤ 3e-7)."""
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from tests.dynamics.test_bars import DURATION, bars
from tests.support.bad_studies import write_study
from wcs.cli import main
from wcs.dynamics.adjoint import reduction_weights
from wcs.dynamics.history import DynamicEvaluator
from wcs.study import load_study

ROOT = Path(__file__).resolve().parents[2]
BOX = {"materials.steel.E": [1.9e11, 2.3e11], "materials.steel.density": [7700.0, 8000.0]}
FD_STEP = 1e-4              # of the box's width


def seed_bars(tmp_path, **search):
    """The two bars under the seed scheme to past the impact's middle, E and ρ uncertain, one
    criterion per reduction (`min` of the far end's travel, 0 at the start and 2e-8 of its largest
    one level later, before the wave arrives: tied levels)."""
    doc = bars(0.05, 1e-5, "seed", width=0.05, end=DURATION / 2)
    doc["scene"]["boundaries"]["t_end"] = {"body": "target", "segment": [[2.0, 0.0], [2.0, 0.05]]}
    doc["scene"]["regions_of_interest"]["end"] = {"boundary": "t_end"}
    doc["uncertain"] = BOX
    doc["criteria"] = [
        {"name": "peak", "kind": "contact_pressure", "regions": ["face"], "over_time": "max"},
        {"name": "travel", "kind": "mean_normal_displacement", "regions": ["end"], "direction": [1.0, 0.0],
         "over_time": "final"},
        {"name": "average", "kind": "contact_pressure", "regions": ["face"], "over_time": "mean"},
        {"name": "least", "kind": "mean_normal_displacement", "regions": ["end"], "direction": [1.0, 0.0],
         "over_time": "min"}]
    if search:
        doc["search"] = search
    return write_study(doc, tmp_path, "bars.yaml")


def check_against_central_differences(ev, x, lower, upper, names, which=None):
    """Each criterion's adjoint dJ/dx_i against central differences, relative to J's change across
    the box along x_i (J at the box's two faces through x), for every i or those in `which`."""
    e = ev.evaluate(x, gradients=True)
    for i in range(x.size) if which is None else which:
        h = FD_STEP * (upper[i] - lower[i])
        at = {}
        for key, value in (("+", x[i] + h), ("-", x[i] - h), ("lo", lower[i]), ("hi", upper[i])):
            xi = x.copy()
            xi[i] = value
            at[key] = ev.evaluate(xi).phi
        for c in names:
            fd = (at["+"][c] - at["-"][c]) / (2 * h)
            change = abs(at["hi"][c] - at["lo"][c])
            assert change > 0, (c, i)
            assert abs(e.grad[c][i] - fd) * (upper[i] - lower[i]) <= 1e-5 * change, (c, i, e.grad[c][i], fd)
    return e


def test_adjoint_through_time_agrees_with_central_differences_for_max_final_and_mean(tmp_path):
    study = load_study(seed_bars(tmp_path))
    ev = DynamicEvaluator(study)
    lower, upper = (np.array(v, float) for v in zip(*BOX.values()))
    e = check_against_central_differences(ev, np.array([2.05e11, 7890.0]), lower, upper,
                                          ["peak", "travel", "average"])
    assert e.phi == ev.evaluate(np.array([2.05e11, 7890.0])).phi       # the gradients change no value


def test_a_peak_tied_between_levels_is_not_differentiable_and_the_evaluation_says_so(tmp_path):
    """The far end's least travel is 0 at the start and within 1e-7 of its largest one level later:
    the `min` is tied between levels, its gradient is left to finite differences (None) and the
    message names the levels."""
    ev = DynamicEvaluator(load_study(seed_bars(tmp_path)))
    e = ev.evaluate(np.array([2.05e11, 7890.0]), gradients=True)
    assert e.grad["least"] is None
    assert "least: finite-difference gradient, its least value over time is reached at levels 0 and 1" in e.message
    assert all(e.grad[c] is not None for c in ("peak", "travel", "average"))


def test_each_reduction_weighs_its_levels_and_a_tie_is_named():
    phi = np.array([0.0, 3.0, 1.0, 2.0])
    for how, weights in (("max", [0, 1, 0, 0]), ("min", [1, 0, 0, 0]), ("final", [0, 0, 0, 1]),
                         ("mean", [0.25] * 4)):
        c, why = reduction_weights(how, phi)
        assert np.array_equal(c, weights) and why == "", how
    c, why = reduction_weights("max", np.array([1.0, 3.0, 3.0 - 1e-8, 0.0]))
    assert why == "its peak over time is reached at levels 1 and 2 (within 1e-07)"
    c, why = reduction_weights("max", np.array([1.0, 3.0 - 1e-8, 3.0, 2.0, 3.0, 3.0]))   # a plateau: all named
    assert why == "its peak over time is reached at 4 levels from 1 to 5 (within 1e-07)" and c[2] == 1.0


def test_a_source_point_on_a_cell_face_is_not_differentiable_and_the_evaluation_says_so(tmp_path):
    """A point force at a mesh node (on the faces of the cells around it) whose position is
    uncertain: its P1 nodal loads have a kink there, so every gradient is left to finite differences."""
    doc = yaml.safe_load(seed_bars(tmp_path).read_text())
    doc["scene"]["sources"] = {"quake": {"point": [0.5, 0.0], "force": [1e3, 0.0],
                                         "wavelet": {"ricker": {"frequency": 2e4, "delay": 1e-4}}}}
    doc["uncertain"] = {"sources.quake.point.0": [0.4, 0.6]}
    ev = DynamicEvaluator(load_study(write_study(doc, tmp_path, "source.yaml")))
    e = ev.evaluate(np.array([0.5]), gradients=True)
    assert all(g is None for g in e.grad.values())
    assert "the point of source 'quake' lies on a cell face" in e.message
    assert all(g is not None for c, g in ev.evaluate(np.array([0.5 + 1e-3]), gradients=True).grad.items()
               if c != "least")


def test_the_stabilized_schemes_adjoint_agrees_with_central_differences(tmp_path):
    """The contact-stabilized Newmark rule (its predictor's M-projection and the trapezoidal step)
    through time, on the two bars (measured: ≤ 7e-9 of the change across the box)."""
    doc = yaml.safe_load(seed_bars(tmp_path).read_text())
    doc["dynamics"]["scheme"] = "stabilized"
    ev = DynamicEvaluator(load_study(write_study(doc, tmp_path, "stabilized.yaml")))
    lower, upper = (np.array(v, float) for v in zip(*BOX.values()))
    e = check_against_central_differences(ev, np.array([2.05e11, 7890.0]), lower, upper,
                                          ["peak", "travel", "average"])
    assert "finite-difference gradient" not in e.message.replace("least: finite-difference gradient", "")


def test_a_thermal_scenes_adjoint_agrees_with_central_differences(tmp_path):
    """The heated plate (studies/heated-plate.yaml, coarse) from its static thermal state, its top
    loaded by a ramped pressure: the heave at the end, the mean shear intensity over time and the
    core's temperature at the end against central differences over the modulus, the expansion and
    the top's temperature (measured: ≤ 2e-8 of the change across the box; the temperature does
    not depend on the modulus nor on the expansion: both 0)."""
    doc = yaml.safe_load((ROOT / "studies/heated-plate.yaml").read_text())
    doc.pop("include")
    doc["scene"]["mesh"]["size"] = 0.1
    doc["scene"]["materials"]["steel"]["density"] = 7850.0
    doc["scene"]["loads"] = {"top": {"pressure": 1.0e8, "time": {"ramp": 2.0e-5}}}
    doc["dynamics"] = {"end_time": 1.0e-4, "time_step": 1.0e-5, "scheme": "seed", "output_every": 5,
                       "initial": "static"}
    box = {"materials.steel.E": [1.9e11, 2.3e11], "materials.steel.expansion": [1.0e-5, 1.4e-5],
           "thermal.temperature.top": [323.0, 363.0]}
    doc["uncertain"] = box
    doc["criteria"] = [dict(doc["criteria"][0], over_time="final"), dict(doc["criteria"][1], over_time="mean"),
                       dict(doc["criteria"][2], over_time="final")]
    ev = DynamicEvaluator(load_study(write_study(doc, tmp_path, "plate.yaml")))
    lower, upper = (np.array(v, float) for v in zip(*box.values()))
    x = lower + 0.37 * (upper - lower)
    check_against_central_differences(ev, x, lower, upper, ["heave", "shear"])
    e = check_against_central_differences(ev, x, lower, upper, ["temperature"], which=[2])
    assert e.grad["temperature"][:2].tolist() == [0.0, 0.0]


def cylinder(tmp_path, box, scheme="stabilized"):
    """studies/validation/cylinder-impact.yaml, coarse (1 mm at the contact, Δt = 4 µs, 55 levels
    through the whole impact), with one criterion per reduction and `box` uncertain."""
    doc = yaml.safe_load((ROOT / "studies/validation/cylinder-impact.yaml").read_text())
    doc["dynamics"]["scheme"] = scheme
    doc["dynamics"]["time_step"] = 4e-6
    doc["scene"]["mesh"]["refine"] = [{"box": [0.0, -0.002, 0.002, 0.002], "size": 4e-4},
                                      {"box": [0.0, -0.008, 0.008, 0.008], "size": 1.6e-3}]
    doc["uncertain"] = box
    doc["criteria"] = [
        {"name": "peak", "kind": "contact_pressure_peak", "regions": ["contact_zone"], "over_time": "max"},
        {"name": "average", "kind": "contact_pressure", "regions": ["contact_zone"], "over_time": "mean"},
        {"name": "bounce", "kind": "mean_normal_displacement", "regions": ["contact_zone"],
         "direction": [0.0, 1.0], "over_time": "final"}]
    return DynamicEvaluator(load_study(write_study(doc, tmp_path, "cylinder.yaml")))


@pytest.mark.slow
def test_the_stabilized_adjoint_on_the_cylinder_impact_and_a_predictor_at_a_switch(tmp_path):
    """The cylinder dropped on the block (stabilized): the peak, mean and final values against
    central differences over the steel's modulus and the aluminium's density; the mean pressure
    over a window that holds the whole impact is its impulse over the window, which the modulus
    changes by 4e-6 of its value only: the levels' shares of its derivative nearly cancel, so the
    data's central differences must carry little round-off (at a data step of 1e-6 of the width
    this derivative was 3.5 % of that change off, at 1e-4 3e-5): it is held to 1e-5 of the change
    along the density and to 1e-5 of itself along the modulus (measured: 3e-7; the others ≤ 5e-6 of
    their changes). At (2.03e11, 2737) the predictor's projection leaves a node open at a gap
    of 7.5e-12 m at level 21 (a switch within reach): the gradients are left to finite differences
    and the evaluation says so."""
    box = {"materials.steel.E": [1.9e11, 2.1e11], "materials.aluminium.density": [2600.0, 2800.0]}
    ev = cylinder(tmp_path, box)
    lower, upper = (np.array(v, float) for v in zip(*box.values()))
    check_against_central_differences(ev, np.array([1.97e11, 2690.0]), lower, upper, ["peak", "bounce"])
    check_against_central_differences(ev, np.array([1.97e11, 2690.0]), lower, upper, ["average"], which=[1])
    for scheme in ("stabilized", "seed"):          # along the modulus: to 1e-5 of itself, both schemes
        one = cylinder(tmp_path, box, scheme)
        x, h = np.array([1.97e11, 2690.0]), np.array([FD_STEP * 2e10, 0.0])
        fd = (one.evaluate(x + h).phi["average"] - one.evaluate(x - h).phi["average"]) / (2 * h[0])
        assert abs(one.evaluate(x, gradients=True).grad["average"][0] - fd) <= 1e-5 * abs(fd), scheme
    e = ev.evaluate(np.array([2.03e11, 2737.0]), gradients=True)
    assert all(g is None for g in e.grad.values())
    assert "at time level 21 the predictor's projection: contact node 4 is open and touching" in e.message


def test_wcs_run_takes_the_adjoint_and_its_results_say_so(tmp_path):
    path = seed_bars(tmp_path, method="local", budget=6, local={"starts": 1}, sample={"design": "lhs", "n": 2, "seed": 1})
    out = tmp_path / "run.nc"
    assert main(["run", str(path), "-o", str(out), "--quiet", "--no-mesh-check"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds.attrs["gradients"].startswith("adjoint through time")
        notes = dict(zip(map(str, ds["criterion"].values), map(str, ds["certificate_note"].values)))
        assert all("gradients through time by the adjoint" in n for n in notes.values())
        grad = ds["grad"].sel(criterion="peak").values
        assert np.isfinite(grad).all(axis=1).any()                 # adjoint gradients were recorded
        assert "fd" not in set(map(str, ds["stage"].values)) or np.isnan(ds["grad"].sel(criterion="least")).all()


@pytest.mark.slow
def test_seismic_adjoint_agrees_with_central_differences_at_a_coarse_step(tmp_path):
    """studies/tunnel-fault-seismic.yaml at Δt = 1e-2 s (60 levels): the static initial state, the
    released supports with their dashpots, the source's amplitude, depth and frequency and the
    rock's modulus, each against central differences."""
    doc = yaml.safe_load((ROOT / "studies/tunnel-fault-seismic.yaml").read_text())
    doc["dynamics"].update(time_step=1e-2)
    study = load_study(write_study(doc, tmp_path, "seismic.yaml"))
    ev = DynamicEvaluator(study)
    lower = np.array([u.lower for u in study.uncertain])
    upper = np.array([u.upper for u in study.uncertain])
    check_against_central_differences(ev, lower + 0.37 * (upper - lower), lower, upper, ["peak_slip", "convergence"])
