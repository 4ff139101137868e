"""Absorbing boundaries (a scene's `absorbing:` block): the seed's damping layer and
Lysmer–Kuhlemeyer dashpots, as matrices C added to the damping of M ü + C u̇ + K u = f.

    absorbing:
      layer: {boundaries: [left, right, bottom], thickness: D, damping: α}
      dashpots: [left, right, bottom]

- The layer [101, §2]: "the damping α(x) > 0, defined by such a way that the waves propagated
  through the areas of a certain thickness D (in which α(x) > 0) near the boundary Γ_u are
  completely absorbed", entering the equation as (α u̇, v) [101, (8)]. Here α
  [1/s] is mass proportional: C = α ∫_layer ρ φ_a φ_b dx (the seed's α(x) is ρα), in the cells
  whose centroid lies within distance D of the named boundaries. A wave of angular frequency ω
  decays as exp(−α t / 2) in amplitude in the layer, and the layer's edge reflects
  |(1 − √(1 + iα/ω)) / (1 + √(1 + iα/ω))|² of its energy: α ≪ ω over several wavelengths absorbs.
- Dashpots (Lysmer & Kuhlemeyer 1969, J. Eng. Mech. Div. ASCE 95): the traction −ρ c_p u̇_n on
  the normal and −ρ c_s u̇_t on the tangential velocity, C_ab = ∫_Γ (ρc_p n⊗n + ρc_s (I − n⊗n))
  φ_a φ_b ds on the named boundary facets. At normal incidence it absorbs a plane P (or S) wave
  exactly (in 1D the impedance matches: no reflection); obliquely it reflects a little.

Boundary names are the scene's (`SceneMesh.boundaries`, resolved from the selectors by the
mesher, 2D and 3D alike). dof = d·node + component.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..errors import StudyError
from ..geometry import tet
from ..geometry.facets import facet_lengths, facet_normals
from ..scene.spec import Absorbing, Layer
from .mass import mass_cell_matrices

def check_references(absorbing: Absorbing, boundaries, path: str) -> None:
    """StudyError at the key (e.g. `scene.absorbing.dashpots.1`) of a boundary name the scene does not have."""
    named = [(f"{path}.dashpots.{i}", n) for i, n in enumerate(absorbing.dashpots)]
    if absorbing.layer is not None:
        named += [(f"{path}.layer.boundaries.{i}", n) for i, n in enumerate(absorbing.layer.boundaries)]
    for key, name in named:
        if name not in boundaries:
            raise StudyError(f"unknown boundary '{name}' (boundaries: {', '.join(boundaries) or 'none'})", path=key)


def named_facets(sm, names, path: str) -> np.ndarray:
    """Sorted unique indices into `sm.mesh.facets` of the named boundaries' facets."""
    for i, name in enumerate(names):
        if name not in sm.boundaries:
            raise StudyError(f"unknown boundary '{name}' (boundaries: {', '.join(sm.boundaries) or 'none'})",
                             path=f"{path}.{i}")
    return np.unique(np.concatenate([np.asarray(sm.boundaries[n], dtype=np.int64) for n in names]))


def facet_geometry(mesh, facets) -> tuple[np.ndarray, np.ndarray]:
    """(n, d) outward unit normals and (n,) measures (lengths, areas) of boundary facets."""
    if mesh.p.shape[0] == 3:
        return tet.face_normals(mesh, facets)
    return facet_normals(mesh, facets), facet_lengths(mesh, facets)


def impedances(rho, lam, mu) -> tuple[np.ndarray, np.ndarray]:
    """(ρ c_p, ρ c_s) = (√(ρ(λ + 2μ)), √(ρμ)): λ, μ as they enter the stiffness (plane stress:
    λ* = 2λμ/(λ + 2μ), the plate's P-wave speed)."""
    rho, lam, mu = (np.asarray(a, dtype=float) for a in (rho, lam, mu))
    return np.sqrt(rho * (lam + 2.0 * mu)), np.sqrt(rho * mu)


