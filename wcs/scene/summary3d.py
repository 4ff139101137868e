"""What a 3D study holds, in the words of the study file, with its mesh (`wcs check`)."""
from __future__ import annotations

import numpy as np

from ..geometry.tet import volumes
from .estimate import DEFAULT_MAX_CELLS
from .meshdata import SceneMesh


def _words(value) -> str:
    return str(value.model_dump(by_alias=True, exclude_none=True, exclude_defaults=True)
               if hasattr(value, "model_dump") else value)


def _areas(mesh, facets: np.ndarray) -> float:
    x = mesh.p[:, mesh.facets[:, facets]]
    return float(0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], axis=0), axis=0).sum())


def summary3d(study, sm: SceneMesh) -> str:
    """The mesh (nodes, tetrahedra, edge lengths, volumes per region, face areas per boundary)
    and the scene's supports, loads, contacts, glue and thermal data (`wcs.cli.plan` adds the
    parameters, criteria, search and output)."""
    scene, mesh = study.scene, sm.mesh
    p, t = mesh.p, mesh.t
    pairs = [(a, b) for a in range(4) for b in range(a + 1, 4)]
    edges = np.max([np.linalg.norm(p[:, t[a]] - p[:, t[b]], axis=0) for a, b in pairs], axis=0)
    vol = volumes(p, t)
    lines = [f"study {study.name}  ({study.file})",
             f"  model: 3D, P1 tetrahedra, {p.shape[1]} nodes, {t.shape[1]} cells, {3 * p.shape[1]} unknowns, "
             f"{'thermal step + ' if scene.thermal else ''}elasticity{' with contact' if scene.contacts else ''}",
             "  bodies:"]
    for b, name in enumerate(sm.bodies):
        regs = [(j, r) for j, (bb, r) in enumerate(sm.regions) if bb == name]
        material = {r.name: r.material for r in scene.bodies[name].regions}
        lines.append(f"    {name}: " + ", ".join(
            f"{r} [{material[r]}, {int(np.sum(sm.cell_region == j))} cells, volume {vol[sm.cell_region == j].sum():.4g}]"
            for j, r in regs))
    m = scene.mesh
    made = f"file {m.file}" if m.file else f"target size {'default' if m.size is None else m.size}"
    lines.append(f"  mesh: {made}"
                 + "".join(f", body {b}: {_words(v.mesh)}" for b, v in scene.bodies.items() if v.mesh)
                 + f"; cell diameters from {edges.min():.3g} m to {edges.max():.3g} m"
                 + ("" if study.estimated_cells is None else
                    f"; estimated {study.estimated_cells:.3g} cells before meshing (limit mesh.max_cells = "
                    f"{DEFAULT_MAX_CELLS if m.max_cells is None else m.max_cells:g})"))
    lines.append("  boundaries:")
    for name, facets in sm.boundaries.items():
        lines.append(f"    {name}: {len(facets)} triangles, area {_areas(mesh, facets):.4g}")
    for name, cells in sm.roi_cells.items():
        lines.append(f"  region of interest {name}: {len(cells)} cells, volume {vol[cells].sum():.4g}")
    for key, label in (("supports", "support"), ("loads", "load"), ("body_forces", "body force"),
                       ("contacts", "contact"), ("glue", "glue")):
        for name, v in getattr(scene, key).items():
            lines.append(f"  {label} {name}: {_words(v)}")
    if scene.thermal:
        lines.append(f"  thermal: {_words(scene.thermal)}")
    return "\n".join(lines)
