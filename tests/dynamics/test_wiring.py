"""The dynamic loads wired into a study and its levels: sources, absorbing boundaries and load time
functions accepted and addressable by dotted path, refused where wrong (exit 2 naming the key),
and acting in the levels (the impulse of a source, the release of held boundaries that take
dashpots, a ramped load's static start)."""
import copy

import numpy as np
import pytest

from tests.support.bad_studies import drop, put
from wcs.cli import main
from wcs.dynamics.absorbing import weighted_mass
from wcs.dynamics.history import simulate
from wcs.dynamics.mass import mass_operator
from wcs.dynamics.sources import ricker
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs.study import load_study

E, RHO = 2.0e11, 7850.0
C = np.sqrt(E / RHO)              # ν = 0: the P-wave speed of the column, 5048 m/s
H, W = 1.0, 0.1                   # column height and width [m]
PULSE = 6e-5                      # a triangle pulse of traction on the top, 0.3 m long in the column


def column(dashpots=True, end=4e-4, dt=6e-6, h=0.05):
    """A column with lateral rollers, held at its bottom, struck on its top by a pulse of
    traction (a 1D P wave); dashpots on the held bottom when asked."""
    seg = lambda a, z: {"body": "col", "segment": [a, z]}     # noqa: E731
    scene = {
        "mesh": {"size": h},
        "materials": {"steel": {"E": E, "nu": 0.0, "density": RHO}},
        "bodies": {"col": {"regions": [{"material": "steel", "shape": {"rectangle": [0.0, 0.0, W, H]}}]}},
        "boundaries": {"left": seg([0.0, 0.0], [0.0, H]), "right": seg([W, 0.0], [W, H]),
                       "bottom": seg([0.0, 0.0], [W, 0.0]), "top": seg([0.0, H], [W, H])},
        "supports": {"left": {"normal": 0.0}, "right": {"normal": 0.0}, "bottom": {"u": [0.0, 0.0]}},
        "loads": {"top": {"traction": [0.0, -1.0e6],
                          "time": {"table": [[0.0, 0.0], [PULSE / 2, 1.0], [PULSE, 0.0]]}}},
    }
    if dashpots:
        scene["absorbing"] = {"dashpots": ["bottom"]}
    return {"study": "column", "scene": scene,
            "dynamics": {"end_time": end, "time_step": dt, "scheme": "stabilized", "initial": "static"}}


def quake_block():
    """A free block at rest (no supports) with a point force under a Ricker wavelet."""
    doc = column(dashpots=False, end=1e-3, dt=1e-5, h=0.1)
    scene = doc["scene"]
    scene["supports"], scene["loads"] = {}, {}
    scene["sources"] = {"quake": {"point": [0.05, 0.4], "force": [2.0e3, 1.0e3],
                                  "wavelet": {"ricker": {"frequency": 4.0e3, "delay": 5e-4}}}}
    doc["dynamics"]["initial"] = "rest"
    return doc


def test_the_dynamic_loads_are_addressable_by_path():
    doc = quake_block()
    doc["scene"]["absorbing"] = {"layer": {"boundaries": ["bottom"], "thickness": 0.2, "damping": 100.0}}
    doc["scene"]["loads"] = {"top": {"pressure": 1.0e3, "time": {"ramp": 1e-4}}}
    doc["uncertain"] = {"sources.quake.force.1": [0.5e3, 1.5e3], "sources.quake.point.1": [0.3, 0.5],
                        "sources.quake.wavelet.ricker.frequency": [3.0e3, 5.0e3],
                        "absorbing.layer.damping": [50.0, 150.0], "loads.top.time.ramp": [1e-4, 2e-4]}
    study = load_study(doc)
    assert study.parameters.names == list(doc["uncertain"])


@pytest.mark.parametrize("change, fragment", [
    ({"uncertain": {"sources.quake.wavelet.ricker.frequency": [1.0e3, 5.0e3]}},
     "uncertain.sources.quake.wavelet.ricker.frequency: at the corner frequency 1000 Hz, delay 0.0005 s"),
    ({"uncertain": {"sources.quake.wavelet.ricker.delay": [1e-4, 6e-4]}},
     "uncertain.sources.quake.wavelet.ricker.delay: at the corner frequency 4000 Hz, delay 0.0001 s"),
    ({"dynamics": None}, "scene.sources: acts only in a dynamic study"),
    ({"scene.absorbing": {"dashpots": ["base"]}}, "scene.absorbing.dashpots.0: unknown boundary 'base'"),
    ({"scene.absorbing": {"layer": {"boundaries": ["top", "base"], "thickness": 0.1, "damping": 1.0}}},
     "scene.absorbing.layer.boundaries.1: unknown boundary 'base'"),
])
def test_bad_dynamic_loads_name_the_key(change, fragment):
    doc = quake_block()
    for path, value in change.items():
        keys = path.split(".")
        (drop(keys) if value is None else put(keys, value))(doc)
    with pytest.raises(StudyError) as info:
        load_study(doc)
    assert fragment in str(info.value)


