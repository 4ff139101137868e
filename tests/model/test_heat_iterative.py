"""The thermal step of `solver.method: iterative` by CG + GAMG (`wcs.model.heat`) against the
direct solve of the same reduced conduction system: the temperatures agree to 1e-8 relative to
their variation (CG stops at the relative residual 1e-12)."""
from pathlib import Path

import numpy as np
import yaml

from wcs import load_study
from wcs.model.evaluation import Evaluator
from wcs.model.heat import heat_by_krylov

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def test_heat_step_by_cg_agrees_with_the_direct_solve():
    d = yaml.safe_load((STUDIES / "heated-plate.yaml").read_text())
    d["scene"]["thermal"]["temperature"] = {"bottom": 363.0, "top": 323.0}     # a gradient across the plate
    d["solver"] = {"method": "iterative"}
    model = Evaluator(load_study(d)).model
    c = model.nominal
    T_cg = heat_by_krylov(model, c)
    T_direct = model._heat(c, adjoint=True)[0]                       # the adjoint's direct factor
    variation = np.linalg.norm(T_direct - T_direct.mean())
    assert variation > 1.0
    assert np.linalg.norm(T_cg - T_direct) <= 1e-8 * variation
    assert np.array_equal(model._heat(c, adjoint=False)[0], T_cg)    # the forward step of the method
