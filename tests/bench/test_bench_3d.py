"""3D speed at ≈ 1e5 unknowns (issue 13), as ratios measured in one run:

- assembly: the parameter-affine stiffness K(c) of a data set (closed-form P1 tetra cell
  matrices combined with the data, `wcs.fem.affine`) against scikit-fem's assembly of the same
  matrix (basis + `asm` of linear elasticity); also the once-per-mesh set-up (cell matrices and
  the sparse pattern) against it. Goal: ≤ 0.2×. The matrices agree to round-off.

Table: results/bench/bench_3d.csv.
"""
from __future__ import annotations

import numpy as np
import pytest
import skfem
from skfem.models.elasticity import linear_elasticity

from common import measure, write_table
from wcs.fem.affine import CellAffineOperator, elastic_cell_matrices

pytestmark = pytest.mark.bench
NODES_PER_SIDE = 33                       # 3 · 33³ = 1.08e5 unknowns, 1.9e5 tetrahedra


def test_assembly_of_a_data_set_costs_at_most_a_fifth_of_scikit_fems():
    x = np.linspace(0.0, 1.0, NODES_PER_SIDE)
    mesh = skfem.MeshTet.init_tensor(x, x, x)
    lam, mu = 2.0e9, 1.5e9

    def skfem_assembly():
        basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP1()))
        return skfem.asm(linear_elasticity(lam, mu), basis)

    def setup():
        local = elastic_cell_matrices(mesh.p, mesh.t)
        return CellAffineOperator(mesh.t, mesh.p.shape[1], local, np.zeros(mesh.t.shape[1], dtype=np.int64))

    t_skfem, s_skfem, K_ref = measure(skfem_assembly, 2)        # ~10-20 s each
    t_setup, _, op = measure(setup, 3)
    t_data, s_data, K = measure(lambda: op([[lam, mu]]), 5)
    assert abs(K - K_ref).max() <= 1e-12 * abs(K_ref).max()
    rows = [["unknowns", 3 * mesh.p.shape[1]], ["tetrahedra", mesh.t.shape[1]],
            ["scikit-fem basis + asm [s]", f"{t_skfem:.3f} (spread {s_skfem:.2f})"],
            ["wcs set-up once per mesh [s]", f"{t_setup:.3f}"],
            ["wcs K(c) per data set [s]", f"{t_data:.4f} (spread {s_data:.2f})"],
            ["ratio per data set", f"{t_data / t_skfem:.3f}"], ["ratio set-up", f"{t_setup / t_skfem:.3f}"]]
    write_table("bench_3d", ["quantity", "value"], rows)
    print("\n".join(f"{a}: {b}" for a, b in rows))
    assert t_data <= 0.2 * t_skfem
    assert t_setup <= 0.2 * t_skfem
