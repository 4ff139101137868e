"""One forward evaluation of a study at a data vector x: Φ(x) and the fields.

`Evaluator(study)` meshes the scene, assembles the model and compiles the parameter map
once; `evaluate(x)` maps the data set to coefficients, solves, and measures the criteria.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .coefficients import ParameterMap
from .criteria import build_criteria, embedded_rois
from .errors import SolveError
from .fem.gluing import glued_clusters
from .model import Model, Solution
from .scene.mesher import build_mesh
from .scene.mesher3d import build_mesh3d
from .sensitivity import gradients as adjoint_gradients
from .status import Status
from .study import check_bonded_contrast


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
    evaluator: "Evaluator | None" = field(default=None, repr=False)
    _fields: object = field(default=None, repr=False)

    @property
    def fields(self):
        """xarray.Dataset of the solution fields (built on first access)."""
        if self._fields is None and self.state is not None:
            from .fields import fields_dataset   # xarray loads when fields are asked for (`wcs check` never does)
            self._fields = fields_dataset(self.evaluator.model, self.state)
        return self._fields


def bonded_materials(smesh, model) -> list[tuple[list[str], list[str]]]:
    """Per group of bodies that share a factorization (a body, or bodies glued together):
    (their names, the materials of their regions)."""
    out = []
    for cluster in glued_clusters(len(smesh.bodies), model.glue):
        bodies = [smesh.bodies[b] for b in cluster]
        materials = [m for (body, _), m in zip(smesh.regions, model.region_material) if body in bodies]
        out.append((bodies, list(dict.fromkeys(materials))))
    return out


class Evaluator:
    """comm: the MPI communicator whose ranks share each DD solve (None: serial); splits: the
    study's mesh refined that many times, every triangle split into four, every tetrahedron into
    eight (the mesh check, `wcs/meshcheck.py`). A 3D scene is meshed into tetrahedra
    (`wcs.scene.mesher3d`); what 3D does not do yet is refused by name (exit 2), never answered
    with a number."""

    def __init__(self, study, comm=None, splits: int = 0):
        t0 = time.perf_counter()
        self.study = study
        if study.scene.dimension == 3:
            self.smesh = build_mesh3d(study.scene, splits)
        else:
            self.smesh = build_mesh(study.scene, embedded_rois(study.criteria), splits)
        t1 = time.perf_counter()
        self.model = Model(study.scene, self.smesh, study.solver, comm=comm)
        check_bonded_contrast(study.scene, study.uncertain, bonded_materials(self.smesh, self.model))
        self.map = ParameterMap(self.model, study.scene, study.uncertain)
        self.criteria = build_criteria(study.criteria, study.scene, self.smesh, self.model.zone)
        t2 = time.perf_counter()
        self.timings = {"mesh": t1 - t0, "assembly": t2 - t1}

    def evaluate(self, values, gradients: bool = False) -> Evaluation:
        """Solve at a parameter vector or a mapping {dotted path: value} (others nominal);
        with `gradients`, also dΦ/dx of every criterion by the adjoint (one extra solve each)."""
        t0 = time.perf_counter()
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
        message = "solved" if state.solver in ("direct", "monolithic", "dd", "qp") else f"solved ({state.solver})"
        return Evaluation(x, phi, Status.SOLVED, message, state.iterations, time.perf_counter() - t0,
                          state=state, grad=grad, nonsmooth=nonsmooth, evaluator=self)

