"""The `dynamics:` block, the dynamic material data and `wcs solve` on a dynamic study:
what is refused (exit 2, the key path named), what static studies keep (bitwise), what is written."""
import copy

import numpy as np
import pytest
import xarray as xr

from tests.support.bad_studies import demo_doc, write_study
from tests.dynamics.test_bars import DURATION, bars
from wcs.cli import main
from wcs.dynamics.history import simulate
from wcs.dynamics.mass import mass_cell_matrices, mass_operator
from wcs.dynamics.stepping import dynamic_matrices, region_dynamics
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs import load_study


def coarse(scheme="stabilized"):
    return bars(0.05, 1e-5, scheme, width=0.05, end=DURATION)


def _set(doc, path, value):
    keys = path.split(".")
    for k in keys[:-1]:
        doc = doc[k]
    if value is None:
        del doc[keys[-1]]
    else:
        doc[keys[-1]] = value


@pytest.mark.parametrize("path, value, fragment", [
    ("scene.materials.steel.density", None, "scene.materials.steel.density: is missing"),
    ("scene.materials.steel.density", -1.0, "scene.materials.steel.density"),
    ("scene.materials.steel.viscosity", {"ratio": 1e-3, "E": 1.0, "nu": 0.3}, "scene.materials.steel.viscosity"),
    ("scene.materials.steel.viscosity", {"E": 1.0}, "scene.materials.steel.viscosity"),
    ("dynamics.time_step", 1.0, "dynamics"),
    ("dynamics.time_step", 0.0, "dynamics.time_step"),
    ("dynamics.scheme", "newmark", "dynamics.scheme"),
    ("dynamics.output_every", 0, "dynamics.output_every"),
    ("dynamics.initial", {"velocity": {"hammer": [1.0, 0.0]}}, "dynamics.initial.velocity.hammer"),
    ("dynamics.initial", {"velocity": {"striker": [1.0, 0.0, 0.0]}}, "dynamics.initial.velocity.striker"),
    ("dynamics.initial", "moving", "dynamics.initial"),
    ("dynamics.damping", 1.0, "dynamics.damping: unknown key 'damping'"),
    ("scene.absorbing", {"dashpots": ["top"]}, "scene.absorbing.dashpots.0: unknown boundary 'top'"),
    ("scene.absorbing", {}, "scene.absorbing: give a `layer`, `dashpots` or both"),
    ("scene.sources", {"q": {"point": [0.1, 0.01, 0.0], "force": [1.0, 0.0, 0.0],
                             "wavelet": {"ricker": {"frequency": 1e4, "delay": 1e-3}}}}, "scene.sources.q.point"),
    ("scene.loads", {"s_top": {"pressure": 1.0, "time": {"ramp": 0.0}}}, "scene.loads.s_top.time.ramp"),
    ("solver", {"method": "qp"}, "solver.method: 'qp' does not step in time"),
    ("uncertain", {"materials.steel.density": [7000.0, 7000.0]}, "lies outside the box"),
])
def test_bad_dynamic_input_names_the_key(path, value, fragment):
    doc = coarse()
    _set(doc, path, value)
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert fragment in str(info.value)


def test_dynamic_numbers_are_addressable():
    doc = coarse()
    doc["scene"]["materials"]["steel"]["viscosity"] = {"ratio": 1e-6}
    doc["uncertain"] = {"materials.steel.density": [7000.0, 8000.0], "materials.steel.viscosity.ratio": [0.0, 2e-6]}
    study = load_study(doc)
    assert study.parameters.names == ["materials.steel.density", "materials.steel.viscosity.ratio"]


@pytest.mark.parametrize("path, value, fragment", [
    ("uncertain", {"materials.rubber.density": [900.0, 1100.0]}, "uncertain.materials.rubber.density: acts only"),
    ("criteria", [{"name": "shear", "kind": "contact_pressure", "regions": ["under_pad"], "over_time": "max"}],
     "criteria.0.over_time: applies only"),
])
def test_a_static_study_refuses_what_acts_in_time(path, value, fragment):
    doc = demo_doc()
    doc["scene"]["materials"]["rubber"]["density"] = 1000.0
    _set(doc, path, value)
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert fragment in str(info.value)


def test_density_and_viscosity_change_nothing_in_a_static_study():
    """Bitwise the same criteria with and without the dynamic data (they act only in time)."""
    plain = demo_doc()
    plain["scene"]["mesh"] = {"size": 0.2}
    dynamic = copy.deepcopy(plain)
    for m in dynamic["scene"]["materials"].values():
        m.update(density=1000.0, viscosity={"ratio": 1e-3})
    a, b = load_study(plain), load_study(dynamic)
    assert a.dynamics is None and b.dynamics is None
    ea, eb = a.evaluate(a.nominal()), b.evaluate(b.nominal())
    assert ea.status == eb.status == 0
    assert all(ea.phi[k] == eb.phi[k] for k in ea.phi)
    assert np.array_equal(ea.state.u, eb.state.u)


