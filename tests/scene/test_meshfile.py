"""Scenes from the user's own mesh file (`scene.mesh: {file: ...}`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from wcs.cli import main
from wcs.errors import StudyError
from wcs.scene import meshfile
from wcs.scene.mesher2d import build_mesh
from wcs.scene.spec import GroupBoundary
from wcs import load_study

STUDIES = Path(__file__).resolve().parents[2] / "studies"
DEMO = STUDIES / "user-mesh-demo.yaml"


# ---------------------------------------------------------------- the demo


def test_demo_bodies_regions_boundaries_come_from_the_groups():
    study = load_study(DEMO)
    sm = build_mesh(study.scene)
    assert sm.bodies == ["base", "pad"]
    assert sm.regions == [("base", "lower"), ("base", "upper"), ("pad", "pad")]
    assert {"base_bottom", "pad_top", "pad_left", "base_top", "pad_bottom", "base_right"} <= set(sm.boundaries)
    p, f = sm.mesh.p, sm.mesh.facets
    # region split at y = 0.5; pad above y = 1
    c = p[:, sm.mesh.t].mean(axis=1)
    assert np.all(c[1, sm.cell_region == 0] < 0.5) and np.all(c[1, sm.cell_region == 1] > 0.5)
    assert np.all(c[1, sm.cell_body == 1] > 1.0)
    # the two sides of the contact: same curve, one body each, own nodes
    nb = sm.node_body
    top, bot = sm.boundaries["base_top"], sm.boundaries["pad_bottom"]
    assert len(top) == len(bot) > 0
    assert set(nb[f[:, top].ravel()]) == {0} and set(nb[f[:, bot].ravel()]) == {1}
    assert np.allclose(p[1, f[:, top]], 1.0) and np.allclose(p[1, f[:, bot]], 1.0)
    assert not set(f[:, top].ravel()) & set(f[:, bot].ravel())
    # regions of one body are glued: nodes on y = 0.5 are shared by both regions
    lower_nodes = set(sm.mesh.t[:, sm.cell_region == 0].ravel())
    upper_nodes = set(sm.mesh.t[:, sm.cell_region == 1].ravel())
    assert len(lower_nodes & upper_nodes) > 10
    # a geometric selector still works on the file's mesh
    assert np.allclose(p[0, f[:, sm.boundaries["base_right"]]], 2.0)
    # counter-clockwise cells
    t = sm.mesh.t
    d1, d2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    assert np.all(d1[0] * d2[1] - d1[1] * d2[0] > 0)


def test_demo_mesh_is_what_the_script_writes(tmp_path):
    import importlib.util
    spec = importlib.util.spec_from_file_location("mk", STUDIES / "meshes" / "make_user_mesh_demo.py")
    mk = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mk)
    mk.main(tmp_path / "two-blocks.msh")
    study = yaml.safe_load(DEMO.read_text())
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(study).replace("meshes/two-blocks.msh", "two-blocks.msh"))
    a = build_mesh(load_study(tmp_path / "s.yaml").scene)
    b = build_mesh(load_study(DEMO).scene)
    assert a.mesh.p.shape == b.mesh.p.shape and a.mesh.t.shape == b.mesh.t.shape


# ---------------------------------------------------------------- small hand-written files


def write_msh(path, nodes, groups, elements):
    """gmsh 2.2 ASCII. nodes [(x, y)], groups {name: (dim, tag)}, elements [(type, tag, [1-based nodes])]."""
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(groups))]
    out += [f'{d} {t} "{n}"' for n, (d, t) in groups.items()]
    out += ["$EndPhysicalNames", "$Nodes", str(len(nodes))]
    out += [f"{i + 1} {x} {y} 0" for i, (x, y) in enumerate(nodes)]
    out += ["$EndNodes", "$Elements", str(len(elements))]
    out += [f"{i + 1} {t} 2 {g} {g} " + " ".join(map(str, ns)) for i, (t, g, ns) in enumerate(elements)]
    out += ["$EndElements"]
    Path(path).write_text("\n".join(out) + "\n")


def write_msh41(path, nodes, groups, elements, tags):
    """gmsh 4.1 ASCII (64-bit node tags; 2.2 reads them as 32-bit): one entity per physical group,
    tagged as the group, all nodes on the first surface; node i (1-based) written with tag tags[i - 1]."""
    curves = [(n, t) for n, (d, t) in groups.items() if d == 1]
    surfaces = [(n, t) for n, (d, t) in groups.items() if d == 2]
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(groups))]
    out += [f'{d} {t} "{n}"' for n, (d, t) in groups.items()]
    out += ["$EndPhysicalNames", "$Entities", f"0 {len(curves)} {len(surfaces)} 0"]
    out += [f"{t} 0 0 0 0 0 0 1 {t} 0" for _, t in curves + surfaces]
    out += ["$EndEntities", "$Nodes", f"1 {len(nodes)} {min(tags)} {max(tags)}",
            f"2 {surfaces[0][1]} 0 {len(nodes)}"]
    out += [str(t) for t in tags] + [f"{x} {y} 0" for x, y in nodes]
    out += ["$EndNodes", "$Elements", f"{len(groups)} {len(elements)} 1 {len(elements)}"]
    for name, (d, g) in groups.items():
        mine = [(k + 1, typ, ns) for k, (typ, gg, ns) in enumerate(elements) if gg == g]
        out += [f"{d} {g} {mine[0][1]} {len(mine)}"] + [f"{k} " + " ".join(str(tags[n - 1]) for n in ns)
                                                      for k, _, ns in mine]
    out += ["$EndElements"]
    Path(path).write_text("\n".join(out) + "\n")


NODES = [(0, 0), (1, 0), (1, 1), (0, 1), (2, 0), (2, 1)]
GROUPS = {"left": (2, 1), "right": (2, 2), "bottom": (1, 3), "left:side": (1, 4), "right:side": (1, 5)}
ELEMENTS = [(2, 1, [1, 2, 3]), (2, 1, [1, 3, 4]), (2, 2, [2, 5, 6]), (2, 2, [2, 6, 3]),
            (1, 3, [1, 2]), (1, 3, [2, 5]), (1, 4, [2, 3]), (1, 5, [2, 3])]


def study_text(mesh="m.msh", bodies=None, extra=""):
    bodies = bodies or "    left: {regions: [{material: steel}]}\n    right: {regions: [{material: steel}]}\n"
    return f"""study: t
