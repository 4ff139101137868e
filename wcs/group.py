"""The ranks the solves of the current evaluation span: `solver.ranks_per_evaluation: k` makes
groups of k MPI ranks (`wcs.app.parallel.groups`), and a solve made inside `spanning(group)`
distributes its Krylov solves over that group (`wcs.contact.distributed`); elsewhere each rank
solves alone. Every rank of a group must solve the same data sets in the same order, and a
failure of one rank reaches them all (`together`)."""
from __future__ import annotations

import contextlib
import os

_LAUNCHER_VARIABLES = ("PMI_SIZE", "PMI_RANK", "OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS")
_evaluation = None                # the group the solves of the current evaluation span (None: this rank)


def launched() -> bool:
    """Whether an MPI launcher (mpiexec) started this process (else MPI, where started, is a singleton)."""
    return any(v in os.environ for v in _LAUNCHER_VARIABLES)


class GroupFailure(RuntimeError):
    """Another rank of the evaluation's group failed (its message); raised on every other rank."""


def rows(n: int, size: int, rank: int) -> tuple[int, int]:
    """[lo, hi) of the rows rank `rank` of `size` owns: contiguous, sizes n // size or one more
    (the first n % size ranks), PETSc's own split."""
    base, extra = divmod(n, size)
    lo = rank * base + min(rank, extra)
    return lo, lo + base + (rank < extra)


def share(n: int) -> tuple[int, int]:
    """[lo, hi) of n items (rows, nodes) this rank owns in the evaluation's group (`rows`; (0, n) alone)."""
    return (0, n) if _evaluation is None else rows(n, _evaluation.size, _evaluation.rank)


def evaluation_comm():
    """The communicator the current evaluation's solves span (None: this process alone)."""
    return _evaluation


@contextlib.contextmanager
def spanning(group):
    """Solves in this block span the ranks of `group` (None: each rank alone)."""
    global _evaluation
    before, _evaluation = _evaluation, group
    try:
        yield
    finally:
        _evaluation = before


def together(f, *args, **kwargs):
    """f(*args, **kwargs), the ranks of the evaluation's group then agreeing whether it failed
    (one allgather): a rank's exception is re-raised there, and every other rank raises
    GroupFailure with the first failed rank's message, so that no rank is left waiting in a
    collective step for one that has left. A failure already agreed on (by a `together` called
    inside f) passes through without a second agreement, so every rank of the group must call
    `together` at the same points, nested alike (the evaluation: `Evaluator.evaluate`; inside
    it each distributed matrix, `wcs.contact.distributed`)."""
    comm = _evaluation
    if comm is None:
        return f(*args, **kwargs)
    try:
        out = f(*args, **kwargs)
    except Exception as e:
        if not getattr(e, "agreed_by_group", False):
            _agree(comm, e)
        raise
    _agree(comm, None)
    return out


def _agree(comm, error: Exception | None) -> None:
    """Every rank's failure (None: none) known to all; GroupFailure on a rank that did not fail
    where another did."""
    said = comm.allgather(None if error is None else f"{type(error).__name__}: {error}")
    if error is not None:
        error.agreed_by_group = True
        return
    failed = next(((r, s) for r, s in enumerate(said) if s is not None), None)
    if failed is not None:
        e = GroupFailure(f"rank {failed[0]} of the evaluation's {comm.size} ranks failed: {failed[1]}")
        e.agreed_by_group = True
        raise e
