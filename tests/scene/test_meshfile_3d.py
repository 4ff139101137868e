"""3D scenes from the user's own mesh file (`scene: {dimension: 3, mesh: {file: ...}}`).

A block on a two-region base, meshed by gmsh from the same two boxes and fragment as the
scene built from solids, is written to a .msh with physical groups (3D: `base:lower`,
`base:upper`, `block`; 2D: `base_bottom`, `block_top` and the contact face twice,
`base:base_top` and `block:block_bottom`). Read back, it is the scene meshed from solids:
the same node count (the contact face's nodes doubled), region volumes and face areas equal
to round-off (planar faces are meshed exactly: the boxes' volumes and areas). Every bad file
or study is exit 2 naming the file and the key path; seeded mutations never fail inside."""
from __future__ import annotations

import copy
import io
import random
import re
from contextlib import redirect_stderr, redirect_stdout

import gmsh
import numpy as np
import pytest
import yaml

from tests.acceptance.test_fuzz_check import mutate
from tests.support.bad_studies import drop, put
from wcs.cli import main
from wcs.geometry.tet import volumes
from wcs.scene.mesher3d import ALGORITHM_3D, build_mesh3d
from wcs.scene.session import Session
from wcs.scene.spec import GroupBoundary
from wcs import load_study

SIZE = 0.25
LOWER, UPPER, BLOCK = [0, 0, -0.5, 1, 1, -0.25], [0, 0, -0.25, 1, 1, 0], [0.2, 0.2, 0, 0.8, 0.8, 0.4]

SOLIDS = f"""
study: block-on-base-3d
scene:
  dimension: 3
  mesh: {{size: {SIZE}}}
  materials:
    stiff: {{E: 1.0e10, nu: 0.25}}
    soft: {{E: 1.0e9, nu: 0.35}}
  bodies:
    base: {{regions: [{{material: stiff, name: lower, shape: {{box: {LOWER}}}}},
                      {{material: stiff, name: upper, shape: {{box: {UPPER}}}}}]}}
    block: {{regions: [{{material: soft, name: block, shape: {{box: {BLOCK}}}}}]}}
  boundaries:
    base_bottom: {{plane: {{point: [0, 0, -0.5], normal: [0, 0, 1]}}}}
    block_top: {{plane: {{point: [0, 0, 0.4], normal: [0, 0, 1]}}}}
    base_top: {{body: base, box: [0.2, 0.2, 0, 0.8, 0.8, 0]}}
    block_bottom: {{body: block, plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}
    base_side: {{plane: {{point: [1, 0, 0], normal: [1, 0, 0]}}}}
  supports:
    base_bottom: {{u: [0.0, 0.0, 0.0]}}
  loads:
    block_top: {{traction: [0.0, 0.0, -1.0e6]}}
  contacts:
    interface: {{slave: block_bottom, master: base_top}}
  regions_of_interest:
    contact: {{boundary: base_top}}
uncertain:
  materials.soft.E: [0.8e9, 1.2e9]
criteria:
  - {{name: pressure, kind: contact_pressure, regions: [contact]}}
"""

FILE = """
study: block-on-base-3d-file
scene:
  dimension: 3
  mesh: {file: block.msh}
  materials:
    stiff: {E: 1.0e10, nu: 0.25}
    soft: {E: 1.0e9, nu: 0.35}
  bodies:
    base: {regions: [{material: stiff, name: lower}, {material: stiff, name: upper}]}
    block: {regions: [{material: soft}]}
  boundaries:
    base_side: {plane: {point: [1, 0, 0], normal: [1, 0, 0]}}
  supports:
    base_bottom: {u: [0.0, 0.0, 0.0]}
  loads:
    block_top: {traction: [0.0, 0.0, -1.0e6]}
  contacts:
    interface: {slave: block_bottom, master: base_top}
  regions_of_interest:
    contact: {boundary: base_top}
uncertain:
  materials.soft.E: [0.8e9, 1.2e9]
criteria:
  - {name: pressure, kind: contact_pressure, regions: [contact]}
"""

AREAS = {"base_bottom": 1.0, "block_top": 0.36, "base_top": 0.36, "block_bottom": 0.36, "base_side": 0.5}
VOLUMES = [0.25, 0.25, 0.144]


