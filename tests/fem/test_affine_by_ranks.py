"""K(c) assembled by shares of the node rows (`CellAffineOperator`, spanning a group of ranks):
each rank sums only the node-pair blocks of its rows, from the cells that touch them; the
shares put together are K(c) to the bit, on any number of ranks."""
import numpy as np
import pytest
from skfem import MeshTet

from wcs.fem import affine
from wcs.fem.affine import CellAffineOperator, elastic_cells
from wcs.group import rows


@pytest.mark.parametrize("size", [2, 3, 5])
def test_the_shares_of_the_node_rows_are_k_to_the_bit(monkeypatch, size):
    monkeypatch.setattr(affine, "CHUNK", 97)            # several chunks, shares cutting through them
    m = MeshTet.init_tensor(*[np.linspace(0, 1, 6)] * 3)
    region = (m.p[0, m.t].mean(axis=0) > 0.5).astype(int)
    op = CellAffineOperator(m.t, m.nvertices, elastic_cells(m.p, m.t), region)
    c = np.array([[2.0, 0.7], [1.3, 3.1]])[region]       # (λ, μ) of each region, per cell
    whole = op._entries(c, 0, op.nblocks)
    shares = [op._entries(c, *(int(op.indptr[i]) for i in rows(m.nvertices, size, r))) for r in range(size)]
    assert all(len(s) for s in shares) and np.abs(whole).max() > 0
    assert np.array_equal(np.concatenate(shares), whole)