def dashpot_matrix(mesh, facets, zp, zs) -> sp.csr_matrix:
    """C_ab = Σ_facets (zp n⊗n + zs (I − n⊗n)) ∫_f φ_a φ_b ds (d nnodes square): zp = ρc_p and
    zs = ρc_s of each facet's body (a number or (n,) per facet; the owning cell is
    `mesh.f2t[0, facets]`); ∫_f φ_a φ_b = |f| (1 + δ_ab) / (d (d + 1)) on a flat P1 facet."""
    facets = np.asarray(facets, dtype=np.int64)
    d = mesh.p.shape[0]
    n, size = facet_geometry(mesh, facets)
    zp = np.broadcast_to(np.asarray(zp, dtype=float), size.shape)
    zs = np.broadcast_to(np.asarray(zs, dtype=float), size.shape)
    nn = n[:, :, None] * n[:, None, :]
    D = zs[:, None, None] * np.eye(d) + (zp - zs)[:, None, None] * nn           # (nf, d, d)
    ab = (1.0 + np.eye(d)) / (d * (d + 1))                                     # (d, d) per unit measure
    blocks = size[:, None, None, None, None] * ab[None, :, :, None, None] * D[:, None, None]   # (nf, a, b, i, j)
    nodes = mesh.facets[:, facets].T                                           # (nf, d)
    return _assemble(nodes, blocks, d, mesh.p.shape[1])


def weighted_mass(p, t, cells, weight) -> sp.csr_matrix:
    """∫ w φ_a φ_b I dx over the given cells, w constant per cell (a number or one per cell): the
    consistent P1 mass of `wcs.dynamics.mass` times w (d nnodes square)."""
    cells = np.asarray(cells, dtype=np.int64)
    local = mass_cell_matrices(p, t[:, cells])[0]                              # (ne, a, b, i, j), unit density
    w = np.broadcast_to(np.asarray(weight, dtype=float), (cells.size,))
    return _assemble(t[:, cells].T, w[:, None, None, None, None] * local, p.shape[0], p.shape[1])


def _assemble(nodes, blocks, d, nnodes) -> sp.csr_matrix:
    """Sum of element blocks (ne, k, k, d, d) at node tuples (ne, k) into a (d nnodes)² CSR matrix."""
    k = nodes.shape[1]
    dof = d * nodes[:, :, None] + np.arange(d)                                 # (ne, k, d)
    rows = np.broadcast_to(dof[:, :, None, :, None], (len(nodes), k, k, d, d))
    cols = np.broadcast_to(dof[:, None, :, None, :], (len(nodes), k, k, d, d))
    return sp.csr_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(d * nnodes, d * nnodes))


def layer_cells(mesh, facets, thickness: float) -> np.ndarray:
    """Sorted cells whose centroid lies within `thickness` of the boundary facets (the exact
    distance to the segments / triangles). A k-d tree of the facets' midpoints settles most cells by
    the facet of the nearest midpoint; a cell it leaves open (its nearest midpoint within
    thickness + the facets' reach, that facet farther than thickness) tries every facet that near."""
    facets = np.asarray(facets, dtype=np.int64)
    d = mesh.p.shape[0]
    centroid = sum(mesh.p[:, mesh.t[k]] for k in range(d + 1)).T / (d + 1)      # (nc, d)
    corners = mesh.p[:, mesh.facets[:, facets]].transpose(2, 1, 0)            # (nf, d, dim)
    middle = corners.mean(axis=1)
    reach = np.linalg.norm(corners - middle[:, None], axis=2).max()
    tree = cKDTree(middle)
    nearest, facet = tree.query(centroid, distance_upper_bound=thickness + reach)
    near = np.flatnonzero(np.isfinite(nearest))
    inside = np.zeros(len(centroid), dtype=bool)
    inside[near] = _distance_to_simplex(centroid[near], corners[facet[near]]) <= thickness
    unsure = near[~inside[near]]
    if unsure.size:
        lists = tree.query_ball_point(centroid[unsure], thickness + reach)
        cell = np.repeat(unsure, [len(f) for f in lists])
        facet = np.concatenate([np.asarray(f, dtype=np.int64) for f in lists])
        hit = cell[_distance_to_simplex(centroid[cell], corners[facet]) <= thickness]
        inside[hit] = True
    return np.flatnonzero(inside)