def _faces_at(z: float, box=None) -> list[int]:
    """Tags of the model's surfaces lying in the plane z (inside the xy box, if given)."""
    out, tol = [], 1e-6                     # OCC bounding boxes are padded by its tolerance 1e-7
    for _, tag in gmsh.model.getEntities(2):
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, tag)
        if abs(z0 - z) < tol and abs(z1 - z) < tol and (box is None or (
                x0 > box[0] - tol and y0 > box[1] - tol and x1 < box[2] + tol and y1 < box[3] + tol)):
            out.append(tag)
    return out


def write_block_msh(path, order: int = 1) -> None:
    """The block on the two-region base, meshed as `build_mesh3d` meshes the scene of solids
    (one fragment of the three boxes, Delaunay 3D, `Mesh.MeshSizeMax` = SIZE)."""
    with Session():
        occ = gmsh.model.occ
        boxes = [occ.addBox(*b[:3], *np.subtract(b[3:], b[:3])) for b in (LOWER, UPPER, BLOCK)]
        _, pieces = occ.fragment([(3, boxes[0])], [(3, b) for b in boxes[1:]])
        occ.synchronize()
        lower, upper, block = (m[0][1] for m in pieces)
        contact = _faces_at(0.0, (0.2, 0.2, 0.8, 0.8))
        groups = [(3, [lower], "base:lower"), (3, [upper], "base:upper"), (3, [block], "block"),
                  (2, _faces_at(-0.5), "base_bottom"), (2, _faces_at(0.4), "block_top"),
                  (2, contact, "base:base_top"), (2, contact, "block:block_bottom")]
        for dim, tags, name in groups:
            gmsh.model.addPhysicalGroup(dim, tags, name=name)
        gmsh.option.setNumber("Mesh.Algorithm3D", ALGORITHM_3D)
        gmsh.option.setNumber("Mesh.MeshSizeMax", SIZE)
        gmsh.model.mesh.generate(3)
        if order > 1:
            gmsh.model.mesh.setOrder(order)
        gmsh.write(str(path))


GMSH_TYPE = {3: 2, 4: 4, 6: 6, 10: 11}     # nodes of an element -> gmsh type: triangle, tetrahedron, prism, 10-node tet


def write_tets(path, nodes, groups: dict) -> None:
    """A .msh by the gmsh API from node coordinates and {name: (dim, [0-based cells])}: one
    discrete entity per group (the nodes in the first)."""
    with Session():
        for k, (name, (dim, cells)) in enumerate(groups.items()):
            tag = gmsh.model.addDiscreteEntity(dim)
            if k == 0:
                gmsh.model.mesh.addNodes(dim, tag, list(range(1, len(nodes) + 1)), np.ravel(nodes).tolist())
            gmsh.model.mesh.addElementsByType(tag, GMSH_TYPE[len(cells[0])], [],
                                              (np.asarray(cells) + 1).ravel().tolist())
            gmsh.model.addPhysicalGroup(dim, [tag], name=name)
        gmsh.write(str(path))


@pytest.fixture(scope="module")
def block_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("msh3d")
    write_block_msh(folder / "block.msh")
    (folder / "study.yaml").write_text(FILE)
    return folder


def run(args) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(args)
    return code, out.getvalue(), err.getvalue()


# ---------------------------------------------------------------- the block on the base


def test_the_file_gives_the_scene_meshed_from_solids(block_file):
    study = load_study(block_file / "study.yaml")
    scene = study.scene
    assert scene.boundaries["base_top"] == GroupBoundary(group="base:base_top", body="base")
    assert scene.boundaries["base_bottom"] == GroupBoundary(group="base_bottom", body=None)
    sm = build_mesh3d(scene)
    ref = build_mesh3d(load_study(yaml.safe_load(SOLIDS)).scene)
    assert sm.bodies == ref.bodies == ["base", "block"]
    assert sm.regions == ref.regions == [("base", "lower"), ("base", "upper"), ("block", "block")]
    assert sm.mesh.p.shape == ref.mesh.p.shape and sm.mesh.t.shape == ref.mesh.t.shape
    vol = volumes(sm.mesh.p, sm.mesh.t)
    assert (vol > 0).all()                                        # positively oriented
    by_region = [vol[sm.cell_region == j].sum() for j in range(3)]
    ref_vol = volumes(ref.mesh.p, ref.mesh.t)
    assert by_region == pytest.approx([ref_vol[ref.cell_region == j].sum() for j in range(3)], rel=1e-12)
    assert by_region == pytest.approx(VOLUMES, rel=1e-12)

    def area(m, facets):
        x = m.mesh.p[:, m.mesh.facets[:, facets]]
        return 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], axis=0), axis=0).sum()
    for name, a in AREAS.items():
        assert area(sm, sm.boundaries[name]) == pytest.approx(a, rel=1e-12), name
        assert len(sm.boundaries[name]) == len(ref.boundaries[name]), name
    # the two sides of the contact: the same face, one body each, each with its own nodes
    f, nb = sm.mesh.facets, sm.node_body
    top, bottom = f[:, sm.boundaries["base_top"]], f[:, sm.boundaries["block_bottom"]]
    assert set(nb[top.ravel()]) == {0} and set(nb[bottom.ravel()]) == {1}
    assert not set(top.ravel()) & set(bottom.ravel())
    assert np.allclose(sm.mesh.p[2, top], 0.0) and np.allclose(sm.mesh.p[2, bottom], 0.0)
    # the regions of one body share their nodes on z = -0.25
    lower, upper = (set(sm.mesh.t[:, sm.cell_region == j].ravel()) for j in (0, 1))
    assert len(lower & upper) > 10


