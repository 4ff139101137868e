"""The thermal step by CG + AMG (`solver.method: iterative`): the reduced conduction system of
`Model.heat_system` (symmetric positive definite once a temperature is prescribed) solved by
PETSc's CG preconditioned by GAMG (`wcs.contact.iterative.krylov_solve`) instead of a direct factor,
to the relative residual `RTOL`; the temperatures agree with the direct solve's to 1e-8 relative
(tests/model/test_heat_iterative.py). The adjoint keeps the direct factor (`Model._heat`)."""
from __future__ import annotations

import numpy as np

from ..contact.iterative import krylov_solve
from ..errors import SolveError
from ..status import Status

RTOL = 1e-12                # ‖b − K θ‖ ≤ RTOL ‖b‖


def heat_by_krylov(model, c) -> np.ndarray:
    """The nodal temperature of data set c by CG + GAMG; a SolveError when CG does not reach RTOL."""
    Kr, rhs, Th0 = model.heat_system(c)[:3]
    x, its, ok = krylov_solve(Kr, rhs, RTOL)
    if not ok:
        raise SolveError(f"the heat step's CG + GAMG did not reach the relative residual {RTOL:g} "
                         f"in {its} iterations", status=Status.CONTACT_NOT_CONVERGED)
    return model.P @ (model.heat_elim.T @ x + Th0)
