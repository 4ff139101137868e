r"""Dashpots on held boundaries: the levels replace the supports by their static reactions.

A dashpot on a held component does nothing (the component cannot move), yet the static initial
state a seismic study starts from ([101, §2]) needs the supports. So, as engineers' codes do
for viscous boundaries, a boundary named both in `supports` and in `absorbing.dashpots` is
held in the static initial state only: the levels step a model without those supports
(`released_scene`) and load the released nodes with the reactions R the supports exerted at
t = 0 — held constant, so the state at t = 0 stays an equilibrium and only the waves move the
boundary, against its dashpots. R = K u + Bnᵀλn + Btᵀλt − f at the static solution (the full
balance K u + Bᵀλ = f + R, R nonzero only on held DOFs). From `initial: rest` there is no
static state: the released boundaries are free, with their dashpots.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp


def released_names(scene) -> list[str]:
    """The boundaries held by supports that also take dashpots."""
    dashpots = scene.absorbing.dashpots if scene.absorbing is not None else []
    return [name for name in dashpots if name in scene.supports]


def released_scene(scene):
    """The scene without the supports of `released_names`."""
    names = released_names(scene)
    return scene.model_copy(update={"supports": {k: v for k, v in scene.supports.items() if k not in names}})


def released_dofs(model, names) -> np.ndarray:
    """(d nnodes,) mask of the DOFs of the named boundaries' nodes."""
    sm, d = model.smesh, model.dim
    nodes = np.unique(sm.mesh.facets[:, np.concatenate([np.asarray(sm.boundaries[n], dtype=np.int64)
                                                         for n in names])])
    mask = np.zeros(d * model.nnodes, dtype=bool)
    mask[(d * nodes[:, None] + np.arange(d)).ravel()] = True
    return mask


def reactions(model, c, u, res, heat=None) -> np.ndarray:
    """R = K u + Bnᵀλn + Btᵀλt − f on the full DOFs: the supports' reactions at the static
    state u with contact result res (None: no contact)."""
    R = model.stiffness(c) @ u - model.mechanical_load(c, heat)
    if model.zone is not None and res is not None:
        R += model.zone.Bn.T @ res.lam_n + model.zone.Bt.T @ res.lam_t
    return R


def carried_over(model, c, u, res):
    """(w, the contact result) of the released model at data set c for the full displacement u:
    w solves T w = u − u₀ exactly (the released model holds a subset of the DOFs the static one
    held); the contact result keeps its multipliers and active set, not the static solve's
    vectors and factor (another operator, another size)."""
    T = model.elim.T
    w = sp.linalg.spsolve(sp.csc_matrix(T.T @ T), T.T @ (u - model.elim.U0 @ c.support_values))
    return w, (dataclasses.replace(res, u=None, factor=None, free=None) if res is not None else None)


def released_model(ev):
    """(model, parameter map) of the released scene, built once per evaluator."""
    if getattr(ev, "_released", None) is None:
        from wcs.model.coefficients import ParameterMap
        from wcs.model.model import Model
        scene = released_scene(ev.study.scene)
        model = Model(scene, ev.smesh, ev.study.solver, dynamic=True)
        ev._released = (model, ParameterMap(model, scene, ev.study.uncertain))
    return ev._released