def test_consistent_mass_holds_the_mass_of_each_body():
    """1ᵀ M 1 over one component = ρ |Ω| (2D: triangles, 3D: a cube of 6 tetrahedra), and each
    cell matrix is |T|(1 + δ_ab)/((d+1)(d+2)) — the exact ∫ N_a N_b."""
    p = np.array([[0.0, 2.0, 0.0], [0.0, 0.0, 1.0]])
    m = mass_cell_matrices(p, np.array([[0], [1], [2]]))[0, 0, :, :, 0, 0]
    assert m == pytest.approx(np.array([[2, 1, 1], [1, 2, 1], [1, 1, 2]]) / 12.0, rel=1e-14)   # |T| = 1
    cube = np.array([[0, 1, 0, 1, 0, 1, 0, 1], [0, 0, 1, 1, 0, 0, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1]], float)
    tets = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]]).T
    local = mass_cell_matrices(cube, tets)
    assert local[0, :, :, :, 0, 0].sum() == pytest.approx(1.0, rel=1e-14)
    assert local[0, 0, 0, 0, 0, 0] == pytest.approx((1 / 6) * 2 / 20, rel=1e-14)


def test_mass_and_viscous_matrices_of_a_study():
    """M of the bars: 1ᵀ M_x 1 = ρ · 2L · width; viscosity {ratio: η} gives C = η K."""
    doc = coarse()
    doc["scene"]["materials"]["steel"]["viscosity"] = {"ratio": 2e-6}
    study = load_study(doc)
    ev = Evaluator(study)
    model = ev.model
    rho, visc = region_dynamics(model, ev.map)
    M = mass_operator(model)(rho)
    ones_x = np.tile([1.0, 0.0], model.nnodes)
    assert ones_x @ M @ ones_x == pytest.approx(7850.0 * 2.0 * 0.05, rel=1e-12)
    mats = dynamic_matrices(model, ev.map.coefficients(), rho, visc)
    assert abs(mats.C - 2e-6 * mats.K).max() <= 1e-12 * abs(mats.C).max()


def test_a_support_in_the_way_of_an_initial_velocity_is_bad_input():
    doc = coarse()
    doc["dynamics"]["initial"] = {"velocity": {"striker": [1.0, 0.5]}}
    study = load_study(doc)
    with pytest.raises(StudyError, match="dynamics.initial.velocity: a support holds"):
        simulate(Evaluator(study))


def test_solve_writes_the_history_and_a_paraview_series(tmp_path, capsys):
    doc = coarse()
    doc["dynamics"].update(output_every=5, end_time=DURATION / 3)
    path = write_study(doc, tmp_path, "bars.yaml")
    out = tmp_path / "bars.nc"
    assert main(["solve", str(path), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "pressure = " in printed and "the peak over time" in printed
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        levels = load_study(doc).dynamics.levels
        assert ds["phi_history"].dims == ("criterion", "time") and ds.sizes["time"] == levels + 1
        assert float(ds["phi"].sel(criterion="pressure")) == float(ds["phi_history"].max())
        assert ds["time"].values[-1] == pytest.approx(levels * 1e-5)
        assert ds.sizes["output_time"] == len(range(0, levels + 1, 5)) + (levels % 5 != 0)
        assert float(ds["contact_force"].min()) >= 0.0
    pvd = (tmp_path / "bars.pvd").read_text()
    assert pvd.count("<DataSet") == len(list(tmp_path.glob("bars-*.vtu")))


def test_a_dynamic_study_is_never_answered_by_a_static_solve():
    study = load_study(coarse())
    with pytest.raises(StudyError, match="dynamics: a dynamic study is evaluated over its time levels"):
        study.evaluate(study.nominal())


def test_check_prints_the_levels_and_refuses_a_static_start_without_equilibrium(tmp_path, capsys):
    """`wcs check` of a dynamic study solves no static state it does not start from; the two bars
    have none (each is free along x), so `initial: static` is bad input (exit 2)."""
    doc = coarse()
    path = write_study(doc, tmp_path, "bars.yaml")
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "dynamics: 34 levels of 1e-05 s" in out and "scheme stabilized" in out and out.rstrip().endswith("ok")
    doc["dynamics"]["initial"] = "static"
    path = write_study(doc, tmp_path, "static.yaml")
    assert main(["check", str(path)]) == 2
    assert "the static initial state (dynamics.initial: static) cannot be solved" in capsys.readouterr().err
