"""The `Study`: a validated study file as plain frozen data. It builds nothing: whoever runs
the study builds the evaluator (`wcs.model.evaluation.Evaluator(study)`; `wcs.load_study`
returns the study paired with one, `wcs.app.evaluable`)."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..dynamics.spec import Dynamics
from ..options import Search, Solver
from ..scene.spec import Scene
from .data import _split_mapping, parameter_vector
from .paths import get_path
from .schema import Criterion, Sweep
from .uncertain import Parameters, Uncertain

@dataclass(frozen=True)
class Study:
    """A validated study, frozen plain data; `scene` is the resolved typed scene. A variant is
    another study: `load_study(mapping)`. It solves nothing: `Evaluator(study).evaluate(x)` (or
    `wcs.load_study(...).evaluate(x)`) does."""

    name: str
    file: Path                                          # Path("<mapping>") for a study given as a mapping
    text: str
    sha256: str
    scene: Scene
    uncertain: list[Uncertain]
    criteria: list[Criterion]
    limits: dict                                        # criterion -> upper limit
    search: Search
    solver: Solver
    sweep: Sweep | None
    output: str
    parameters: Parameters
    notes: list[str]
    warnings: list[str] = field(default_factory=list)   # results to distrust (e.g. P1 locking)
    estimated_cells: float | None = None                # before meshing; None for a mesh file
    lower_limits: dict = field(default_factory=dict)    # criterion -> lower limit
    levels: tuple[float, ...] | None = None             # α-levels of a fuzzy study, ascending; None: crisp
    dynamics: Dynamics | None = None                    # time stepping (`wcs.dynamics`); None: static

    def data_set(self, values) -> tuple[np.ndarray, dict[str, float]]:
        """A data set as (x, others): the parameter vector and any other addressed numbers.

        `values` is a vector in the order of `parameters`, or a mapping from dotted path to
        value: a parameter name (`...slip_limit[2]`), an uncertain path (a profile takes one
        value for all points or a list of `points` values), or any other addressable number
        of the scene (e.g. a sweep path). Parameters a mapping leaves out keep their nominal
        value."""
        if isinstance(values, Mapping):
            return _split_mapping(self, values)
        return parameter_vector(self, values), {}

    def nominal(self) -> np.ndarray:
        """The scene's own values in parameter order (a profile repeats the constant value)."""
        values = []
        for entry in self.uncertain:
            values += [get_path(self.scene, entry.path)] * entry.points
        return np.array(values, dtype=float)
