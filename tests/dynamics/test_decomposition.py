"""The domain decomposition steps in time (`solver.method: dd`): each level's contact problem is
solved by the decomposition, its subdomains' matrices the level operator's (mass with
stiffness, `wcs.dynamics.stepping.level_coefficients`), and agrees with the monolithic solve of
the same level to the decomposition's tolerance, with absorbing boundaries too."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.dynamics.test_bars import DURATION, bars
from tests.dynamics.test_friction import sliding
from tests.support.bad_studies import write_study
from wcs.cli import main
from wcs.dynamics.history import simulate
from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs.study import load_study

TOLERANCE = 1e-8        # solver.tolerance: the DD's outer iteration stops at this relative change


def _levels(doc, method):
    doc["solver"] = {"method": method, "tolerance": TOLERANCE, "dd": {"subdomains": 4}}
    ev = Evaluator(load_study(doc))
    return simulate(ev, ev.study.nominal()), ev


def _both(doc):
    """(the monolithic levels, the decomposition's, the monolithic normal forces), the normal
    forces agreeing to 100 × the tolerance (the interface iteration's relative stop, carried
    through the levels) over as many levels."""
    mono, _ = _levels(doc, "monolithic")
    dd, ev = _levels(doc, "dd")
    assert ev.model.solver_method == "dd"
    lam = np.array(mono.force_n)
    assert lam.sum() > 0 and len(dd.time) == len(mono.time)
    assert np.abs(np.array(dd.force_n) - lam).max() <= 100 * TOLERANCE * lam.max()
    return mono, dd, lam


def _coulomb_block():
    doc = sliding("seed")
    doc["dynamics"]["end_time"] = 0.003
    doc["scene"]["boundaries"]["block_top"] = {"body": "block", "segment": [[0.0, 0.2], [1.0, 0.2]]}
    doc["scene"]["loads"] = {"block_top": {"pressure": 1.0e5}}
    doc["scene"]["contacts"]["slide"]["friction"] = {"coefficient": 0.3}
    return doc


@pytest.mark.parametrize("scene", ["two bars, stabilized", "Coulomb block, seed"])
def test_dd_solves_each_level_as_the_monolithic_method(scene):
    """Two floating bars' impact (the stabilized scheme: its predictor A = M and its step) and
    a block sliding under Coulomb friction on a held base (the seed scheme): the contact forces
    and displacements of every level agree with the monolithic solve's to 100 × the tolerance
    (the interface iteration's relative stop, carried through the levels)."""
    doc = (bars(0.05, 1e-5, "stabilized", width=0.05, end=DURATION / 2) if scene.startswith("two")
           else _coulomb_block())
    mono, dd, lam = _both(doc)
    lam_t = np.array(mono.force_t)
    assert np.abs(np.array(dd.force_t) - lam_t).max() <= 100 * TOLERANCE * max(lam.max(), 1.0)
    u = np.array(mono.displacement)
    assert np.abs(np.array(dd.displacement) - u).max() <= 100 * TOLERANCE * np.abs(u).max()


@pytest.mark.parametrize("scheme", ["seed", "stabilized"])
def test_dd_steps_with_absorbing_boundaries_as_the_monolithic_method(scheme):
    """The target's far end with dashpots and a damping layer (their pieces split over the
    subdomains with the cells, `AbsorbingCells`): every level's contact forces and displacements
    agree with the monolithic solve's to 100 × the tolerance, as without them."""
    doc = bars(0.05, 1e-5, scheme, width=0.05, end=DURATION / 2)
    doc["scene"]["boundaries"]["t_end"] = {"body": "target", "segment": [[2.0, 0.0], [2.0, 0.05]]}
    doc["scene"]["absorbing"] = {"dashpots": ["t_end"],
                                 "layer": {"boundaries": ["t_end"], "thickness": 0.3, "damping": 2.0e4}}
    mono, dd, _ = _both(doc)
    u = np.array(mono.displacement)
    assert np.abs(np.array(dd.displacement) - u).max() <= 100 * TOLERANCE * np.abs(u).max()


def test_dd_steps_the_seismic_tunnel_as_the_monolithic_method():
    """studies/tunnel-fault-seismic.yaml coarsened (mesh 8 m, 1 m at the tunnel) with a damping
    layer on two of its dashpot sides, 3 levels: the static start by dd, the supports released,
    the Tresca fault's forces and the displacements as the monolithic solve's to 100 × the
    tolerance."""
    doc = yaml.safe_load((Path(__file__).parents[2] / "studies" / "tunnel-fault-seismic.yaml").read_text())
    doc["scene"]["mesh"] = {"size": 8.0, "refine": [{"disc": {"center": [0.0, 0.0], "radius": 6.0}, "size": 1.0}]}
    doc["scene"]["absorbing"]["layer"] = {"boundaries": ["left", "bottom"], "thickness": 10.0, "damping": 20.0}
    doc["dynamics"]["end_time"] = 3 * doc["dynamics"]["time_step"]
    mono, _ = _levels(doc, "monolithic")
    dd, _ = _levels(doc, "dd")
    lam = np.array(mono.force_n)
    assert lam.sum() > 0 and len(dd.time) == len(mono.time) == 4
    assert np.abs(np.array(dd.force_n) - lam).max() <= 100 * TOLERANCE * lam.max()
    assert np.abs(np.array(dd.force_t) - np.array(mono.force_t)).max() <= 100 * TOLERANCE * lam.max()
    u = np.array(mono.displacement)
    assert np.abs(np.array(dd.displacement) - u).max() <= 100 * TOLERANCE * np.abs(u).max()


def test_dd_starts_from_its_static_solution():
    """`initial: static` solved by dd (the block pressed on its base, held sideways at its left
    side): the levels start from its reduced unknowns and contact forces — the level 0 force is
    the static one, as the monolithic solve's — and every level agrees with the monolithic's."""
    doc = _coulomb_block()
    doc["dynamics"]["initial"] = "static"
    doc["dynamics"]["end_time"] = 0.002
    doc["scene"]["boundaries"]["block_left"] = {"body": "block", "segment": [[0.0, 0.0], [0.0, 0.2]]}
    doc["scene"]["supports"]["block_left"] = {"normal": 0.0}
    mono, _ = _levels(doc, "monolithic")
    dd, _ = _levels(doc, "dd")
    lam = np.array(mono.force_n)
    assert lam[0].sum() == pytest.approx(1.0e5 * 1.0, rel=1e-6)       # the pressure on the 1 m top
    assert np.abs(np.array(dd.force_n) - lam).max() <= 100 * TOLERANCE * lam.max()
    u = np.array(mono.displacement)
    assert np.abs(np.array(dd.displacement) - u).max() <= 100 * TOLERANCE * np.abs(u).max()


def test_absorbing_cell_pieces_sum_to_the_layer_and_dashpots():
    """`AbsorbingCells` at (α ρ, ρ c_p, ρ c_s) per region, summed over the cells, is
    `layer_damping` + `dashpots` (two regions of different material, dashpots on three sides)."""
    from scipy import sparse as sp
    from wcs.dynamics.absorbing import AbsorbingCells, absorbing_coefficients, layer_cells, named_facets
    from wcs.dynamics.loading import damping_matrix
    from wcs.fem.affine import CellAffineOperator
    doc = bars(0.05, 1e-5, "seed", width=0.05, end=DURATION / 2)
    doc["scene"]["materials"]["soft"] = {"E": 7.0e10, "nu": 0.2, "density": 2700.0}
    doc["scene"]["bodies"]["target"]["regions"][0]["material"] = "soft"
    doc["scene"]["boundaries"]["t_end"] = {"body": "target", "segment": [[2.0, 0.0], [2.0, 0.05]]}
    doc["scene"]["absorbing"] = {"dashpots": ["t_end", "t_top", "s_bottom"],
                                 "layer": {"boundaries": ["t_end"], "thickness": 0.3, "damping": 2.0e4}}
    doc["scene"]["supports"] = {k: {"normal": 0.0} for k in ("s_top", "t_bottom")}
    ev = Evaluator(load_study(doc))
    model, scene, sm = ev.model, ev.study.scene, ev.model.smesh
    c = ev.map.coefficients(ev.study.nominal())
    rho = np.array([{"steel": 7850.0, "soft": 2700.0}[m] for m in model.region_material])
    C = damping_matrix(model, scene, c, rho, ev.map.slots(ev.study.nominal()), ev.map.index)
    layer = layer_cells(sm.mesh, named_facets(sm, ["t_end"], "x"), 0.3)
    pieces = AbsorbingCells(sm.mesh, layer, named_facets(sm, ["t_end", "t_top", "s_bottom"], "x"))
    assembled = CellAffineOperator(sm.mesh.t, model.nnodes, pieces.of(np.arange(sm.mesh.t.shape[1])),
                                   sm.cell_region)(absorbing_coefficients(2.0e4, rho, c.lam, c.mu))
    assert layer.size > 0 and len(set(model.region_material)) == 2
    assert sp.linalg.norm(assembled - C) <= 1e-12 * sp.linalg.norm(C)


def test_check_says_each_level_is_solved_by_the_decomposition(tmp_path, capsys):
    doc = bars(0.05, 1e-5, "seed", width=0.05, end=DURATION / 4)
    doc["solver"] = {"method": "dd", "dd": {"subdomains": 4}}
    assert main(["check", str(write_study(doc, tmp_path, "bars.yaml"))]) == 0
    out = capsys.readouterr().out
    assert ("solver: each level (seed scheme, Δt = 1e-05 s) by dd: the domain decomposition, its subdomains' "
            "matrices those of the level's operator A = M/Δt² + C/Δt + K; each level from the decomposition's "
            "glued start") in out