def test_check_prints_the_file_mesh(block_file):
    code, out, err = run(["check", str(block_file / "study.yaml")])
    # the file's study is a frictionless block with no tangential hold: check solves its nominal
    # data and refuses it by name (status 7), after printing the mesh
    assert code == 2 and "body 'block' is not held" in err, err
    mesh_line = next(line for line in out.splitlines() if line.startswith("  mesh: "))
    assert mesh_line.startswith("  mesh: file ") and str(block_file / "block.msh") in out
    assert "estimated" not in mesh_line         # the file's mesh is read, not estimated
    vols = [float(v) for v in re.findall(r"volume ([0-9.e+-]+)\]", out)]
    assert vols == pytest.approx(VOLUMES, rel=1e-12)
    areas = dict(re.findall(r"    (\w+): \d+ triangles, area ([0-9.e+-]+)", out))
    assert {k: float(v) for k, v in areas.items()} == pytest.approx(AREAS, rel=1e-3)   # printed to 4 digits


def test_negatively_oriented_tetrahedra_are_reoriented_with_a_note(tmp_path):
    nodes = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)]
    write_tets(tmp_path / "m.msh", nodes, {"a": (3, [[0, 2, 1, 3], [1, 2, 3, 4]])})   # the first negative
    study = load_study({"scene": {"dimension": 3, "mesh": {"file": "m.msh"},
                                  "materials": {"s": {"E": 1.0e9, "nu": 0.3}},
                                  "bodies": {"a": {"regions": [{"material": "s"}]}}}}, base_dir=tmp_path)
    assert "m.msh: 1 negatively oriented tetrahedron(s) reoriented" in study.notes
    sm = build_mesh3d(study.scene)
    assert volumes(sm.mesh.p, sm.mesh.t) == pytest.approx([1 / 6, 1 / 3], rel=1e-12)


# ---------------------------------------------------------------- bad files and studies


def _doc() -> dict:
    return yaml.safe_load(FILE)


def _put(keys, value):
    """Set (None: remove) the scene's key at `keys`."""
    return drop(["scene", *keys]) if value is None else put(["scene", *keys], value)


CUBE = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (0.2, 0.2, 0.2), (0.3, 0.2, 0.2),
        (0.2, 0.3, 0.2), (0.2, 0.2, 0.3), (0.5, 0.5, 0.0)]
TWO = [[0, 1, 2, 3], [1, 2, 3, 4]]                       # two tetrahedra sharing a face


def _tets(groups):
    return lambda folder: write_tets(folder / "block.msh", CUBE, groups)


BAD_FILES = [
    (lambda folder: (folder / "block.msh").write_text("not a mesh\n"), "scene.mesh.file", "gmsh cannot read"),
    (lambda folder: write_block_msh(folder / "block.msh", order=2), "scene.mesh.file",
     "holds 'Triangle 6' elements; only 4-node tetrahedra (3D) and 3-node triangles (2D)"),
    (_tets({"a": (3, TWO + [[0, 1, 2, 9]])}), "scene.mesh.file", "1 degenerate tetrahedron(s) (zero volume)"),
    (_tets({"a": (3, TWO), "b": (3, [[5, 6, 7, 8]])}), "scene.mesh.file",
     "groups 'a' and 'b' overlap (a cell of 'b' at (0.225, 0.225, 0.225) lies inside 'a')"),
    (_tets({"a": (3, TWO + [[3, 2, 1, 0]])}), "scene.mesh.file", "the tetrahedra of group 'a' overlap each other"),
    (_tets({"a": (2, [[0, 1, 2]])}), "scene.mesh.file", "no 3D physical group with tetrahedra"),
    (_tets({"a": (3, [[0, 1, 2, 3, 4, 5]])}), "scene.mesh.file", "holds 'Prism 6' elements"),
    (_tets({"a": (3, [list(range(10))])}), "scene.mesh.file", "holds 'Tetrahedron 10' elements"),
]