def _distance_to_segment(x, a, b) -> np.ndarray:
    d = b - a
    s = np.clip(np.einsum("ij,ij->i", x - a, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    return np.linalg.norm(x - a - s[:, None] * d, axis=1)


def _distance_to_simplex(x, corners) -> np.ndarray:
    """Distance of points x (k, dim) to segments or triangles corners (k, 2 or 3, dim)."""
    if corners.shape[1] == 2:
        return _distance_to_segment(x, corners[:, 0], corners[:, 1])
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    h = np.einsum("ij,ij->i", x - a, n)
    q = x - h[:, None] * n                                                     # the projection on the plane
    inside = np.all([np.einsum("ij,ij->i", np.cross(v - u, q - u), n) >= 0.0 for u, v in ((a, b), (b, c), (c, a))],
                    axis=0)
    edges = np.min([_distance_to_segment(x, u, v) for u, v in ((a, b), (b, c), (c, a))], axis=0)
    return np.where(inside, np.abs(h), edges)


def layer_damping(sm, layer: Layer, rho_cell, path: str) -> sp.csr_matrix:
    """The seed's layer as a matrix: α ∫_layer ρ φ_a φ_b dx (ρ per cell, (ncells,)); StudyError at
    `path` (e.g. `scene.absorbing.layer`) for an unknown boundary."""
    facets = named_facets(sm, layer.boundaries, f"{path}.boundaries")
    cells = layer_cells(sm.mesh, facets, layer.thickness)
    rho = np.broadcast_to(np.asarray(rho_cell, dtype=float), (sm.mesh.t.shape[1],))
    return weighted_mass(sm.mesh.p, sm.mesh.t, cells, layer.damping * rho[cells])


def dashpots(sm, names, rho_cell, lam_cell, mu_cell, path: str) -> sp.csr_matrix:
    """The Lysmer–Kuhlemeyer matrix on the named boundaries, each facet with the impedances of its
    owning cell's material (per-cell arrays ρ, λ, μ as the stiffness takes them); StudyError at
    `path` (e.g. `scene.absorbing.dashpots`) for an unknown boundary."""
    facets = named_facets(sm, names, path)
    owner = sm.mesh.f2t[0, facets]
    zp, zs = impedances(*(np.broadcast_to(np.asarray(a, dtype=float), (sm.mesh.t.shape[1],))[owner]
                          for a in (rho_cell, lam_cell, mu_cell)))
    return dashpot_matrix(sm.mesh, facets, zp, zs)


class AbsorbingCells:
    """The layer and the dashpots as cell pieces (`wcs.fem.affine.CellMatrices`' protocol) for a
    solve that assembles each subdomain itself (`dd`): piece 0 the consistent mass of unit density
    on the layer's cells (zero elsewhere), pieces 1 and 2 the dashpots' n⊗n and I − n⊗n facet
    terms of unit impedance, each facet's on its owning cell (a facet's nodes are among its
    cell's). At per region (α ρ, ρ c_p, ρ c_s) (`absorbing_coefficients`) they sum to
    `layer_damping` + `dashpots`. `key`: the layer's cells (what a held decomposition is made of)."""

    npieces = 3

    def __init__(self, mesh, layer, facets):
        self.p, self.t = mesh.p, mesh.t
        d = mesh.p.shape[0]
        self.block = d
        self.layer = np.zeros(mesh.t.shape[1], dtype=bool)
        self.layer[np.asarray(layer, dtype=np.int64)] = True
        self.key = np.flatnonzero(self.layer).tobytes()
        facets = np.asarray(facets, dtype=np.int64)
        self.owner = mesh.f2t[0, facets]
        nodes, cell_nodes = mesh.facets[:, facets].T, mesh.t[:, self.owner].T     # (nf, d), (nf, d + 1)
        self.position = np.argmax(cell_nodes[:, None, :] == nodes[:, :, None], axis=2)   # (nf, d)
        if facets.size:
            n, size = facet_geometry(mesh, facets)
            nn = n[:, :, None] * n[:, None, :]
            unit = size[:, None, None, None, None] * ((1.0 + np.eye(d)) / (d * (d + 1)))[None, :, :, None, None]
            self.facet_blocks = (unit * nn[:, None, None], unit * (np.eye(d) - nn)[:, None, None])
        else:
            self.facet_blocks = (np.zeros((0, d, d, d, d)),) * 2

    def of(self, cells) -> np.ndarray:
        cells = np.asarray(cells, dtype=np.int64)
        d = self.block
        out = np.zeros((3, cells.size, d + 1, d + 1, d, d))
        out[0] = mass_cell_matrices(self.p, self.t[:, cells])[0] * self.layer[cells][:, None, None, None, None]
        where = np.full(self.t.shape[1], -1)
        where[cells] = np.arange(cells.size)
        k = where[self.owner]
        mine = k >= 0
        k, pos = k[mine], self.position[mine]
        for piece, blocks in zip((1, 2), self.facet_blocks):
            for a in range(d):
                for b in range(d):
                    np.add.at(out[piece], (k, pos[:, a], pos[:, b]), blocks[mine, a, b])
        return out


def absorbing_coefficients(alpha: float, rho, lam, mu) -> np.ndarray:
    """(nregions, 3): per region (α ρ, ρ c_p, ρ c_s), the coefficients of `AbsorbingCells`' pieces
    (α the layer's damping, 0 without a layer; ρ, λ, μ per region as the stiffness takes them)."""
    zp, zs = impedances(rho, lam, mu)
    return np.column_stack([alpha * np.asarray(rho, dtype=float), zp, zs])


# What of the absorbing boundaries can be uncertain, with its physical range (the loader's address table).
