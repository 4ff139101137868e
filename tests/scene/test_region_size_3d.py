"""A region's own mesh size in 3D (`regions[i].mesh: {size}`, as in 2D): gmsh meets a size s with
median edges of 1.1-1.3 s (measured), hence the window 1-1.5 s; the cell estimate before meshing
bounds the count; a mesh file is used as it is, so a region size there is refused.
"""
import gmsh
import numpy as np
import pytest
import yaml

from wcs.errors import StudyError
from wcs.scene.mesher3d import build_mesh3d
from wcs.scene.session import Session
from wcs.study import load_study

from tests.fem.test_glue_3d import MATERIALS


def median_edge(mesh, cells) -> float:
    t = mesh.t[:, cells]
    return float(np.median(np.concatenate([np.linalg.norm(mesh.p[:, t[i]] - mesh.p[:, t[j]], axis=0)
                                           for i in range(4) for j in range(i + 1, 4)])))


def core_scene(h=0.25, s=0.08, shape=None, body_size=None) -> dict:
    core = shape or {"box": [0.25, 0.25, 0.25, 0.75, 0.75, 0.75]}
    regions = [{"material": "stiff", "shape": {"box": [0, 0, 0, 1, 1, 1], "minus": [core]}},
               {"material": "soft", "name": "core", "shape": core, "mesh": {"size": s}}]
    body = {"regions": regions} if body_size is None else {"regions": regions, "mesh": {"size": body_size}}
    return {"study": "core-3d", "scene": {"dimension": 3, "mesh": {"size": h}, "materials": MATERIALS,
                                          "bodies": {"cube": body}}}


@pytest.mark.parametrize("h, s, body_size", [(0.25, 0.08, None), (0.25, 0.1, 0.2)])
def test_a_region_own_size_meshes_its_cells_at_it_and_the_estimate_bounds_the_count(h, s, body_size):
    """The core's cells have a median edge of 1-1.5 times its size, the rest of the cube that of
    the scene (or of the body meshed on its own) or finer (the transition), never coarser; the
    estimate before meshing is at least the meshed count."""
    study = load_study(core_scene(h, s, body_size=body_size))
    sm = build_mesh3d(study.scene)
    core, rest = sm.cell_region == 1, sm.cell_region == 0
    assert 1.0 * s <= median_edge(sm.mesh, core) <= 1.5 * s
    outer = h if body_size is None else body_size
    assert s * 1.5 < median_edge(sm.mesh, rest) <= 1.5 * outer
    assert study.estimated_cells >= sm.mesh.t.shape[1]
    without = core_scene(h, s, body_size=body_size)
    del without["scene"]["bodies"]["cube"]["regions"][1]["mesh"]
    coarse = build_mesh3d(load_study(without).scene)
    # cells ∝ size⁻³, the sizes met within 1-1.5×: the core holds ≥ (outer / 1.5 s)³ times the cells
    assert np.count_nonzero(core) >= (outer / (1.5 * s)) ** 3 * np.count_nonzero(coarse.cell_region == 1)


@pytest.mark.slow
@pytest.mark.parametrize("L, h, s, shape", [
    (4, 0.5, 0.1, {"box": [1.5, 1.5, 1.5, 2.5, 2.5, 2.5]}),
    (2, 0.4, 0.1, {"box": [0, 0, 0, 2, 2, 0.3]}),
    (2, 0.4, 0.08, {"sphere": {"center": [1, 1, 1], "radius": 0.5}}),
    (2, 0.4, 0.08, {"cylinder": {"start": [1, 1, 0], "end": [1, 1, 2], "radius": 0.3}}),
])
def test_the_estimate_bounds_the_count_of_finer_regions(L, h, s, shape):
    d = core_scene(h, s, shape)
    d["scene"]["bodies"]["cube"]["regions"][0]["shape"]["box"] = [0, 0, 0, L, L, L]
    study = load_study(d)
    sm = build_mesh3d(study.scene)
    assert sm.mesh.t.shape[1] <= study.estimated_cells <= 3 * sm.mesh.t.shape[1]
    assert 1.0 * s <= median_edge(sm.mesh, sm.cell_region == 1) <= 1.5 * s


def test_a_region_size_on_a_mesh_file_is_refused_at_its_key(tmp_path):
    """A mesh file is used as it is: a region's own size there is exit 2 at its key path (it
    would be silently ignored)."""
    with Session():
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], name="cube")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(tmp_path / "cube.msh"))
    d = {"study": "file-3d", "scene": {"dimension": 3, "mesh": {"file": "cube.msh"}, "materials": MATERIALS,
                                       "bodies": {"cube": {"regions": [{"material": "stiff", "mesh": {"size": 0.1}}]}}}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(d))
    with pytest.raises(StudyError, match="scene.bodies.cube.regions.0.mesh: the scene's mesh is a file: a region "
                                         "cannot have its own mesh size"):
        load_study(tmp_path / "s.yaml")
