"""A .msh read by meshio (`wcs.scene.meshfile._read_msh`) is what gmsh reads (`_read_gmsh`):
the same nodes in the same order and the same groups, each with the same elements in the
same order, on the shipped mesh, the test files of tests/scene and the Kratos bench's meshes
(MSH 2.2, the contact face in two groups of one entity); a file the meshio reader leaves to
gmsh (other versions, higher-order cells, unnamed groups, sparse
node tags) says so by None."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import gmsh
import numpy as np
import pytest

from tests.scene.test_meshfile import ELEMENTS, GROUPS, NODES, write_msh, write_msh41
from tests.scene.test_meshfile_3d import CUBE, TWO, write_block_msh, write_tets
from wcs.scene.meshfile import KINDS, _read_gmsh, _read_msh
from wcs.scene.session import Session

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("kratos_mesh", ROOT / "tests" / "bench" / "kratos_mesh.py")
kratos_mesh = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(kratos_mesh)


def write_msh22(path, nodes, elements, names):
    """MSH 2.2 ASCII with elementary tags apart from the physical ones: elements [(type,
    physical, elementary, [1-based nodes])], names {physical: (dim, name)}; node i tagged 10 i."""
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(names))]
    out += [f'{d} {t} "{n}"' for t, (d, n) in names.items()]
    out += ["$EndPhysicalNames", "$Nodes", str(len(nodes))]
    out += [f"{10 * (i + 1)} {x} {y} 0" for i, (x, y) in enumerate(nodes)]
    out += ["$EndNodes", "$Elements", str(len(elements))]
    out += [f"{i + 1} {t} 2 {p} {e} " + " ".join(str(10 * n) for n in ns) for i, (t, p, e, ns) in enumerate(elements)]
    Path(path).write_text("\n".join(out + ["$EndElements"]) + "\n")


# two entities of triangles, elements out of entity order, a line entity in two groups (written twice)
SHUFFLED = [(1, 4, 7, [2, 3]), (2, 2, 2, [2, 6, 3]), (1, 3, 8, [2, 5]), (2, 1, 1, [1, 3, 4]), (1, 5, 7, [2, 3]),
            (2, 1, 1, [1, 2, 3]), (1, 3, 8, [1, 2]), (2, 2, 2, [2, 5, 6])]
SHUFFLED_NAMES = {1: (2, "left"), 2: (2, "right"), 3: (1, "bottom"), 4: (1, "left:side"), 5: (1, "right:side")}


def unnamed_groups(path):
    with Session():
        tag = gmsh.model.addDiscreteEntity(3)
        gmsh.model.mesh.addNodes(3, tag, list(range(1, len(CUBE) + 1)), np.ravel(CUBE).tolist())
        gmsh.model.mesh.addElementsByType(tag, 4, [], (np.asarray(TWO) + 1).ravel().tolist())
        gmsh.model.addPhysicalGroup(3, [tag])
        gmsh.write(str(path))


FILES = {   # name -> (writer, dimension, read by meshio)
    "shipped": (lambda p: p.write_bytes((ROOT / "studies" / "meshes" / "two-blocks.msh").read_bytes()), 2, True),
    "2.2": (lambda p: write_msh(p, NODES, GROUPS, ELEMENTS), 2, True),
    "2.2-shuffled": (lambda p: write_msh22(p, NODES, SHUFFLED, SHUFFLED_NAMES), 2, True),
    "4.1-sparse-tags": (lambda p: write_msh41(p, NODES, GROUPS, ELEMENTS, tags=[7, 2, 10**12, 4, 3, 999_999_999_999]),
                        2, False),         # meshio would index the tags by an array of 1e12
    "4.1-occ": (lambda p: write_block_msh(p), 3, True),
    "4.1-order-2": (lambda p: write_block_msh(p, order=2), 3, False),
    "4.1-tets": (lambda p: write_tets(p, CUBE, {"a": (3, TWO), "b": (3, [[5, 6, 7, 8]]), "a:top": (2, [[1, 2, 3]])}),
                 3, True),
    "4.1-unnamed": (unnamed_groups, 3, False),
    "2.2-patch": (lambda p: kratos_mesh.write_patch_msh(p, 0.25), 3, True),
    "2.2-hertz": (lambda p: kratos_mesh.write_hertz_msh(p, 0.05), 3, True),
}


@pytest.mark.parametrize("name", list(FILES))
def test_meshio_reads_what_gmsh_reads(tmp_path, name):
    write, dim, by_meshio = FILES[name]
    path = tmp_path / "m.msh"
    write(path)
    kind = KINDS[dim]
    read = _read_msh(path, kind)
    assert (read is not None) == by_meshio
    if read is None:
        return
    (x, groups), (gx, ggroups) = read, _read_gmsh(path, kind)
    assert np.array_equal(x, gx)
    assert [(n, d) for n, d, _ in groups] == [(n, d) for n, d, _ in ggroups]
    for (n, _, c), (_, _, gc) in zip(groups, ggroups):
        assert c.dtype == gc.dtype and np.array_equal(c, gc), n


@pytest.mark.parametrize("kind", ["tri", "tet"])
def test_facets_made_by_keys_are_scikit_fems(kind):
    """A mesh file's facets and cell-to-facet map, made from one int64 key a facet, are the
    arrays scikit-fem's `build_entities` makes (values, dtypes, shapes), cells in any order."""
    from skfem import MeshTet, MeshTri
    from wcs.scene.meshfile import made_facets
    m = MeshTet().refined(2) if kind == "tet" else MeshTri().refined(3)
    t = m.t[:, np.random.default_rng(1).permutation(m.t.shape[1])]
    ours, theirs = type(m)(m.p, t, sort_t=False), type(m)(m.p, t, sort_t=False)
    made_facets(ours)
    for a, b in ((ours._facets, theirs.facets), (ours._t2f, theirs.t2f)):
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


