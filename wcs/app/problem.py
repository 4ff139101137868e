"""The search problem of a study: the box U_ad, the criteria, and the linear constraints of the
Lipschitz slip-limit profiles.

A slip limit g along a contact's slave side is admissible when |dg/ds| <= C (the seed
thesis, eq. (3.9)). A profile of m values g_1..g_m at equidistant points of the slave side
(length L, spacing ds = L / (m - 1)) keeps it as |g_{i+1} - g_i| <= C ds, two rows of
A x <= b per difference. On a 3D contact surface (an nu × nv grid over the slave face) the
differences of neighbours along each side, with that side's spacing.
"""
from __future__ import annotations

import numpy as np

from ..contact.frame import surface_grid
from ..search import Problem


def contact_length(evaluator, contact: str) -> float:
    """Length of the slave side of a contact pair (sum of its facet lengths)."""
    scene = evaluator.study.scene
    slave = scene.contacts[contact].slave
    mesh = evaluator.smesh.mesh
    facets = mesh.facets[:, evaluator.smesh.boundaries[slave]]
    d = mesh.p[:, facets[1]] - mesh.p[:, facets[0]]
    return float(np.sum(np.hypot(d[0], d[1])))


def lipschitz_constraints(study, evaluator):
    """A x <= b for |g[i+1] - g[i]| <= C ds of every slip-limit profile (None, None if none); on a
    3D contact surface the grid's neighbours in both directions, ds the grid spacing along each
    side of the face's rectangle (`wcs.contact.frame.surface_grid`)."""
    rows, rhs, start = [], [], 0
    n = len(study.parameters)
    for entry in study.uncertain:
        count = entry.points
        if entry.lipschitz is not None:
            contact = entry.path.split(".")[1]
            if entry.grid is None:
                shape, spacing = (count, 1), (contact_length(evaluator, contact) / (count - 1), 0.0)
            else:
                zone = evaluator.model.zone
                _, lengths = surface_grid(zone.coords[zone.contact_of_node == zone.names.index(contact)])
                shape = entry.grid
                spacing = (lengths[0] / (shape[0] - 1), lengths[1] / (shape[1] - 1))
            index = start + np.arange(count).reshape(shape)
            for pairs, ds in ((zip(index[:-1].ravel(), index[1:].ravel()), spacing[0]),
                              (zip(index[:, :-1].ravel(), index[:, 1:].ravel()), spacing[1])):
                for i, j in pairs:
                    for sign in (1.0, -1.0):
                        a = np.zeros(n)
                        a[j], a[i] = sign, -sign
                        rows.append(a)
                        rhs.append(float(entry.lipschitz) * ds)
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
