"""The study that `wcs.load_study` returns: the plain `Study` paired with its `Evaluator`, which
is built on the first `evaluate` (the mesh and the assembled model, then reused by every later call). It is a `Study` (every field, `parameters`, `nominal()`, `data_set()`), so whatever takes a
study takes it; `wcs.study.load_study` returns the plain one, which builds nothing."""
from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property

from ..study.load import load_study as load_plain
from ..study.study import Study


@dataclass(frozen=True)
class EvaluableStudy(Study):
    """A `Study` with `evaluate(x)`: its evaluator is built on the first call and reused."""

    @cached_property
    def _evaluator(self):
        """The evaluator of this study, built on the first solve."""
        from ..model.evaluation import Evaluator   # the solvers (gmsh, scikit-fem, PARDISO) load on the first solve
        return Evaluator(self)

    def evaluate(self, values, gradients: bool = False):
        """One forward solve at a data vector (or {dotted path: value}); the mesh and the
        assembled model are built on the first call and reused. With `gradients`, the
        evaluation also carries dΦ/dx of every criterion (adjoint)."""
        return self._evaluator.evaluate(values, gradients=gradients)


def evaluable(study: Study) -> EvaluableStudy:
    """`study` paired with a lazily built evaluator."""
    return EvaluableStudy(**{f.name: getattr(study, f.name) for f in fields(Study)})


def load_study(path_or_mapping, base_dir=None) -> EvaluableStudy:
    """`wcs.study.load_study` (StudyError on bad input), paired with a lazily built evaluator."""
    return evaluable(load_plain(path_or_mapping, base_dir))