def test_rows_in_by_keys_and_by_rows_agree(monkeypatch):
    """Which sorted rows of a are rows of b: by int64 keys, and by np.unique over rows where
    the keys would not fit (`_row_keys` None), the same answer, rows of b beyond a's indices too."""
    from wcs.scene import meshfile
    rng = np.random.default_rng(2)
    a = np.sort(rng.integers(0, 40, (500, 3)), axis=1)
    b = np.r_[a[rng.random(500) < 0.3], np.sort(rng.integers(0, 60, (50, 3)), axis=1)]
    expected = np.array([tuple(r) in set(map(tuple, b)) for r in a])
    assert 0 < expected.sum() < len(a)
    assert np.array_equal(meshfile._rows_in(a, b), expected)
    monkeypatch.setattr(meshfile, "_row_keys", lambda rows: None)
    assert np.array_equal(meshfile._rows_in(a, b), expected)


def _msh22_text(tmp_path) -> str:
    write_msh22(tmp_path / "clean.msh", NODES, SHUFFLED, SHUFFLED_NAMES)
    return (tmp_path / "clean.msh").read_text()


def _element_line(text: str, i: int) -> str:
    return text.split("$Elements\n")[1].splitlines()[1 + i]


MALFORMED = {   # a mutation of a valid MSH 2.2 file -> its text; each is left to gmsh (None)
    "three tags": lambda t: t.replace(_element_line(t, 1), _element_line(t, 1).replace(" 2 2 2 ", " 2 3 2 2 2 ", 1)),
    "a node short": lambda t: t.replace(_element_line(t, 1), _element_line(t, 1).rsplit(" ", 1)[0]),
    "a node too many": lambda t: t.replace(_element_line(t, 1), _element_line(t, 1) + " 10"),
    "blank line among the elements": lambda t: t.replace(_element_line(t, 2) + "\n", _element_line(t, 2) + "\n\n"),
    "not a number": lambda t: t.replace(_element_line(t, 3), _element_line(t, 3)[:-1] + "x"),
    "a fraction for a node": lambda t: t.replace(_element_line(t, 3), _element_line(t, 3) + ".5"),
    "more elements counted": lambda t: t.replace(f"$Elements\n{len(SHUFFLED)}\n", f"$Elements\n{len(SHUFFLED) + 1}\n"),
    "fewer nodes counted": lambda t: t.replace(f"$Nodes\n{len(NODES)}\n", f"$Nodes\n{len(NODES) - 1}\n"),
    "a quadrangle": lambda t: t.replace(_element_line(t, 1), _element_line(t, 1).replace(" 2 2 2 ", " 3 2 2 2 ", 1)
                                        + " 10"),
    "no elements": lambda t: t.split("$Elements")[0] + "$Elements\n0\n$EndElements\n",
}

HARMLESS = {    # the same file written otherwise -> the clean file's read
    "CRLF line ends": lambda t: t.replace("\n", "\r\n"),
    "spaces and tabs": lambda t: t.replace(" ", " \t "),
    "blank lines before the ends": lambda t: t.replace("$EndElements", "\n\n$EndElements").replace("$EndNodes",
                                                                                                    "\n$EndNodes"),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_a_malformed_msh22_file_is_left_to_gmsh(tmp_path, name):
    """The MSH 2.2 reader's numbers come from numpy's parse of whole sections: a line it cannot
    place (a tag count other than 2, a node short or too many, a gap, a word, a count that does
    not match, an unsupported cell) makes it say None, and gmsh reads the file with its message."""
    from wcs.scene.meshfile import _read_msh22
    text = MALFORMED[name](_msh22_text(tmp_path))
    assert text != _msh22_text(tmp_path)
    (tmp_path / "m.msh").write_text(text)
    assert _read_msh22(tmp_path / "m.msh") is None


@pytest.mark.parametrize("name", list(HARMLESS))
def test_an_msh22_file_written_otherwise_reads_the_same(tmp_path, name):
    from wcs.scene.meshfile import _read_msh22
    text = _msh22_text(tmp_path)
    clean = _read_msh22(tmp_path / "clean.msh")
    (tmp_path / "m.msh").write_bytes(HARMLESS[name](text).encode())
    other = _read_msh22(tmp_path / "m.msh")
    assert clean is not None and other is not None
    assert np.array_equal(clean[0], other[0]) and clean[1] == other[1] and clean[3] == other[3]
    assert len(clean[2]) == len(other[2])
    for a, b in zip(clean[2], other[2]):
        assert a[:2] == b[:2] and np.array_equal(a[2], b[2]) and np.array_equal(a[3], b[3])
