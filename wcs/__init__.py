"""wcs: worst-scenario uncertainty quantification for contact problems of elastic bodies.

Citations are to the seed, a habilitation thesis on multibody contact problems: "thesis eq. (3.15)"
for the thesis itself, "[21, (4.32)]" for equation (4.32) of a paper it collects, numbered as the
thesis numbers them:
[17] DD for frictionless unilateral contact; [19] 2D knee replacement; [21] DD for contact with
Tresca friction; [28] knee replacement with Coulomb friction; [33] mortar FEM for 2D elliptic
problems; [68] quasi-coupled thermo-elasticity, DD and worst scenario; [101] dynamic contact in
viscoelasticity, dual mortar, primal-dual active set.

Layers, from the bottom up: a module imports only from its own layer and the layers below it
(tests/acceptance/test_imports.py holds the code to this list, and `search` to the first layer alone).

    1. errors, status, linalg, options, progress, choose, version, group: low-level, one idea each, used everywhere
    2. geometry: mesh geometry shared by fem, scene and contact (tetrahedra, normals, mortar integrals)
    3. fem: finite elements with scikit-fem (affine pieces, constraints, stresses, glued interfaces)
    4. scene: shapes, meshers (gmsh) and mesh files -> a mesh with named bodies, regions, boundaries
    5. contact: contact problems, friction laws, pairs and mortar rows, the contact methods
    6. dd: the seed's domain decomposition, a contact method of its own
    7. search: the search strategies of the worst scenario (they see a `Problem`, not a study)
    8. model: the forward evaluation of one data set (`Evaluator`)
    9. dynamics: time stepping of a dynamic study, each level a contact problem ([101])
    10. study: study files read and validated into a plain `Study`
    11. results: the results file, its store, extremes, verdict, drivers, mesh check
    12. report: the HTML report of a results file
    13. app: running a study (the runner, the commands, the study paired with its evaluator)
    14. cli (and this package's own __init__): the command line and the Python API
"""
from .errors import SolveError, StudyError
from .version import __version__


def run(study, output=None, resume=False, progress=None, **kwargs):
    """The whole worst-scenario study -> xarray.Dataset (the results file's content):
    `wcs.app.runner.run`."""
    from .app.runner import run as _run
    return _run(study, output=output, resume=resume, progress=progress, **kwargs)


def load_study(path_or_mapping, base_dir=None):
    """Load and validate a study file or mapping (raises StudyError on bad input): the plain
    `wcs.study.Study` paired with its evaluator, built on the first `study.evaluate(x)`
    (`wcs.app.evaluable`)."""
    from .app.evaluable import load_study as _load
    return _load(path_or_mapping, base_dir)


__all__ = ["StudyError", "SolveError", "load_study", "run", "__version__"]