@pytest.mark.parametrize("write, path, words", BAD_FILES, ids=[f"file-{i}" for i in range(len(BAD_FILES))])
def test_a_bad_file_is_exit_2_naming_it(tmp_path, write, path, words):
    write(tmp_path)
    study = tmp_path / "study.yaml"
    d = _doc()
    d["scene"]["bodies"] = {"a": {"regions": [{"material": "stiff"}]}}
    for key in ("boundaries", "supports", "loads", "contacts", "regions_of_interest"):
        d["scene"].pop(key)
    d.pop("criteria")
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    code, _, err = run(["check", str(study), "--quiet"])
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"error: {study}: {path}: {tmp_path / 'block.msh'}: ") and words in line, line


BAD = [
    (_put(["mesh", "file"], "nothere.msh"), "scene.mesh.file", "nothere.msh' not found (looked for"),
    (_put(["mesh", "size"], 0.1), "scene.mesh", "a mesh `file` is used as it is"),
    (_put(["bodies", "lid"], {"regions": [{"material": "soft"}]}), "scene.bodies.lid",
     "no 3D physical group 'lid' or 'lid:REGION' in block.msh"),
    (_put(["bodies", "block"], None), "scene.bodies", "the mesh file has body 'block'"),
    (_put(["bodies", "base", "regions", 0, "name"], "cap"), "scene.bodies.base.regions.0.name",
     "no 3D physical group 'base:cap'"),
    (_put(["bodies", "base", "regions"], [{"material": "stiff", "name": "lower"}]), "scene.bodies.base.regions",
     "region 'upper' of body 'base' in block.msh has no material"),
    (_put(["bodies", "block", "regions", 0, "shape"], {"box": BLOCK}), "scene.bodies.block.regions.0.shape",
     "drop `shape`"),
    (_put(["bodies", "block", "mesh"], {"size": 0.1}), "scene.bodies.block.mesh", "cannot have its own mesh sizes"),
    (_put(["contacts", "interface", "slave"], "block_side"), "scene.contacts.interface.slave",
     "unknown boundary 'block_side'"),
    (_put(["boundaries", "block_top"], {"plane": {"point": [0, 0, 0.4], "normal": [0, 0, 1]}}),
     "scene.boundaries.block_top", "'block_top' is also a 2D physical group of block.msh"),
    (_put(["boundaries", "base_side", "body"], "block"), "scene.boundaries.base_side",
     "the plane selector selects no boundary face of body 'block'"),
    (_put(["regions_of_interest", "core"], {"ball": {"center": [0.5, 0.5, -0.25], "radius": 0.2}}),
     "scene.regions_of_interest.core.ball", "cannot be cut from the cells of a mesh file"),
]


@pytest.mark.parametrize("change, path, words", BAD, ids=[b[1].split("scene.")[-1] + f"-{i}" for i, b in enumerate(BAD)])
def test_a_bad_study_on_a_file_is_exit_2_at_its_key_path(block_file, tmp_path, change, path, words):
    d = _doc()
    change(d)
    d["scene"]["mesh"]["file"] = str(block_file / d["scene"]["mesh"]["file"])
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    code, _, err = run(["check", str(study), "--quiet"])
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"error: {study}: ") and f"{path}: " in line and words in line, line


def test_a_face_group_off_the_boundary_is_exit_2(tmp_path):
    """The face between the two tetrahedra is inside the body; `b:top` names a face of body a."""
    for groups, words in [({"a": (3, TWO), "inner": (2, [[1, 2, 3]])}, "2D physical group 'inner' lies on no boundary face"),
                          ({"a": (3, TWO[:1]), "b": (3, TWO[1:]), "b:top": (2, [[0, 1, 2]])},
                           "2D physical group 'b:top' lies on no boundary face of body 'b'")]:
        write_tets(tmp_path / "m.msh", CUBE, groups)
        bodies = {g: {"regions": [{"material": "s"}]} for g, (dim, _) in groups.items() if dim == 3}
        study = tmp_path / "s.yaml"
        study.write_text(yaml.safe_dump({"scene": {"dimension": 3, "mesh": {"file": "m.msh"},
                                                   "materials": {"s": {"E": 1.0e9, "nu": 0.3}}, "bodies": bodies}}))
        code, _, err = run(["check", str(study), "--quiet"])
        line = err.strip().splitlines()[-1]
        assert code == 2 and line.startswith(f"error: {tmp_path / 'm.msh'}: scene.boundaries.") and words in line, line


