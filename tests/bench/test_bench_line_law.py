"""The constants of the line-contact law of a cylinder striking a block (`tests/support/reference_forms.py`,
`line_law`), measured for the bodies of the 2D impact benchmark by static plane-strain solves
(scikit-fem, independent of wcs): δ = q(1−ν²)/(πE) (2 ln(4R/b) + k1) for the cylinder, and
q(1−ν²)/(πE) (2 ln(2H/b) + k2) for a block of height H held at its base, under Hertz's pressure of
half-width b.

- Johnson's k1 = −1 is the cylinder between two opposite line loads (its axis to a contact): this
  bench reproduces it (asserted to 0.02: the check of the method). A cylinder decelerated by its
  own inertia (the pressure balanced by a uniform body force; its centre of mass to the contact)
  has its own k1, measured at ν = 0.2, 0.3, 0.45.
- A half-space to a point at depth d has k2 = −ν/(1−ν); a block held at its base with free sides
  has its own k2, which depends on its width W: measured at W = H, 2H, 4H (ν = 0.3) and W = 2H
  (ν = 0.33, the aluminium block of the 2D impact).
How far a unit of k moves the contact time: `cylinder_impact`'s docstring. Table:
results/bench/line_law_constants.csv (docs/benchmarks.md); tests/dynamics/test_impact.py's K1,
K2 are its rows of the inertia-decelerated cylinder at ν = 0.3 and the block of width 2H at
ν = 0.33.
"""
import numpy as np
import pytest
import skfem
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

from common import write_table

VECTOR = skfem.ElementVector(skfem.ElementTriP1())


def _hertz_load(m, b: float, side: float, centre: float):
    """The load vector of Hertz's pressure 2q/(πb²) √(b² − x²) (q = 1) pushing into the surface
    y = centre (side −1: a bottom surface pushed up; +1: a top surface pushed down)."""
    facets = m.facets_satisfying(lambda x: (np.abs(x[1] - centre) < 2 * b) & (np.abs(x[0]) < 2 * b),
                                 boundaries_only=True)

    @skfem.LinearForm
    def load(v, w):
        return side * 2 / (np.pi * b ** 2) * np.sqrt(np.maximum(b ** 2 - w.x[0] ** 2, 0.0)) * -v[1]
    return skfem.asm(load, skfem.FacetBasis(m, VECTOR, facets=facets, intorder=6))


def disc_constants(nu: float, b: float, nref: int = 6, nrefine: int = 4) -> tuple[float, float]:
    """(k1 between two opposite line loads, k1 decelerated by inertia) of a unit disc, E = 1."""
    m = skfem.MeshTri.init_circle(nref)
    for _ in range(nrefine):                                   # finer at both poles, nodes kept on the circle
        c = m.p[:, m.t].mean(axis=1)
        m = m.refined(np.flatnonzero((np.abs(c[0]) < 4 * b) & (np.abs(c[1]) > 1 - 4 * b)))
        p, bn = m.p.copy(), m.boundary_nodes()
        p[:, bn] /= np.hypot(*p[:, bn])
        m = skfem.MeshTri(p, m.t)
    basis = skfem.Basis(m, VECTOR)
    K = skfem.asm(linear_elasticity(*lame_parameters(1.0, nu)), basis)
    M = skfem.asm(skfem.BilinearForm(lambda u, v, w: dot(u, v)), basis)
    uy = np.tile([0.0, 1.0], m.p.shape[1])
    bottom = _hertz_load(m, b, -1.0, -1.0)
    inertia = -uy @ M / (uy @ M @ uy)                         # a unit downward pull spread as the mass
    centre, top, low = np.argmin(np.hypot(*m.p)), np.argmax(m.p[1]), np.argmin(m.p[1])
    held = np.array([2 * centre, 2 * centre + 1, 2 * top])    # the rigid motions
    scale = (1 - nu ** 2) / np.pi
    out = []
    for f, measured_from in ((bottom + _hertz_load(m, b, +1.0, 1.0), "centre"), (bottom + inertia, "mass")):
        u = skfem.solve(*skfem.condense(K, f, D=held))
        ref = u[2 * centre + 1] if measured_from == "centre" else uy @ M @ u / (uy @ M @ uy)
        out.append((u[2 * low + 1] - ref) / scale - 2 * np.log(4 / b))
    return out[0], out[1]


def block_constant(nu: float, width: float, b: float, nrefine: int = 7) -> float:
    """k2 of a block [−W/2, W/2] × [−1, 0] held at its base, free sides, E = 1."""
    m = skfem.MeshTri.init_tensor(np.linspace(-width / 2, width / 2, int(8 * width) + 1), np.linspace(-1, 0, 9))
    for k in range(nrefine):
        c = m.p[:, m.t].mean(axis=1)
        m = m.refined(np.flatnonzero(np.hypot(*c) < max(4 * b, 2.0 ** -k)))
    basis = skfem.Basis(m, VECTOR)
    K = skfem.asm(linear_elasticity(*lame_parameters(1.0, nu)), basis)
    u = skfem.solve(*skfem.condense(K, _hertz_load(m, b, +1.0, 0.0), D=basis.get_dofs(lambda x: x[1] < -1 + 1e-12).all()))
    top = np.argmin(np.hypot(*m.p))
    return -u[2 * top + 1] / ((1 - nu ** 2) / np.pi) - 2 * np.log(2 / b)


@pytest.mark.bench
def test_line_law_constants():
    rows = []
    for nu in (0.2, 0.3, 0.45):
        diametral, inertia = disc_constants(nu, 0.05)
        assert diametral == pytest.approx(-1.0, abs=0.02)           # Johnson's cylinder, reproduced
        rows.append(["cylinder", nu, "", 0.05, round(diametral, 4), round(inertia, 4), ""])
    for nu, width in ((0.3, 1.0), (0.3, 2.0), (0.3, 4.0), (0.33, 2.0)):
        rows.append(["block", nu, width, 0.05, "", "", round(block_constant(nu, width, 0.05), 4)])
    path = write_table("line_law_constants", ["body", "nu", "W/H", "b/R or b/H", "k1 two loads",
                                              "k1 inertia", "k2 held base"], rows)
    print(path.read_text())