def test_a_varied_support_under_dashpots_is_refused():
    doc = column()
    doc["uncertain"] = {"supports.bottom.u.1": [-1e-3, 0.0]}
    with pytest.raises(StudyError, match="uncertain.supports.bottom.u.1: boundary 'bottom' takes dashpots"):
        load_study(doc)


def test_check_locates_the_source_at_the_corners_of_its_box(tmp_path, capsys):
    """`wcs check`: a source point whose box reaches outside the mesh is exit 2 naming the source."""
    import yaml
    doc = quake_block()
    doc["uncertain"] = {"sources.quake.point.0": [0.02, 0.15]}           # the block ends at x = 0.1
    path = tmp_path / "quake.yaml"
    path.write_text(yaml.safe_dump(doc))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "scene.sources.quake.point" in err and "outside the mesh" in err


def test_a_source_gives_the_free_block_its_impulse():
    """No supports: the momentum M v of the block is the impulse of the source, F ∫ r dt (the
    stabilized rule's trapezoid of f(t) to round-off; the wavelet's integral to 1e-3 of the
    peak impulse over the levels, r has zero mean)."""
    study = load_study(quake_block())
    ev = Evaluator(study)
    hist = simulate(ev, study.nominal())
    M = mass_operator(ev.model)(np.full(len(ev.model.region_material), RHO))
    t = np.asarray(hist.time)
    force = np.array([2.0e3, 1.0e3])
    r = ricker(t, 4.0e3, 5e-4)
    trapezoid = np.concatenate([[0.0], np.cumsum((r[1:] + r[:-1]) / 2 * np.diff(t))])
    peak = np.abs(trapezoid).max()
    for k, level in enumerate(hist.output_levels):
        p = (M @ hist.velocity[k]).reshape(-1, 2).sum(axis=0)
        assert p == pytest.approx(force * trapezoid[level], abs=1e-9 * force.max() * peak)
    assert peak > 1e-5                       # the source acted: its half cycle's impulse is ~1e-4 s


def test_dashpots_on_the_held_bottom_absorb_the_pulse():
    """The bottom is held in the static state and takes dashpots: the levels release it, the
    pulse leaves through it (the energy left is ~0.1 % of the pulse's; the held bottom keeps it
    all, a dashpot on held components would do nothing)."""
    kept = {}
    for dashpots in (True, False):
        study = load_study(column(dashpots))
        hist = simulate(Evaluator(study), study.nominal())
        energy = np.asarray(hist.kinetic) + np.asarray(hist.elastic)
        kept[dashpots] = energy[-1] / energy.max()
    assert kept[False] == pytest.approx(1.0, abs=0.01)
    assert kept[True] < 0.01


def test_released_supports_keep_the_static_state():
    """A column under its full top load (no time function), held at its bottom with dashpots:
    the levels replace the support by its reaction and nothing moves (to the solver's round-off)."""
    doc = column()
    del doc["scene"]["loads"]["top"]["time"]
    study = load_study(doc)
    hist = simulate(Evaluator(study), study.nominal())
    u = np.asarray(hist.displacement)
    assert np.abs(u).max() == pytest.approx(1e6 * H / E, rel=1e-6)     # the static shortening σH/E
    assert np.abs(u - u[0]).max() < 1e-9 * np.abs(u).max()
    assert np.abs(hist.velocity).max() < 1e-9 * C * 1e6 / E


def test_a_ramped_load_starts_from_its_static_state_at_t0():
    """`initial: static` balances the loads at t = 0: a load ramped from 0 starts unloaded (the
    first level, at 0.6 % of the ramp, moves by far less than the full load's σH/E)."""
    doc = column(dashpots=False, end=1.2e-4)
    doc["scene"]["loads"]["top"]["time"] = {"ramp": 1e-3}
    study = load_study(doc)
    hist = simulate(Evaluator(study), study.nominal())
    assert np.abs(hist.displacement[0]).max() == 0.0
    assert np.abs(hist.displacement[1]).max() < 0.01 * 1e6 * H / E


def test_one_consistent_mass():
    """The layer's α ρ-weighted mass over all cells is the consistent mass M(ρ) times α."""
    study = load_study(quake_block())
    ev = Evaluator(study)
    mesh = ev.smesh.mesh
    M = mass_operator(ev.model)(np.full(len(ev.model.region_material), RHO))
    L = weighted_mass(mesh.p, mesh.t, np.arange(mesh.t.shape[1]), 3.0 * RHO)
    assert abs(L - 3.0 * M).max() < 1e-12 * abs(M).max()
