"""Whether a solution stays where the model holds: small strains, small rotations, small slips.

The model is linear elasticity with contact conditions between points paired in the undeformed
configuration (thesis §1; seed [101] eq. (2.1)-(2.3)): the strain is ε = ½(∇u + ∇uᵀ), and the
Green–Lagrange strain it stands for is E = ε + ½∇uᵀ∇u. The neglected term is |∇u|/2 of |∇u|
itself at most: `MAX_GRADIENT` = 0.1 keeps it within 5 % of the strain, the order of the mesh's
own share (wcs/results/meshcheck.py), and it bounds the rotations too, which ε does not see. It lets
the peaks of a few percent at contact edges pass (the cylinder of validation/hertz.yaml 0.023,
the knee's insert 0.054 at the nominal data), not a rubber pad strained by 20 %
(two-blocks-demo, 0.21) nor a modulus given in GPa where Pa is meant (10⁹ times the strain).
The contact pairs and normals are those of the undeformed bodies: a body displaced by more than
`MAX_DISPLACEMENT` = 5 % of its own size has moved onto other contact points and normals than
the model pairs — a slide of 6.4 m of a 10 cm block is a number without meaning.

The two measures of a displacement field, from the P1 fields of the results file:
- `displacement`: max over bodies of max |u| on the body / the diagonal of its bounding box;
- `gradient`: max over cells of the spectral norm |∇u| (u is linear on each cell).
"""
from __future__ import annotations

import numpy as np

MAX_GRADIENT = 0.1           # |∇u|: ½∇uᵀ∇u, left out of the strain, stays within 5 % of it
MAX_DISPLACEMENT = 0.05      # max |u| / body size: the contact pairs of the undeformed bodies still face
CELLS = 16384                # cells whose gradients `measures` makes at once
MEANINGLESS = 1.0            # |∇u| or max |u| / body size at 1: a cell may turn inside out, a body leaves
                             # its own place; no linear answer means anything (a modulus in GPa, not Pa)


def gradients(coords: np.ndarray, cells: np.ndarray, u: np.ndarray) -> np.ndarray:
    """∇u of each P1 cell (cell, d, d), [i, j] = ∂u_i/∂x_j: the edges from the cell's first
    vertex, E (d × d), and the displacement differences along them, D = E ∇uᵀ (NaN on a cell
    of no volume)."""
    edges = coords[cells[:, 1:]] - coords[cells[:, :1]]          # (cell, d, d): rows are edges
    du = u[cells[:, 1:]] - u[cells[:, :1]]
    flat = np.linalg.det(edges) == 0
    edges[flat] = np.eye(coords.shape[1])
    out = np.swapaxes(np.linalg.solve(edges, du), 1, 2)
    out[flat] = np.nan
    return out


def measures(coords, cells, cell_body, u) -> tuple[float, float]:
    """(max |u| / body size over the bodies, max |∇u| over the cells) of a displacement field."""
    coords, cells, u = np.asarray(coords, float), np.asarray(cells, np.int64), np.asarray(u, float)
    body = np.zeros(len(cells), int) if cell_body is None else np.asarray(cell_body, int)
    ratio = 0.0
    for b in np.unique(body):
        nodes = np.zeros(len(coords), bool)
        nodes[cells[body == b].ravel()] = True
        size = float(np.linalg.norm(coords[nodes].max(axis=0) - coords[nodes].min(axis=0)))
        ratio = max(ratio, float(np.linalg.norm(u[nodes], axis=1).max()) / size)
    largest = 0.0
    for start in range(0, len(cells), CELLS):    # made for a block of cells at a time: 290 bytes a cell in 3D
        g = gradients(coords, cells[start:start + CELLS], u)
        g = g[np.isfinite(g).all(axis=(1, 2))]
        # the spectral norm: the square root of the largest eigenvalue of ∇uᵀ∇u (symmetric: cheaper than an SVD)
        if len(g):
            largest = max(largest, float(np.linalg.eigvalsh(np.einsum("cji,cjk->cik", g, g))[:, -1].max()))
    return ratio, float(np.sqrt(max(largest, 0.0)))


def warning(ratio: float, grad: float, where: str) -> str:
    """One sentence when the measures leave the model's validity ("" when within, or unknown)."""
    out = []
    if grad > MAX_GRADIENT:
        out.append(f"displacement gradients up to {grad:.3g} (strains or rotations beyond the {MAX_GRADIENT:g} of "
                   f"small-strain theory)")
    if ratio > MAX_DISPLACEMENT:
        out.append(f"displacements up to {ratio:.3g} times a body's size (beyond {MAX_DISPLACEMENT:g}: the contact "
                   f"pairs of the undeformed bodies no longer face)")
    return (f"{where}: " + " and ".join(out) + "; the linear model does not hold there (a large deformation, "
            "or data in other units than SI)" if out else "")


def variables(coords, cells, cell_body, u) -> dict:
    """The two measures as scalar field variables (`small_strain_displacement`, `small_strain_gradient`)."""
    ratio, grad = measures(coords, cells, cell_body, u)
    return {"small_strain_displacement": ((), ratio, {
                "long_name": "max |u| / body size (bounding-box diagonal) over the bodies",
                "valid_max": MAX_DISPLACEMENT, "comment": "beyond valid_max the small-slip contact pairing fails"}),
            "small_strain_gradient": ((), grad, {
                "long_name": "max over cells of the spectral norm of the displacement gradient",
                "valid_max": MAX_GRADIENT, "comment": "beyond valid_max small-strain theory fails"})}


def meaningless(ds) -> bool:
    """Whether some stored measure of the file (a solve's, the nominal's, a worst case's) reaches
    MEANINGLESS: between the MAX_* limits and it a result is warned of; beyond, it is no answer."""
    names = [f"{p}small_strain_{m}" for p in ("", "nominal_", "worst_") for m in ("displacement", "gradient")]
    return any(np.nanmax(np.atleast_1d(ds[n].values).astype(float), initial=0.0) >= MEANINGLESS
               for n in names if n in ds)


def warnings(ds) -> list[str]:
    """The validity warnings of a results file: its solve's fields (`small_strain_*`), or a run's
    nominal case (`nominal_small_strain_*`) and the worst case of each criterion
    (`worst_small_strain_*`, criterion)."""
    out = []
    for prefix, where in (("", "the solved case"), ("nominal_", "the nominal case")):
        if f"{prefix}small_strain_gradient" in ds:
            w = warning(float(ds[f"{prefix}small_strain_displacement"].values),
                        float(ds[f"{prefix}small_strain_gradient"].values), where)
            out += [w] if w else []
    if "worst_small_strain_gradient" in ds:
        done = set()
        for c in ds["criterion"].values:
            r = float(ds["worst_small_strain_displacement"].sel(criterion=c))
            g = float(ds["worst_small_strain_gradient"].sel(criterion=c))
            if (r, g) in done:
                continue
            done.add((r, g))
            w = warning(r, g, f"the worst case of {c}")
            out += [w] if w else []
    return out
