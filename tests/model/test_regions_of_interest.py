"""Regions of interest are integrated exactly and refused when they mean nothing: a
contact-pressure region on either side of an open contact, a boundary region that
is a 1D group of a mesh file, means over exactly G_r, and a point X_r off the boundary or at
a corner."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from wcs.errors import StudyError
from wcs.model.evaluation import Evaluator
from wcs import load_study

STUDIES = Path(__file__).resolve().parents[2] / "studies"

E, NU, P = 2.0e9, 0.3, 1.0e7              # the confined block: Young's modulus, Poisson, top pressure
BOX = [0.37, 0.21, 1.53, 0.62]             # interior box, cut by no mesh line of its own
POLYGON = [[0.2, 0.1], [1.7, 0.2], [1.1, 0.5], [1.6, 0.85], [0.3, 0.7]]   # non-convex


def _values(study) -> dict:
    ev = Evaluator(study)
    e = ev.evaluate(study.nominal())
    assert e.status == 0, e.message
    return ev, e.phi


def _block(mesh: dict, rois: dict, criteria: list) -> dict:
    """A block [0, 2] x [0, 1] on rollers (bottom, left) under a top pressure, right side free:
    uniform plane-strain stress σ_yy = −P, σ_xx = 0, so u = (ε_xx x, ε_yy y) is linear (P1 exact)."""
    scene = {"plane": "strain", "mesh": mesh, "materials": {"m": {"E": E, "nu": NU}},
             "bodies": {"block": {"regions": [{"material": "m"}]}},
             "boundaries": {}, "supports": {"bottom": {"u": [None, 0.0]}, "left": {"u": [0.0, None]}},
             "loads": {"top": {"pressure": P}}, "regions_of_interest": rois}
    if "file" not in mesh:
        scene["bodies"]["block"]["regions"][0]["shape"] = {"rectangle": [0.0, 0.0, 2.0, 1.0]}
        scene["boundaries"] = {"bottom": {"segment": [[0, 0], [2, 0]]}, "left": {"segment": [[0, 0], [0, 1]]},
                               "top": {"segment": [[0, 1], [2, 1]]}}
    return {"study": "block", "scene": scene, "uncertain": {"materials.m.E": [0.9 * E, 1.1 * E]},
            "criteria": criteria}


EPS_XX, EPS_YY = NU * (1 + NU) * P / E, -(1 - NU ** 2) * P / E


def _polygon_centroid(pts):
    x, y = np.asarray(pts, float).T
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    w = x * yn - xn * y
    a = w.sum() / 2
    return ((x + xn) * w).sum() / (6 * a), ((y + yn) * w).sum() / (6 * a)


MEANS = [{"name": "down", "kind": "mean_normal_displacement", "regions": ["box"], "direction": [0.0, -1.0]},
         {"name": "side", "kind": "mean_normal_displacement", "regions": ["poly"], "direction": [1.0, 0.0]},
         {"name": "top", "kind": "mean_normal_displacement", "regions": ["box"], "point": [1.0, 1.0]}]
EXACT = {"down": -EPS_YY * (BOX[1] + BOX[3]) / 2, "side": EPS_XX * _polygon_centroid(POLYGON)[0],
         "top": EPS_YY * (BOX[1] + BOX[3]) / 2}


def test_means_over_an_interior_box_and_polygon_are_exact():
    """P1 reproduces the linear field exactly, so the means over G_r are exact: the box and the
    polygon are embedded in the mesh (before: whole cells by centroid, 'down' 6.6 % off)."""
    study = load_study(_block({"size": 0.3}, {"box": {"box": BOX}, "poly": {"polygon": POLYGON}}, MEANS))
    _, phi = _values(study)
    for name, exact in EXACT.items():
        assert phi[name] == pytest.approx(exact, rel=1e-10), name


def _grid_msh(path: Path, nx=8, ny=4):
    """A structured triangulation of [0, 2] x [0, 1] as gmsh 2.2 ASCII: 2D group `block`,
    1D groups `bottom`, `left`, `top`."""
    xs, ys = np.linspace(0, 2, nx + 1), np.linspace(0, 1, ny + 1)
    node = lambda i, j: j * (nx + 1) + i + 1  # noqa: E731
    els = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)
            els += [(2, 1, [a, b, c]), (2, 1, [a, c, d])]
    els += [(1, 2, [node(i, 0), node(i + 1, 0)]) for i in range(nx)]
    els += [(1, 3, [node(0, j), node(0, j + 1)]) for j in range(ny)]
    els += [(1, 4, [node(i, ny), node(i + 1, ny)]) for i in range(nx)]
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", "4",
           '2 1 "block"', '1 2 "bottom"', '1 3 "left"', '1 4 "top"', "$EndPhysicalNames",
           "$Nodes", str((nx + 1) * (ny + 1))]
    out += [f"{node(i, j)} {xs[i]} {ys[j]} 0" for j in range(ny + 1) for i in range(nx + 1)]
    out += ["$EndNodes", "$Elements", str(len(els))]
    out += [f"{k + 1} {t} 2 {g} {g} " + " ".join(map(str, ns)) for k, (t, g, ns) in enumerate(els)]
    path.write_text("\n".join(out + ["$EndElements"]) + "\n")


def test_means_on_a_mesh_file_cut_the_cells_exactly(tmp_path):
    """A mesh file cannot embed G_r: the box and the polygon cut its cells exactly; a disc is
    refused (exit 2 at its key path)."""
    _grid_msh(tmp_path / "grid.msh")
    rois = {"box": {"box": BOX}, "poly": {"polygon": POLYGON}}
    _, phi = _values(load_study(_block({"file": "grid.msh"}, rois, MEANS), base_dir=tmp_path))
    for name, exact in EXACT.items():
        assert phi[name] == pytest.approx(exact, rel=1e-10), name
    disc = _block({"file": "grid.msh"}, {"d": {"disc": {"center": [1.0, 0.5], "radius": 0.3}}},
                  [{"name": "t", "kind": "mean_normal_displacement", "regions": ["d"], "direction": [0, 1]}])
    with pytest.raises(StudyError, match="disc cannot be cut") as e:
        Evaluator(load_study(disc, base_dir=tmp_path))
    assert e.value.path == "scene.regions_of_interest.d.disc"


@pytest.mark.parametrize("point, why", [([2.0, 1.0], "corner"), ([1.0, 51.0], "not on the boundary")])
def test_a_point_at_a_corner_or_off_the_body_is_refused(point, why):
    crit = [{"name": "top", "kind": "mean_normal_displacement", "regions": ["box"], "point": point}]
    study = load_study(_block({"size": 0.3}, {"box": {"box": BOX}}, crit))
    with pytest.raises(StudyError, match=why) as e:
        Evaluator(study)
    assert e.value.path == "criteria.0.point"


# ---------------------------------------------------------------- an initial gap

GAP, DOWN = 0.002, 0.003                     # initial gap; prescribed descent of the block top
EB, NUB, ES, NUS = 1.0e9, 0.3, 1.0e10, 0.25  # block, base


def test_contact_pressure_on_either_side_of_a_closing_gap():
    """A block 2 mm above a base of the same width is pushed down 3 mm: the gap closes and both
    are compressed uniformly, σ_yy = −p with (1 − ν²) p / E summed over the heights = 1 mm.
    Φ6 over a region on the master side (apart from the slave nodes) takes the same rows as on
    the slave side (before: 'holds no contact node')."""
    hb = 1.5 - (1.0 + GAP)
    doc = {"study": "gap", "scene": {
        "plane": "strain", "mesh": {"size": 0.1},
        "materials": {"block": {"E": EB, "nu": NUB}, "base": {"E": ES, "nu": NUS}},
        "bodies": {"base": {"regions": [{"material": "base", "shape": {"rectangle": [0.5, 0.0, 1.5, 1.0]}}]},
                   "block": {"regions": [{"material": "block", "shape": {"rectangle": [0.5, 1.0 + GAP, 1.5, 1.5]}}]}},
        "boundaries": {"base_bottom": {"segment": [[0.5, 0.0], [1.5, 0.0]]},
                       "base_left": {"body": "base", "segment": [[0.5, 0.0], [0.5, 1.0]]},
                       "block_left": {"body": "block", "segment": [[0.5, 1.0 + GAP], [0.5, 1.5]]},
                       "base_top": {"body": "base", "segment": [[0.5, 1.0], [1.5, 1.0]]},
                       "block_bottom": {"body": "block", "segment": [[0.5, 1.0 + GAP], [1.5, 1.0 + GAP]]},
                       "block_top": {"body": "block", "segment": [[0.5, 1.5], [1.5, 1.5]]}},
        "supports": {"base_bottom": {"u": [None, 0.0]}, "base_left": {"normal": 0.0},
                     "block_left": {"normal": 0.0}, "block_top": {"u": [None, -DOWN]}},
        "contacts": {"touch": {"slave": "block_bottom", "master": "base_top"}},
        "regions_of_interest": {"master_box": {"box": [0.5, 0.9, 1.5, 1.0]},
                                "slave_box": {"box": [0.5, 1.0 + GAP, 1.5, 1.1]},
                                "master_side": {"boundary": "base_top"},
                                "slave_side": {"boundary": "block_bottom"}}},
        "uncertain": {"materials.block.E": [0.8 * EB, 1.2 * EB]},
        "criteria": [{"name": r, "kind": "contact_pressure", "regions": [r]}
                     for r in ("master_box", "slave_box", "master_side", "slave_side")]}
    ev, phi = _values(load_study(doc))
    masks = [c.contact_masks[0] for c in ev.criteria]
    assert all(np.array_equal(m, masks[0]) for m in masks) and masks[0].all()
    p = (DOWN - GAP) / (hb * (1 - NUB ** 2) / EB + 1.0 * (1 - NUS ** 2) / ES)
    for name, value in phi.items():
        assert value == pytest.approx(p, rel=1e-9), name


# ---------------------------------------------------------------- a 1D group as G_r


def test_boundary_region_of_a_mesh_file_group():
    """`boundary: base_top` where base_top is a 1D group of the mesh file gives the criteria of
    the same curve chosen by a segment; the mean pressure under the pad is its load, 2 MPa."""
    doc = yaml.safe_load((STUDIES / "user-mesh-demo.yaml").read_text())
    sc = doc["scene"]
    sc["mesh"]["file"] = str(STUDIES / "meshes" / "two-blocks.msh")
    sc["boundaries"]["top_by_segment"] = {"body": "base", "segment": [[0.5, 1.0], [1.5, 1.0]]}
    sc["regions_of_interest"] |= {"by_group": {"boundary": "base_top"}, "by_segment": {"boundary": "top_by_segment"}}
    doc["criteria"] = [{"name": f"{k}_{r}", "kind": k, "regions": [r]} for r in ("by_group", "by_segment")
                       for k in ("contact_pressure", "mean_normal_displacement", "shear_stress_intensity")]
    doc.pop("limits")
    _, phi = _values(load_study(doc))
    for k in ("contact_pressure", "mean_normal_displacement", "shear_stress_intensity"):
        assert phi[f"{k}_by_group"] == pytest.approx(phi[f"{k}_by_segment"], rel=1e-14), k
    assert phi["contact_pressure_by_group"] == pytest.approx(float(sc["loads"]["pad_top"]["pressure"]), rel=1e-9)
