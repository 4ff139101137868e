"""The slip frame of a contact adjoint: the rows of a solution's contact conditions turned so that
each node slipping on a disc (3D) has one row along its slip and one across it. Both adjoints
use it: the monolithic one (`wcs.model.sensitivity.ContactAdjoint`) and the iterative
method's (`wcs.contact.iterative`)."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _slip_frame(model, state, m: int, k: int):
    """(Q, σ, compliance, free) of the adjoint's frame: Q turns each node slipping on a disc
    (3D) to the rows (ν, ν⊥), ν = λ_t/|λ_t| (the slip's direction; where λ_t = 0, gw = 0: the
    slip's own); σ (k m,) the sign of λ_t,i = σ_i gw_i on the fixed tangent rows (2D: sign(s);
    3D: 1 on ν, 0 on ν⊥); the compliance |s|/gw on the ν⊥ rows, which become equality rows
    (free) where gw > 0. Q is None in 2D (the identity, untouched)."""
    res = state.raw
    free = res.free.copy()
    compliance = np.zeros((1 + k) * m)
    if k == 1:
        return None, np.sign(state.contact.slip), compliance, free
    lam_t = res.lam_t.reshape(k, m)
    slip = (model.Bt_r @ res.u).reshape(k, m)                  # the solver's r_t (d_t = 0)
    along = np.where(np.linalg.norm(lam_t, axis=0) > 0, lam_t, slip)
    norm = np.linalg.norm(along, axis=0)
    turn = np.flatnonzero(~free[m:2 * m] & (norm > 0))
    nu = along[:, turn] / norm[turn]
    a, b = m + turn, 2 * m + turn                              # the node's ν and ν⊥ rows
    keep = np.setdiff1d(np.arange((1 + k) * m), np.r_[a, b])
    Q = sp.csr_matrix((np.r_[np.ones(keep.size), nu[0], nu[1], -nu[1], nu[0]],
                       (np.r_[keep, a, a, b, b], np.r_[keep, a, b, a, b])), shape=((1 + k) * m,) * 2)
    sigma = np.zeros(k * m)
    sigma[turn] = 1.0
    gw = np.where(np.isfinite(res.gw), res.gw, 0.0)[turn]
    rubs = gw > 0
    free[b[rubs]] = True
    compliance[b[rubs]] = (nu * slip[:, turn]).sum(axis=0)[rubs] / gw[rubs]
    return Q, sigma, compliance, free
