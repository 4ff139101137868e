"""MPI: the communicator of a run launched by `mpiexec -n N` (N > 1), else None.

Serial runs never import mpi4py (it initialises MPI on import). With N ranks
every rank meshes and assembles its own copy of the model (deterministic, so
identical), drives the same deterministic search, and solves every N-th point
of each batch — with the DD solver too, serially on each rank (a whole `dd` study
on the tunnel: 1.5× on 2 ranks, against 0.5× with each DD solve spread over them);
each rank stores each of its evaluations as soon as it is solved (so a crash mid-batch
loses only those in flight), the outcomes are gathered to all ranks in batch order, so every
rank sees exactly what a serial run sees (bitwise), and rank 0 alone writes the results file.

`solver.ranks_per_evaluation: k` splits the N ranks into N/k groups of k consecutive ranks
(`groups`): group g solves points g, g + N/k, ... of each batch, every rank of the group the
same points, each solve spanning the group (`wcs.group.spanning`: the iterative method's Krylov solves,
`wcs.contact.distributed`); the group's rank 0 gives the outcome to the gather. k = 1 is the
above.
"""
from __future__ import annotations

from ..group import launched


def world():
    if not launched():
        return None
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    return comm if comm.size > 1 else None


def rank(comm) -> int:
    return 0 if comm is None else comm.rank


def agree(comm, error: Exception | None) -> None:
    """Raise on every rank if any rank failed, so that no rank is left waiting in a
    collective step; a StudyError keeps its file, key path and fault."""
    from ..errors import StudyError
    if comm is not None:
        report = None if error is None else (isinstance(error, StudyError), str(getattr(error, "fault", error)),
                                             getattr(error, "file", None), getattr(error, "path", None))
        first = next((r for r in comm.allgather(report) if r is not None), None)
        if error is None and first is not None:
            study_error, fault, file, path = first
            error = StudyError(fault, file=file, path=path) if study_error else RuntimeError(fault)
    if error is not None:
        raise error


def groups(comm, k: int, file=None):
    """(group communicator, group index, number of groups) of `solver.ranks_per_evaluation: k`
    on the world `comm` (None: one process); the group None where k = 1. StudyError (exit 2)
    where the N ranks are not N/k groups of k."""
    from ..errors import StudyError
    n = 1 if comm is None else comm.size
    if k > n or n % k:
        launch = "a serial run" if comm is None else f"mpiexec -n {n}"
        raise StudyError(f"{k} ranks per evaluation do not divide the {n} rank{'s' * (n > 1)} of {launch} "
                         f"into groups: run it under mpiexec -n with a multiple of {k}", file=file,
                         path="solver.ranks_per_evaluation")
    if k == 1:
        return None, rank(comm), n
    return comm.Split(comm.rank // k, comm.rank), comm.rank // k, n // k
