"""MPI: the communicator of a run launched by `mpiexec -n N` (N > 1), else None.

Serial runs never import mpi4py (it initialises MPI on import). With N ranks
every rank meshes and assembles its own copy of the model (deterministic, so
identical), drives the same deterministic search, and solves every N-th point
of each batch — with the DD solver too, serially on each rank (a whole `dd` study
on the tunnel: 1.5× on 2 ranks, against 0.5× with each DD solve spread over them);
the outcomes are gathered to all ranks in batch order, so every rank sees exactly
what a serial run sees (bitwise), and rank 0 alone writes.
"""
from __future__ import annotations

import os

_LAUNCHER_VARIABLES = ("PMI_SIZE", "PMI_RANK", "OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS")


def world():
    if not any(v in os.environ for v in _LAUNCHER_VARIABLES):
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