def test_mutated_file_studies_never_fail_inside(block_file):
    """Seeded mutations (those of tests/acceptance/test_fuzz_check.py) of the study on the file: every
    check is exit 2 (a bad input, or a good 3D study that cannot be solved yet), never an
    internal failure."""
    rng = random.Random(13)
    for i in range(25):
        d = copy.deepcopy(_doc())
        what = mutate(d, rng)
        path = block_file / f"m{i}.yaml"
        path.write_text(yaml.safe_dump(d, sort_keys=False))
        code, _, err = run(["check", str(path), "--quiet"])
        assert code == 2 and "internal failure" not in err and "Traceback" not in err, (what, err)


def _cube_tets(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit cube in n³ cubes of 6 tetrahedra each (Kuhn's split about the diagonal 0-6)."""
    x = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3) / n
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(n)] * 3, indexing="ij"))
    v = [((i + a) * (n + 1) + j + b) * (n + 1) + k + c
         for a, b, c in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]]
    split = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
    return x, np.concatenate([np.stack([v[a] for a in t], 1) for t in split])


def test_the_overlap_check_holds_its_candidate_pairs_a_small_batch_at_a_time():
    """The overlap check of 24,576 tetrahedra allocates under 30 MB at its peak (tracemalloc; the
    per-cell arrays take 5 MB, a batch of candidate pairs and the runs of cells of a block of
    queries (`wcs.geometry.near`) a few MB): with all of them in one batch it took 101 MB here,
    and 0.99 GB, the peak of the whole `wcs solve`, at the patch's face 0.01."""
    import tracemalloc
    from types import SimpleNamespace
    from wcs.scene.meshfile import _check_overlap3d
    x, cells = _cube_tets(16)
    tracemalloc.start()
    try:
        _check_overlap3d(SimpleNamespace(x=x, cells=cells))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(cells) == 24576 and peak < 30e6


@pytest.mark.parametrize("pairs", [None, 7])
def test_the_overlap_check_names_the_first_overlap_of_several(pairs, monkeypatch):
    """Of several overlaps the check names the first tetrahedron (by index) holding another's
    centroid, and the first centroid in it, whatever order its candidate pairs come in (by
    classes of size, the small cells first; in batches of 7 pairs): brute force over all pairs
    of a cube of 384 tetrahedra (group 'a') with halved copies of cells 300 and 50 (cells 384 in
    group 'c' and 385 in group 'b', each inside its original and holding its centroid)."""
    from types import SimpleNamespace

    from wcs.errors import StudyError
    from wcs.geometry import near
    from wcs.scene.meshfile import INSIDE_TOL, _at, _check_overlap3d
    if pairs:
        monkeypatch.setattr(near, "PAIRS", pairs)
    x, cells = _cube_tets(4)
    halves = [0.5 * x[cells[c]] + 0.5 * x[cells[c]].mean(axis=0) for c in (300, 50)]
    cells = np.concatenate([cells, len(x) + np.arange(8).reshape(2, 4)])
    x = np.concatenate([x, *halves])
    corners = x[cells]
    cent = corners.mean(axis=1)
    inv = np.linalg.inv(np.transpose(corners[:, 1:] - corners[:, :1], (0, 2, 1)))
    lam = np.einsum("oab,oib->oia", inv, cent[None, :, :] - corners[:, None, 0, :])    # (outer, inner, 3)
    inside = (lam > INSIDE_TOL).all(axis=2) & (lam.sum(axis=2) < 1 - INSIDE_TOL)
    np.fill_diagonal(inside, False)
    assert sorted(zip(*np.nonzero(inside))) == [(50, 385), (300, 384), (384, 300), (385, 50)]
    raw = SimpleNamespace(x=x, cells=cells, cell_group=np.r_[np.zeros(384, int), 2, 1], groups=["a", "b", "c"],
                          file="cube.msh")
    with pytest.raises(StudyError) as e:
        _check_overlap3d(raw)
    assert f"groups 'a' and 'b' overlap (a cell of 'b' at {_at(cent[385])} lies inside 'a')" in str(e.value)
