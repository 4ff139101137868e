r"""The data of one contact solve (Dirichlet conditions eliminated; `wcs.contact.solver`)::

    minimise  ½ uᵀKu − fᵀu + Σ_i w_i g_i |(Bt u)_i|   subject to  Bn u ≤ d,

with the slip limit g + F p for Coulomb friction (`wcs.contact.laws`), and R the rigid
modes of the floating bodies (K R = 0) when there are any.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from wcs.contact.laws import Coulomb, Tresca, law_of


@dataclass(frozen=True)
class ContactProblem:
    """One contact problem: K u + Bnᵀλn + Btᵀλt = f with the contact conditions on C = [Bn; Bt].

    K: the reduced stiffness — on each unit u of `wcs.contact.units` the data set's one is
    `scale[u]` · K (a scalar scale: all of K); g, F: slip limits and friction coefficients
    per node (None: zero); warm: a previous result on the same mesh that starts the solve;
    reference: the size of the displacement u is an increment of (a time level's last one,
    `wcs.dynamics`), whose round-off d carries — the answer's penetration is measured against
    it too (`wcs.contact.solver.conditions_violated`)."""
    K: sp.spmatrix | None
    f: np.ndarray
    Bn: sp.csr_matrix
    Bt: sp.csr_matrix
    d: np.ndarray
    w: np.ndarray
    g: np.ndarray | None = None
    F: np.ndarray | None = None
    R: np.ndarray | None = None
    warm: object = None             # a `wcs.contact.solver.ContactResult`
    scale: np.ndarray | float = 1.0
    reference: float = 0.0
    coefficients: np.ndarray | None = None      # K(c)'s coefficients c where K is Tᵀ K(c) T itself (BDDC's subdomains)

    def __post_init__(self):
        for name in ("f", "d", "w"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        if self.R is not None:
            object.__setattr__(self, "R", np.asarray(self.R, dtype=float).reshape(len(self.f), -1))

    @property
    def m(self) -> int:
        """Contact nodes."""
        return self.Bn.shape[0]

    @property
    def k(self) -> int:
        """Tangent components per node: d − 1."""
        return self.Bt.shape[0] // self.m if self.m else 1

    @functools.cached_property
    def C(self) -> sp.csr_matrix:
        """The contact rows [Bn; Bt], normals first."""
        return sp.vstack([self.Bn, self.Bt]).tocsr()

    @functools.cached_property
    def law(self) -> Tresca | Coulomb:
        """The friction law (`wcs.contact.laws.law_of`)."""
        return law_of(self.w, self.g, self.F)
