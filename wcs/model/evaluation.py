"""One forward evaluation of a study at a data vector x: Φ(x) and the fields.

`Evaluator(study)` meshes the scene, assembles the model and compiles the parameter map
once; `evaluate(x)` maps the data set to coefficients, solves, and measures the criteria.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .coefficients import ParameterMap
from ..contact.methods import METHODS
from .criteria import build_criteria, embedded_rois
from .fields import fields_dataset
from ..errors import SolveError, StudyError
from ..fem.gluing import glued_clusters
from ..group import together
from .model import Model, Solution
from ..progress import phase
from ..scene.claims import check_claims
from ..scene.estimate import memory_fault
from ..scene.mesher2d import build_mesh
from ..scene.mesher3d import build_mesh3d
from .sensitivity import gradients as adjoint_gradients
from ..status import Status


@dataclass
class Evaluation:
    x: np.ndarray
    phi: dict
    status: Status
    message: str
    iterations: int
    wall_time: float
    state: Solution | None = None
    grad: dict | None = None          # criterion -> dΦ/dx (physical units), when asked for
    nonsmooth: bool = False           # an active-set change or a switch of the max within reach
    krylov_steps: tuple | None = None  # Krylov iterations per outer step (() none, None not counted or failed)
    evaluator: "Evaluator | None" = field(default=None, repr=False)
    _data: object = field(default=None, repr=False)
    _fields: object = field(default=None, repr=False)

    @property
    def field_data(self):
        """The solution fields as a `wcs.model.fields.Data` (built on first access; None when
        the evaluation failed): what the results files hold, without xarray."""
        if self._data is None and self.state is not None:
            self._data = fields_dataset(self.evaluator.model, self.state)
        return self._data

    @property
    def fields(self):
        """The solution fields as an xarray.Dataset (`field_data` converted on first access)."""
        if self._fields is None and self.field_data is not None:
            self._fields = self.field_data.to_xarray()
        return self._fields


# Regions bonded in one stiffness (a body's regions, glued bodies) share one factorization,
# whose round-off in their stresses grows like 1e-14 times the contrast of their moduli
# (glued-layers.yaml: 4e-9 at a contrast of 4e5, 3e-5 at 4e9; tests/acceptance/test_stiff_bodies.py).
# Beyond 1e10 the stresses would carry a round-off above 1e-4: refused, with what to do.
BONDED_CONTRAST_MAX = 1e10


def _modulus_range(scene, name: str, box: dict) -> tuple[float, float]:
    """The least and largest Young's modulus of a material over its box (its nominal value
    when it has none); Lamé constants: μ(3λ+2μ)/(λ+μ) at their nominal values, moved with μ."""
    m = scene.materials[name]
    if m.E is not None:
        return box.get(f"materials.{name}.E", (m.E, m.E))
    E = m.mu * (3 * m.lam + 2 * m.mu) / (m.lam + m.mu)
    lo, hi = box.get(f"materials.{name}.mu", (m.mu, m.mu))
    return E * lo / m.mu, E * hi / m.mu


def check_bonded_contrast(scene, uncertain, bonded: list[tuple[list[str], list[str]]]) -> None:
    """StudyError when materials bonded in one stiffness differ in Young's modulus (nominal or
    anywhere in their boxes) by more than BONDED_CONTRAST_MAX. `bonded`: per group of bodies
    that share a factorization (one body, or bodies glued together), (body names, materials)."""
    box = {e.path: (e.lower, e.upper) for e in uncertain}
    for bodies, materials in bonded:
        ranges = {name: _modulus_range(scene, name, box) for name in materials}
        stiff = max(ranges, key=lambda n: ranges[n][1])
        soft = min(ranges, key=lambda n: ranges[n][0])
        contrast = ranges[stiff][1] / ranges[soft][0]
        if contrast > BONDED_CONTRAST_MAX:
            where = f"body '{bodies[0]}'" if len(bodies) == 1 else f"the glued bodies {', '.join(map(repr, bodies))}"
            raise StudyError(f"'{stiff}' (E up to {ranges[stiff][1]:g} Pa) and '{soft}' (E down to "
                             f"{ranges[soft][0]:g} Pa) are bonded in {where}: a contrast of {contrast:.3g} "
                             f"(> {BONDED_CONTRAST_MAX:g}) in one factorization leaves a round-off of about "
                             f"1e-14 times it in the stresses; make the stiff part a body of its own in contact "
                             f"(bodies in contact are factored apart, at any contrast), or, if it stands for a rigid "
                             f"part that does not move, hold the side the rest shares with it by a support "
                             f"(`u: [0, 0]`, in 3D `[0, 0, 0]`)",
                             path=f"scene.materials.{stiff}")



def bonded_materials(smesh, model) -> list[tuple[list[str], list[str]]]:
    """Per group of bodies that share a factorization (a body, or bodies glued together):
    (their names, the materials of their regions)."""
    out = []
    for cluster in glued_clusters(len(smesh.bodies), model.glue):
        bodies = [smesh.bodies[b] for b in cluster]
        materials = [m for (body, _), m in zip(smesh.regions, model.region_material) if body in bodies]
        out.append((bodies, list(dict.fromkeys(materials))))
    return out


def refuse_static_evaluation(study) -> None:
    """StudyError for one static solve of a dynamic study (`Study.evaluate`): its answer is the
    history of its levels (`wcs.app.dynamics.simulate`), never the static solution."""
    if getattr(study, "dynamics", None) is not None:
        raise StudyError("a dynamic study is evaluated over its time levels (wcs.app.dynamics.simulate, "
                         "`wcs solve`), not by one static solve", file=str(study.file), path="dynamics")

class Evaluator:
    """comm: the MPI communicator whose ranks share each DD solve (None: serial); splits: the
    study's mesh refined that many times, every triangle split into four, every tetrahedron into
    eight (the mesh check, `wcs/results/meshcheck.py`). A 3D scene is meshed into tetrahedra
    (`wcs.scene.mesher3d`); what 3D does not do yet is refused by name (exit 2), never answered
    with a number."""

    def __init__(self, study, comm=None, splits: int = 0):
        t0 = time.perf_counter()
        self.study = study
        with phase("meshing"):
            if study.scene.dimension == 3:
                self.smesh = build_mesh3d(study.scene, splits)
            else:
                self.smesh = build_mesh(study.scene, embedded_rois(study.criteria), splits)
        fault = memory_fault(self.smesh.mesh.t.shape[1], study.scene.dimension)
        if fault is not None:                   # the cells made, before any assembly or solve
            raise StudyError(fault, path="scene.mesh")
        t1 = time.perf_counter()
        with phase("assembly"):
            self.model = Model(study.scene, self.smesh, study.solver, comm=comm,
                               dynamic=getattr(study, "dynamics", None) is not None)
        check_claims(study.scene, self.smesh, {e.path for e in study.uncertain}
                     | set(study.sweep.grid if study.sweep else ()))
        check_bonded_contrast(study.scene, study.uncertain, bonded_materials(self.smesh, self.model))
        self.map = ParameterMap(self.model, study.scene, study.uncertain)
        self.criteria = build_criteria(study.criteria, study.scene, self.smesh, self.model.zone)
        t2 = time.perf_counter()
        self.timings = {"mesh": t1 - t0, "assembly": t2 - t1}

    def evaluate(self, values, gradients: bool = False) -> Evaluation:
        """Solve at a parameter vector or a mapping {dotted path: value} (others nominal);
        with `gradients`, also dΦ/dx of every criterion by the adjoint (one extra solve each).
        Spanning a group of ranks (`wcs.group`), a failure of one rank raises on all (`together`)."""
        return together(self._evaluate, values, gradients)

    def _evaluate(self, values, gradients: bool) -> Evaluation:
        t0 = time.perf_counter()
        refuse_static_evaluation(self.study)
        x, others = self.study.data_set(values)
        c = self.map.coefficients(x, others)
        nan = {c.name: float("nan") for c in self.criteria}
        try:
            state = self.model.solve(c, adjoint=gradients)
        except SolveError as e:
            return Evaluation(x, nan, e.status, str(e), 0, time.perf_counter() - t0, evaluator=self)
        phi = {c.name: c.value(self.model, state) for c in self.criteria}
        grad, nonsmooth = None, False
        if gradients:
            grad, nonsmooth = adjoint_gradients(self, state, x, others)
        message = "solved" if state.solver in ("direct", *METHODS) else f"solved ({state.solver})"
        return Evaluation(x, phi, Status.SOLVED, message, state.iterations, time.perf_counter() - t0,
                          state=state, grad=grad, nonsmooth=nonsmooth, krylov_steps=state.krylov_steps, evaluator=self)

