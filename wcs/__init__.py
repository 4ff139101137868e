"""wcs: worst-scenario uncertainty quantification for contact problems of elastic bodies.

Citations are to the seed, a habilitation thesis on multibody contact problems: "thesis eq. (3.15)"
for the thesis itself, "[21, (4.32)]" for equation (4.32) of a paper it collects, numbered as the
thesis numbers them:
[17] DD for frictionless unilateral contact; [19] 2D knee replacement; [21] DD for contact with
Tresca friction; [28] knee replacement with Coulomb friction; [33] mortar FEM for 2D elliptic
problems; [68] quasi-coupled thermo-elasticity, DD and worst scenario; [101] dynamic contact in
viscoelasticity, dual mortar, primal-dual active set.
"""
from . import run   # the package wcs.run, callable: wcs.run(study) (wcs/run/__init__.py)
from .errors import SolveError, StudyError

__version__ = "0.1.0"


def load_study(path_or_mapping, base_dir=None):
    """Load and validate a study file or mapping (raises StudyError on bad input); see wcs.study.load_study."""
    from .study import load_study as _load
    return _load(path_or_mapping, base_dir)


__all__ = ["StudyError", "SolveError", "load_study", "run", "__version__"]
