"""The meshed scene: one triangle mesh holding every body, and its tags."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import skfem


@dataclass(frozen=True)
class SceneMesh:
    """All bodies in one `skfem.MeshTri`.

    Bodies are disjoint in the mesh: where two bodies touch, each has its own
    nodes (duplicated on a shared curve), so the global stiffness is block
    diagonal across bodies and contact couples them.
    """

    mesh: skfem.MeshTri
    bodies: list[str]                       # body names, scene order
    regions: list[tuple[str, str]]          # (body, region name), scene order
    cell_body: np.ndarray                   # (ncells,) index into bodies
    cell_region: np.ndarray                 # (ncells,) index into regions
    boundaries: dict[str, np.ndarray] = field(default_factory=dict)
    # name -> sorted indices into mesh.facets of the boundary facets selected
    roi_cells: dict[str, np.ndarray] = field(default_factory=dict)
    # region of interest (box, disc, polygon: embedded in the mesh) -> sorted indices of its cells

    @property
    def node_body(self) -> np.ndarray:
        """(nnodes,) body index of every node (each node belongs to one body)."""
        nb = np.full(self.mesh.p.shape[1], -1, dtype=np.int64)
        nb[self.mesh.t.ravel()] = np.tile(self.cell_body, self.mesh.t.shape[0])
        return nb

    def boundary_nodes(self, name: str) -> np.ndarray:
        return np.unique(self.mesh.facets[:, self.boundaries[name]])

    def region_index(self, name: str) -> int:
        for i, (_, r) in enumerate(self.regions):
            if r == name:
                return i
        raise KeyError(name)
