"""The search problem of a study: the box U_ad, the criteria, and the linear constraints of the
Lipschitz slip-limit profiles.

A slip limit g along a contact's slave side is admissible when |dg/ds| <= C (the seed
thesis, eq. (3.9)). A profile of m values g_1..g_m at equidistant points of the slave side
(length L, spacing ds = L / (m - 1)) keeps it as |g_{i+1} - g_i| <= C ds, two rows of
A x <= b per difference.
"""
from __future__ import annotations

import numpy as np

from .search import Problem


def contact_length(evaluator, contact: str) -> float:
    """Length of the slave side of a contact pair (sum of its facet lengths)."""
    scene = evaluator.study.scene
    slave = scene.contacts[contact].slave
    mesh = evaluator.smesh.mesh
    facets = mesh.facets[:, evaluator.smesh.boundaries[slave]]
    d = mesh.p[:, facets[1]] - mesh.p[:, facets[0]]
    return float(np.sum(np.hypot(d[0], d[1])))


def lipschitz_constraints(study, evaluator):
    """A x <= b for |g[i+1] - g[i]| <= C ds of every slip-limit profile (None, None if none)."""
    rows, rhs, start = [], [], 0
    n = len(study.parameters)
    for entry in study.uncertain:
        count = entry.points
        if entry.lipschitz is not None:
            contact = entry.path.split(".")[1]
            ds = contact_length(evaluator, contact) / (count - 1)
            bound = float(entry.lipschitz) * ds
            for i in range(start, start + count - 1):
                for sign in (1.0, -1.0):
                    a = np.zeros(n)
                    a[i + 1], a[i] = sign, -sign
                    rows.append(a)
                    rhs.append(bound)
        start += count
    if not rows:
        return None, None
    return np.array(rows), np.array(rhs)


def build_problem(study, evaluator) -> Problem:
    """The `Problem` a search strategy is given: parameter names, box, criteria, A x <= b."""
    A, b = lipschitz_constraints(study, evaluator)
    return Problem(names=list(study.parameters.names),
                   lower=np.asarray(study.parameters.lower, float).copy(),
                   upper=np.asarray(study.parameters.upper, float).copy(),
                   criteria=[c.name for c in evaluator.criteria], A_ub=A, b_ub=b)