scene:
  mesh: {{file: {mesh}}}
  materials:
    steel: {{E: 2.0e11, nu: 0.3}}
  bodies:
{bodies}  supports:
    bottom: {{u: [0.0, 0.0]}}
  contacts:
    c: {{slave: side_r, master: side_l}}
{extra}"""


def make(tmp_path, nodes=NODES, groups=None, elements=None, **kw):
    groups = dict(GROUPS if groups is None else groups)
    write_msh(tmp_path / "m.msh", nodes, groups, ELEMENTS if elements is None else elements)
    text = study_text(**kw)
    # the contact names the 1D groups `left:side` / `right:side` -> boundaries `side`... rename:
    (tmp_path / "s.yaml").write_text(text)
    return tmp_path / "s.yaml"


GOOD_GROUPS = {"left": (2, 1), "right": (2, 2), "bottom": (1, 3), "left:side_l": (1, 4), "right:side_r": (1, 5)}


def test_small_file_two_bodies_touching(tmp_path):
    path = make(tmp_path, groups=GOOD_GROUPS)
    study = load_study(path)
    assert study.scene.boundaries["side_l"] == GroupBoundary(group="left:side_l", body="left")
    sm = build_mesh(study.scene)
    assert sm.mesh.p.shape[1] == 8                      # nodes 2 and 3 doubled
    assert len(sm.boundaries["bottom"]) == 2
    assert len(sm.boundaries["side_l"]) == len(sm.boundaries["side_r"]) == 1


def test_sparse_node_tags_are_read_as_the_same_mesh(tmp_path):
    """gmsh node tags need not be contiguous: a node tagged 1e12 is valid (before: an index array
    of the largest tag's length, "Unable to allocate 7.28 TiB"). The file reads as the one with
    tags 1..6, node for node."""
    dense = build_mesh(load_study(make(tmp_path, groups=GOOD_GROUPS)).scene)
    sparse_dir = tmp_path / "sparse"
    sparse_dir.mkdir()
    write_msh41(sparse_dir / "m.msh", NODES, GOOD_GROUPS, ELEMENTS, tags=[7, 2, 10**12, 4, 3, 999_999_999_999])
    (sparse_dir / "s.yaml").write_text(study_text())
    sparse = build_mesh(load_study(sparse_dir / "s.yaml").scene)

    def cells(sm):          # every triangle by its corners' coordinates and body (node order aside)
        p, t = sm.mesh.p, sm.mesh.t
        return sorted((sm.cell_body[k], sorted(map(tuple, p[:, t[:, k]].T.tolist()))) for k in range(t.shape[1]))
    assert sparse.mesh.p.shape == dense.mesh.p.shape and cells(sparse) == cells(dense)
    assert {k: len(v) for k, v in sparse.boundaries.items()} == {k: len(v) for k, v in dense.boundaries.items()}


def test_clockwise_triangles_are_reoriented_with_a_note(tmp_path):
    elements = [(2, 1, [1, 3, 2]), (2, 1, [1, 4, 3])] + ELEMENTS[2:]
    study = load_study(make(tmp_path, groups=GOOD_GROUPS, elements=elements))
    assert any("reoriented" in n for n in study.notes)
    sm = build_mesh(study.scene)
    p, t = sm.mesh.p, sm.mesh.t
    d1, d2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    assert np.all(d1[0] * d2[1] - d1[1] * d2[0] > 0)


def run_bad(path, capsys):
    code = main(["check", str(path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    return err


def test_missing_file(tmp_path, capsys):
    (tmp_path / "s.yaml").write_text(study_text(mesh="nothere.msh"))
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert "scene.mesh.file" in err and "not found" in err


def test_unreadable_file(tmp_path, capsys):
    (tmp_path / "m.msh").write_text("this is not a mesh\n")
    (tmp_path / "s.yaml").write_text(study_text())
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert "scene.mesh.file" in err


def test_gmsh_failing_without_a_reason_is_said_so(tmp_path, capsys, monkeypatch):
    """gmsh may raise with an empty last error: the line says it gave none (before: "gmsh cannot
    read the file: " and nothing)."""
    import gmsh

    def merge(name):
        raise Exception("")
    monkeypatch.setattr(gmsh, "merge", merge)
    monkeypatch.setattr(meshfile, "_read_msh", lambda path, kind: None)     # a file meshio leaves to gmsh
    write_msh(tmp_path / "m.msh", NODES, GOOD_GROUPS, ELEMENTS)
    (tmp_path / "s.yaml").write_text(study_text())
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert err == (f"error: {tmp_path / 's.yaml'}: scene.mesh.file: {tmp_path / 'm.msh'}: gmsh cannot read the file "
                   "and gives no reason "
                   "(not a mesh file gmsh parses)\n")


def test_unreadable_other_format(tmp_path, capsys):
    (tmp_path / "m.vtu").write_text("<VTKFile broken")
    (tmp_path / "s.yaml").write_text(study_text(mesh="m.vtu"))
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert "scene.mesh.file" in err


def test_body_missing_in_file(tmp_path, capsys):
    bodies = "    left: {regions: [{material: steel}]}\n    right: {regions: [{material: steel}]}\n" \
             "    femur: {regions: [{material: steel}]}\n"
    err = run_bad(make(tmp_path, groups=GOOD_GROUPS, bodies=bodies), capsys)
    assert "scene.bodies.femur" in err and "no 2D physical group 'femur'" in err


def test_region_missing_in_file(tmp_path, capsys):
    bodies = "    left: {regions: [{name: cap, material: steel}]}\n    right: {regions: [{material: steel}]}\n"
    err = run_bad(make(tmp_path, groups=GOOD_GROUPS, bodies=bodies), capsys)
    assert "scene.bodies.left.regions.0.name" in err


def test_body_of_the_file_not_in_the_study(tmp_path, capsys):
    bodies = "    left: {regions: [{material: steel}]}\n"
    err = run_bad(make(tmp_path, groups=GOOD_GROUPS, bodies=bodies), capsys)
    assert "scene.bodies" in err and "'right'" in err


def test_boundary_group_missing(tmp_path, capsys):
    groups = {"left": (2, 1), "right": (2, 2), "bottom": (1, 3), "left:side_l": (1, 4), "right:other": (1, 5)}
    err = run_bad(make(tmp_path, groups=groups), capsys)
    assert "scene.contacts.c.slave" in err and "side_r" in err


def test_shape_needed_without_file(tmp_path, capsys):
    (tmp_path / "s.yaml").write_text("""scene:
  mesh: {size: 0.1}
  materials: {steel: {E: 2.0e11, nu: 0.3}}
  bodies: {b: {regions: [{material: steel}]}}
""")
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert "scene.bodies.b.regions.0.shape" in err


def test_shape_not_allowed_with_file(tmp_path, capsys):
    bodies = ("    left: {regions: [{material: steel, shape: {rectangle: [0, 0, 1, 1]}}]}\n"
              "    right: {regions: [{material: steel}]}\n")
    err = run_bad(make(tmp_path, groups=GOOD_GROUPS, bodies=bodies), capsys)
    assert "scene.bodies.left.regions.0.shape" in err


def test_degenerate_triangle(tmp_path, capsys):
    nodes = NODES + [(0.5, 0.0)]                       # on the edge 1-2: zero area with 1, 2
    elements = ELEMENTS + [(2, 1, [1, 2, 7])]
    err = run_bad(make(tmp_path, nodes=nodes, groups=GOOD_GROUPS, elements=elements), capsys)
    assert "scene.mesh.file" in err and "degenerate" in err


def test_overlapping_bodies(tmp_path, capsys):
    nodes = NODES + [(0.5, 0.2), (1.5, 0.2), (1.0, 0.8)]   # a triangle of `right` inside `left` and `right`
    elements = ELEMENTS + [(2, 2, [7, 8, 9])]
    err = run_bad(make(tmp_path, nodes=nodes, groups=GOOD_GROUPS, elements=elements), capsys)
    assert "scene.mesh.file" in err and "overlap" in err


def test_unsupported_elements(tmp_path, capsys):
    elements = ELEMENTS[:2] + [(3, 2, [2, 5, 6, 3])] + ELEMENTS[4:]     # a quadrangle
    err = run_bad(make(tmp_path, groups=GOOD_GROUPS, elements=elements), capsys)
    assert "scene.mesh.file" in err and "triangles" in err


def test_group_name_clash(tmp_path, capsys):
    extra = "  boundaries:\n    bottom: {segment: [[0, 0], [2, 0]]}\n"
    text = study_text(extra="").replace("  supports:", extra + "  supports:")
    write_msh(tmp_path / "m.msh", NODES, GOOD_GROUPS, ELEMENTS)
    (tmp_path / "s.yaml").write_text(text)
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert "scene.boundaries.bottom" in err


def test_file_with_size_is_an_error(tmp_path, capsys):
    write_msh(tmp_path / "m.msh", NODES, GOOD_GROUPS, ELEMENTS)
    (tmp_path / "s.yaml").write_text(study_text(mesh="m.msh, size: 0.1"))
    err = run_bad(tmp_path / "s.yaml", capsys)
    assert "scene.mesh" in err


def test_read_mesh_file_errors_name_the_file():
    with pytest.raises(StudyError) as exc:
        from wcs.scene.meshfile import read_mesh_file
        read_mesh_file("/nonexistent/x.msh", {"bodies": {"a": {"regions": [{}]}}})
    assert exc.value.path == "scene.mesh.file" and "x.msh" in str(exc.value)


def test_a_boundary_name_from_the_file_follows_the_rules_for_names(tmp_path, capsys):
    """A 1D group's name becomes a boundary's: an escape character or a name of 200 characters is
    refused at the file as in the study (before: both passed; gmsh itself ends a name at a NUL)."""
    for bad, why in (("side\x1br", "a name may contain printable characters only, got '\\x1b' at position 4"),
                     ("s" * 200, "a name has at most 100 characters, got 200")):
        groups = {**GOOD_GROUPS}
        del groups["right:side_r"]
        groups[f"right:{bad}"] = (1, 5)
        write_msh41(tmp_path / "m.msh", NODES, groups, ELEMENTS, tags=list(range(1, 7)))
        (tmp_path / "s.yaml").write_text(study_text().replace("  contacts:\n    c: {slave: side_r, master: side_l}\n", ""))
        err = run_bad(tmp_path / "s.yaml", capsys)
        assert "scene.mesh.file: m.msh: 1D physical group " in err and err.rstrip().endswith(why), err
