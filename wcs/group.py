"""The ranks the solves of the current evaluation span: `solver.ranks_per_evaluation: k` makes
groups of k MPI ranks (`wcs.app.parallel.groups`), and a solve made inside `spanning(group)`
distributes its Krylov solves over that group (`wcs.contact.distributed`); elsewhere each rank
solves alone. Every rank of a group must solve the same data sets in the same order."""
from __future__ import annotations

import contextlib

_evaluation = None                # the group the solves of the current evaluation span (None: this rank)


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
