"""Structured mutants of small studies for `wcs check` (and `wcs sweep`), seeded.

A `Mutant` is one edit of a small base study (2D contact, 3D contact with Tresca friction, 2D
glue, 2D and 3D scenes from a `.msh` written here), of one kind: 3D solids, selectors, glue,
refine, mesh files, ranges and fuzzy sets, Lipschitz grids, sweeps, solver options, names,
special files, edge numbers. Each mutant says whether its input is wrong (`expect == "bad"`: the
input is physically or logically wrong, so `wcs` must refuse it, exit 2) or may be either
(`"any"`: exit 0 or 2). `build(folder)` writes the case and gives the command line.

`mutants(count, seed)` draws `count` distinct mutants, the same for the same seed; `FAST` names
a handful that load quickly. Importing this module has no side effects.
"""
from __future__ import annotations

import copy
import functools
import itertools
import math
import os
import random
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import yaml

NAN, INF = float("nan"), float("inf")
EDGE = [0, -1, NAN, INF, -INF, 2**62, 1e-300, True, False, 1e300, -0.0]

# ---------------------------------------------------------------- the bases

B2 = """
study: fuzz-2d
scene:
  dimension: 2
  plane: strain
  mesh: {size: 0.1, max_cells: 20000, refine: [{box: [0.4, 0.9, 1.6, 1.1], size: 0.05}]}
  materials:
    steel: {E: 2.1e11, nu: 0.3, conductivity: 45.0, expansion: 1.2e-5}
    rubber: {E: 1.0e7, nu: 0.4, conductivity: 0.2, expansion: 2.0e-4}
  bodies:
    base: {regions: [{material: steel, shape: {rectangle: [0.0, 0.0, 2.0, 1.0]}}]}
    pad: {regions: [{material: rubber, shape: {rectangle: [0.5, 1.0, 1.5, 1.5]}}]}
  boundaries:
    base_bottom: {body: base, segment: [[0.0, 0.0], [2.0, 0.0]]}
    pad_top:     {body: pad,  segment: [[0.5, 1.5], [1.5, 1.5]]}
    pad_left:    {body: pad,  segment: [[0.5, 1.0], [0.5, 1.5]]}
    base_top:    {body: base, segment: [[0.5, 1.0], [1.5, 1.0]]}
    pad_bottom:  {body: pad,  segment: [[0.5, 1.0], [1.5, 1.0]]}
  supports:
    base_bottom: {u: [0.0, 0.0]}
    pad_left:    {normal: 0.0}
  loads:
    pad_top: {pressure: 2.0e6}
  body_forces:
    base: [0.0, -7.7e4]
  contacts:
    interface: {slave: pad_bottom, master: base_top, friction: {slip_limit: 1.0e5}}
  thermal:
    reference: 293.0
    temperature: {base_bottom: 293.0}
    sources: {pad: 0.0}
  regions_of_interest:
    under_pad: {box: [0.9, 0.9, 1.1, 1.0]}
    pad_edge:  {boundary: pad_left}
uncertain:
  materials.rubber.E:  [0.8e7, 1.2e7]
  materials.rubber.nu: [0.35, 0.42]
  loads.pad_top.pressure: [1.5e6, 2.5e6]
  contacts.interface.friction.slip_limit: {range: [0.5e5, 1.5e5], lipschitz: 2.0e5, points: 6}
criteria:
  - {name: settlement, kind: mean_normal_displacement, regions: [under_pad], point: [1.0, 1.0]}
  - {name: shear, kind: shear_stress_intensity, regions: [under_pad]}
limits:
  shear: 4.0e12
search:
  method: auto
  sample: {design: lhs, n: 8, seed: 7}
  budget: 20
solver: {method: auto, tolerance: 1.0e-8, dd: {subdomains: 2}}
output: out.nc
"""

B3 = """
study: fuzz-3d
scene:
  dimension: 3
  mesh: {size: 0.25, max_cells: 20000}
  materials:
    base: {E: 2.0e+10, nu: 0.2}
    block: {E: 5.0e+9, nu: 0.3}
  bodies:
    base: {regions: [{material: base, shape: {box: [0, 0, -0.5, 1, 1, 0]}}]}
    block: {regions: [{material: block, shape: {box: [0, 0, 0, 1, 1, 0.5]}}]}
  boundaries:
    base_bottom: {plane: {point: [0, 0, -0.5], normal: [0, 0, 1]}}
    block_top: {plane: {point: [0, 0, 0.5], normal: [0, 0, 1]}}
    x0: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
    y0: {plane: {point: [0, 0, 0], normal: [0, 1, 0]}}
    base_top: {body: base, plane: {point: [0, 0, 0], normal: [0, 0, 1]}}
    block_bottom: {body: block, plane: {point: [0, 0, 0], normal: [0, 0, 1]}}
  supports:
    base_bottom: {u: [null, null, 0.0]}
    x0: {u: [0.0, null, null]}
    y0: {normal: 0.0}
  loads:
    block_top: {pressure: 2.0e+6}
  contacts:
    interface: {slave: block_bottom, master: base_top, friction: {slip_limit: 3.0e+5}}
  regions_of_interest:
    interface: {boundary: base_top}
    core: {box: [0.25, 0.25, -0.4, 0.75, 0.75, -0.1], body: base}
uncertain:
  loads.block_top.pressure: [1.0e+6, 3.0e+6]
  materials.block.E: [4.0e+9, 6.0e+9]
  contacts.interface.friction.slip_limit: {range: [2.0e+5, 4.0e+5], lipschitz: 1.0e+6, points: [2, 2]}
criteria:
  - {name: pressure, kind: contact_pressure, regions: [interface]}
  - {name: stress, kind: von_mises, regions: [core]}
solver: {method: monolithic}
output: out.nc
"""

G2 = """
study: fuzz-glue
scene:
  plane: strain
  mesh: {size: 0.1, max_cells: 20000}
  materials:
    concrete: {E: 3.0e10, nu: 0.2}
    steel: {E: 2.1e11, nu: 0.3}
  bodies:
    soft: {mesh: {size: 0.05}, regions: [{material: concrete, shape: {rectangle: [0.0, 0.0, 1.0, 0.3]}}]}
    hard: {mesh: {size: 0.08}, regions: [{material: steel, shape: {rectangle: [0.0, 0.3, 1.0, 0.5]}}]}
  boundaries:
    bottom: {segment: [[0.0, 0.0], [1.0, 0.0]]}
    top:    {segment: [[0.0, 0.5], [1.0, 0.5]]}
    left:   {segment: [[0.0, 0.0], [0.0, 0.5]]}
    right:  {segment: [[1.0, 0.0], [1.0, 0.5]]}
    soft_top: {body: soft, segment: [[0.0, 0.3], [1.0, 0.3]]}
    hard_bottom: {body: hard, segment: [[0.0, 0.3], [1.0, 0.3]]}
  glue:
    interface: {slave: hard_bottom, master: soft_top}
  supports:
    bottom: {u: [null, 0.0]}
    left:   {normal: 0.0}
    right:  {u: [0.0, null]}
  loads:
    top: {pressure: 1.0e6}
  regions_of_interest:
    top_edge: {boundary: top}
    soft_layer: {box: [0.0, 0.0, 1.0, 0.3]}
uncertain:
  materials.concrete.E: [2.5e10, 3.5e10]
  loads.top.pressure: [0.8e6, 1.2e6]
criteria:
  - {name: settlement, kind: mean_normal_displacement, regions: [top_edge], direction: [0.0, -1.0]}
  - {name: shear, kind: shear_stress_intensity, regions: [soft_layer]}
output: out.nc
"""

M2 = """
study: fuzz-msh-2d
scene:
  plane: strain
  mesh: {file: mesh.msh}
  materials:
    steel: {E: 2.1e11, nu: 0.3}
  bodies:
    a: {regions: [{material: steel}]}
  supports:
    bottom: {u: [0.0, 0.0]}
  loads:
    top: {pressure: 1.0e6}
  regions_of_interest:
    all: {box: [0.0, 0.0, 1.0, 1.0]}
uncertain:
  loads.top.pressure: [0.5e6, 1.5e6]
criteria:
  - {name: stress, kind: von_mises, regions: [all]}
output: out.nc
"""

M3 = M2.replace("fuzz-msh-2d", "fuzz-msh-3d").replace("plane: strain", "dimension: 3") \
    .replace("u: [0.0, 0.0]", "u: [0.0, 0.0, 0.0]").replace("box: [0.0, 0.0, 1.0, 1.0]",
                                                              "boundary: top")
BASES = {"2d": B2, "3d": B3, "glue": G2, "msh2d": M2, "msh3d": M3}


@functools.cache
def _parsed(name: str) -> dict:
    from wcs.study.source import _Loader
    return yaml.load(BASES[name], Loader=_Loader)


def base(name: str) -> dict:
    """A fresh parsed copy of base `name` (numbers such as 1.0e7 read as numbers, as wcs reads them)."""
    return copy.deepcopy(_parsed(name))


def dump(doc: dict) -> str:
    return yaml.safe_dump(doc, sort_keys=False, allow_unicode=False, width=10**9)


# ---------------------------------------------------------------- mesh files (MSH 2.2, ASCII)


def grid2d(n: int = 3):
    """The unit square as n x n squares, two triangles each: nodes, triangles, bottom and top lines."""
    nodes = [(i / n, j / n, 0.0) for j in range(n + 1) for i in range(n + 1)]
    k = lambda i, j: j * (n + 1) + i                                    # noqa: E731
    tris = [t for i in range(n) for j in range(n)
            for t in ([k(i, j), k(i + 1, j), k(i + 1, j + 1)], [k(i, j), k(i + 1, j + 1), k(i, j + 1)])]
    bottom = [[k(i, 0), k(i + 1, 0)] for i in range(n)]
    top = [[k(i, n), k(i + 1, n)] for i in range(n)]
    return nodes, {"a": (2, 2, tris), "bottom": (1, 1, bottom), "top": (1, 1, top)}


def cube3d():
    """The unit cube as the six Kuhn tetrahedra, and its bottom (z = 0) and top (z = 1) triangles."""
    nodes = [(x, y, z) for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0)]
    index = {p: i for i, p in enumerate(nodes)}
    tets = []
    for axes in itertools.permutations(range(3)):
        p = [0.0, 0.0, 0.0]
        tet = [index[tuple(p)]]
        for a in axes:
            p[a] = 1.0
            tet.append(index[tuple(p)])
        tets.append(tet)
    faces = [[t[a] for a in range(4) if a != skip] for t in tets for skip in range(4)]
    on = lambda f, z: all(nodes[v][2] == z for v in f)                   # noqa: E731
    return nodes, {"a": (3, 4, tets), "bottom": (2, 2, [f for f in faces if on(f, 0.0)]),
                   "top": (2, 2, [f for f in faces if on(f, 1.0)])}


def msh22(nodes, groups, tags=None, names=None) -> str:
    """MSH 2.2 text: `groups` is {name: (dim, gmsh element type, [0-based node lists])}, one
    physical group (and elementary entity) each; `tags` the node tags (default 1..n)."""
    tags = list(range(1, len(nodes) + 1)) if tags is None else tags
    names = names or {}
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(groups))]
    lines += [f'{dim} {g + 1} "{names.get(name, name)}"' for g, (name, (dim, _, _)) in enumerate(groups.items())]
    lines += ["$EndPhysicalNames", "$Nodes", str(len(nodes))]
    lines += [f"{t} {x!r} {y!r} {z!r}" for t, (x, y, z) in zip(tags, nodes)]
    lines += ["$EndNodes", "$Elements"]
    elements = [(etype, g + 1, cell) for g, (_, (_, etype, cells)) in enumerate(groups.items()) for cell in cells]
    lines.append(str(len(elements)))
    lines += [f"{e + 1} {etype} 2 {g} {g} " + " ".join(str(tags[v] if v < len(tags) else v + 1) for v in cell)
              for e, (etype, g, cell) in enumerate(elements)]
    lines.append("$EndElements")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- the mutant


@dataclass
class Mutant:
    kind: str
    what: str
    base: str
    expect: str                                   # "bad": must be exit 2; "any": exit 0 or 2
    edit: Callable[[dict], None] | None = None    # edits the parsed base in place
    text: Callable[[str], str] | None = None      # or: rewrites the study's YAML text
    files: Callable[[Path], None] | None = None   # writes extra files (a mesh, a FIFO) into the folder
    study: Callable[[Path], str] | None = None    # the study path to give (default: the written study)
    command: str = "check"
    known: str = ""                               # the known fault it reaches, named in its failure line

    @property
    def id(self) -> str:
        return f"{self.kind}: {self.what}"

    def build(self, folder: Path) -> list[str]:
        """Write the case into `folder`; the `wcs` command line that checks it."""
        folder.mkdir(parents=True, exist_ok=True)
        if self.base.startswith("msh"):
            nodes, groups = grid2d() if self.base == "msh2d" else cube3d()
            (folder / "mesh.msh").write_text(msh22(nodes, groups), encoding="utf-8")
        doc = base(self.base)
        if self.edit:
            self.edit(doc)
        text = dump(doc)
        assert self.edit is None or text != dump(base(self.base)), f"mutant '{self.id}' changes nothing"
        if self.text:
            text, unchanged = self.text(text), text
            assert text != unchanged, f"mutant '{self.id}' changes nothing"
        path = folder / "study.yaml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        if self.files:
            self.files(folder)
        target = self.study(folder) if self.study else str(path)
        extra = ["-o", str(folder / "sweep.nc")] if self.command == "sweep" else []
        return [self.command, target, "--quiet"] + extra


# ---------------------------------------------------------------- editing helpers


def at(doc, path):
    """The node at key path `path` (missing mappings on the way made empty)."""
    for k in path:
        doc = doc.setdefault(k, {}) if isinstance(doc, dict) else doc[k]
    return doc


def put(path, value):
    def edit(doc):
        at(doc, path[:-1])[path[-1]] = copy.deepcopy(value)
    return edit


def drop(path):
    def edit(doc):
        del at(doc, path[:-1])[path[-1]]
    return edit


def edits(*functions):
    def edit(doc):
        for f in functions:
            f(doc)
    return edit


def rename_everywhere(old: str, new: str):
    """Rename a name consistently: every mapping key and string value equal to `old`."""
    def walk(node):
        if isinstance(node, dict):
            return {(new if k == old else k): walk(v) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v) for v in node]
        return new if node == old else node

    def edit(doc):
        renamed = walk(doc)
        doc.clear()
        doc.update(renamed)
    return edit


def _finite_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def out_of(lo=-INF, hi=INF, lo_open=False, hi_open=False, integer=False):
    """A rule: is a value wrong for a slot of this range (bool, NaN, inf, a float for an integer)?"""
    def bad(v) -> bool:
        if not _finite_number(v) or (integer and not isinstance(v, int)):
            return True
        return v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi)
    return bad


# ---------------------------------------------------------------- the kinds
# Each kind is a function of the random generator giving one Mutant.

S3 = ["scene", "bodies", "base", "regions", 0, "shape"]


def solid3d(rng: random.Random) -> Mutant:
    c = rng.choice([
        ("box reversed", "bad", {"box": [1, 1, 0, 0, 0, -0.5]}),
        ("box of zero thickness", "bad", {"box": [0, 0, -0.5, 1, 1, -0.5]}),
        ("box with NaN", "bad", {"box": [0, 0, NAN, 1, 1, 0]}),
        ("box of five numbers", "bad", {"box": [0, 0, -0.5, 1, 1]}),
        ("box of 1e300", "bad", {"box": [0, 0, -0.5, 1e300, 1, 0]}),
        ("cylinder radius 0", "bad", {"cylinder": {"start": [0.5, 0.5, -0.5], "end": [0.5, 0.5, 0], "radius": 0}}),
        ("cylinder radius -1", "bad", {"cylinder": {"start": [0.5, 0.5, -0.5], "end": [0.5, 0.5, 0], "radius": -1}}),
        ("cylinder start = end", "bad", {"cylinder": {"start": [0.5, 0.5, 0], "end": [0.5, 0.5, 0], "radius": 0.5}}),
        ("cylinder radius NaN", "bad", {"cylinder": {"start": [0.5, 0.5, -0.5], "end": [0.5, 0.5, 0], "radius": NAN}}),
        ("cylinder", "any", {"cylinder": {"start": [0.5, 0.5, -0.5], "end": [0.5, 0.5, 0], "radius": 0.5}}),
        ("sphere radius -0.5", "bad", {"sphere": {"center": [0.5, 0.5, -0.5], "radius": -0.5}}),
        ("sphere radius 1e-9", "bad", {"sphere": {"center": [0.5, 0.5, -0.5], "radius": 1e-9}}),
        ("sphere centre of 2 numbers", "bad", {"sphere": {"center": [0.5, 0.5], "radius": 0.5}}),
        ("sphere", "any", {"sphere": {"center": [0.5, 0.5, -0.5], "radius": 0.5}}),
        ("huge sphere (resource guard)", "any", {"sphere": {"center": [0.5, 0.5, -0.5], "radius": 1e3}}),
        ("extrude in the plane", "bad", {"extrude": {"shape": {"rectangle": [0, 0, 1, 1]}, "vector": [0, 0, 0]}}),
        ("extrude of a 3D box", "bad", {"extrude": {"shape": {"box": [0, 0, 0, 1, 1, 1]}, "vector": [0, 0, -0.5]}}),
        ("extrude of a bowtie", "bad", {"extrude": {"shape": {"polygon": [[0, 0], [1, 1], [1, 0], [0, 1]]},
                                                    "vector": [0, 0, -0.5]}}),
        ("extrude down", "any", {"extrude": {"shape": {"rectangle": [0, 0, 1, 1]}, "vector": [0, 0, -0.5]}}),
        ("a halfspace alone", "bad", {"halfspace": {"point": [0, 0, 0], "normal": [0, 0, 1]}}),
        ("halfspace with zero normal", "bad", {"box": [0, 0, -0.5, 1, 1, 0], "intersect": [
            {"halfspace": {"point": [0, 0, 0], "normal": [0, 0, 0]}}]}),
        ("box minus a larger box (empty)", "bad", {"box": [0, 0, -0.5, 1, 1, 0], "minus": [{"box": [-1, -1, -1, 2, 2, 1]}]}),
        ("box intersect a disjoint box (empty)", "bad", {"box": [0, 0, -0.5, 1, 1, 0],
                                                          "intersect": [{"box": [5, 5, 5, 6, 6, 6]}]}),
        ("box cut by a halfspace", "any", {"box": [0, 0, -0.5, 1, 1, 0],
                                           "intersect": [{"halfspace": {"point": [0, 0, -0.1], "normal": [0.1, 0, 1]}}]}),
        ("two primitives", "bad", {"box": [0, 0, -0.5, 1, 1, 0], "sphere": {"center": [0, 0, 0], "radius": 1}}),
        ("no primitive", "bad", {}),
        ("a 2D rectangle", "bad", {"rectangle": [0, 0, 1, 1]}),
        ("box of strings", "bad", {"box": ["0", "0", "-0.5", "1", "1", "0"]}),
    ])
    return Mutant("solid3d", c[0], "3d", c[1], put(S3, c[2]))


def overlapping_bodies(rng):
    z = rng.choice([-0.25, -0.1])
    return Mutant("solid3d", f"block moved down to z = {z} (overlaps the base)", "3d", "bad",
                  put(["scene", "bodies", "block", "regions", 0, "shape"], {"box": [0, 0, z, 1, 1, z + 0.5]}),
                  known="inputs")


def selector3d(rng):
    B = ["scene", "boundaries"]
    R = ["scene", "regions_of_interest"]
    c = rng.choice([
        ("plane with zero normal", "bad", B + ["block_top"], {"plane": {"point": [0, 0, 0.5], "normal": [0, 0, 0]}}),
        ("plane normal NaN", "bad", B + ["block_top"], {"plane": {"point": [0, 0, 0.5], "normal": [0, 0, NAN]}}),
        ("plane selecting no face", "bad", B + ["block_top"], {"plane": {"point": [0, 0, 7], "normal": [0, 0, 1]}}),
        ("plane tolerance 0", "bad", B + ["block_top"], {"plane": {"point": [0, 0, 0.5], "normal": [0, 0, 1],
                                                                   "tolerance": 0}}),
        ("plane tolerance 1e6 (every face)", "any", B + ["block_top"],
         {"plane": {"point": [0, 0, 0.5], "normal": [0, 0, 1], "tolerance": 1e6}}),
        ("face box reversed", "bad", B + ["block_top"], {"box": [1, 1, 0.5, 0, 0, 0.5]}),
        ("face box", "any", B + ["block_top"], {"box": [-0.1, -0.1, 0.49, 1.1, 1.1, 0.51]}),
        ("face cylinder radius 0", "bad", B + ["block_top"],
         {"cylinder": {"start": [0, 0, 0], "end": [0, 0, 1], "radius": 0}}),
        ("face sphere selecting nothing", "bad", B + ["block_top"], {"sphere": {"center": [9, 9, 9], "radius": 1}}),
        ("face selector of an unknown body", "bad", B + ["block_top"],
         {"body": "ghost", "plane": {"point": [0, 0, 0.5], "normal": [0, 0, 1]}}),
        ("a 2D segment in 3D", "bad", B + ["block_top"], {"segment": [[0, 0], [1, 0]]}),
        ("two face selectors", "bad", B + ["block_top"], {"plane": {"point": [0, 0, 0.5], "normal": [0, 0, 1]},
                                                          "box": [0, 0, 0.5, 1, 1, 0.5]}),
        ("region box outside the scene", "bad", R + ["core"], {"box": [5, 5, 5, 6, 6, 6]}),
        ("region box reversed", "bad", R + ["core"], {"box": [0.75, 0.75, -0.1, 0.25, 0.25, -0.4]}),
        ("region ball radius 0", "bad", R + ["core"], {"ball": {"center": [0.5, 0.5, -0.25], "radius": 0}}),
        ("region ball", "any", R + ["core"], {"ball": {"center": [0.5, 0.5, -0.25], "radius": 0.2}}),
        ("region cylinder", "any", R + ["core"],
         {"cylinder": {"start": [0.5, 0.5, -0.5], "end": [0.5, 0.5, 0], "radius": 0.3}}),
        ("region of an unknown boundary", "bad", R + ["core"], {"boundary": "ghost"}),
        ("region box in a body it misses", "bad", R + ["core"], {"box": [0.25, 0.25, -0.4, 0.75, 0.75, -0.1],
                                                                  "body": "block"}),
        ("region with a 2D disc", "bad", R + ["core"], {"disc": {"center": [0, 0], "radius": 1}}),
    ])
    return Mutant("selector", c[0], "3d", c[1], put(c[2], c[3]))


def selector2d(rng):
    B = ["scene", "boundaries"]
    c = rng.choice([
        ("segment off the scene", "bad", B + ["pad_top"], {"body": "pad", "segment": [[5, 5], [6, 5]]}),
        ("segment of one point", "bad", B + ["pad_top"], {"segment": [[1, 1.5], [1, 1.5]]}),
        ("circle radius -1", "bad", B + ["pad_top"], {"circle": {"center": [1, 1], "radius": -1}}),
        ("circle selecting nothing", "bad", B + ["pad_top"], {"circle": {"center": [1, 1], "radius": 0.1}}),
        ("box boundary", "any", B + ["pad_top"], {"body": "pad", "box": [0.4, 1.4, 1.6, 1.6]}),
        ("region polygon of two points", "bad", ["scene", "regions_of_interest", "under_pad"],
         {"polygon": [[0, 0], [1, 1]]}),
        ("region disc", "any", ["scene", "regions_of_interest", "under_pad"], {"disc": {"center": [1, 1], "radius": 0.2}}),
        ("region box of zero area", "bad", ["scene", "regions_of_interest", "under_pad"], {"box": [1, 1, 1, 1]}),
        ("a 3D plane in 2D", "bad", B + ["pad_top"], {"plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}}),
    ])
    return Mutant("selector", c[0], "2d", c[1], put(c[2], c[3]))


def glue(rng):
    G = ["scene", "glue", "interface"]
    c = rng.choice([
        ("slave = master", "bad", put(G, {"slave": "soft_top", "master": "soft_top"}), ""),
        ("unknown slave", "bad", put(G + ["slave"], "ghost"), ""),
        ("both sides on one body", "bad", put(G, {"slave": "bottom", "master": "soft_top"}), ""),
        ("sides reversed", "any", put(G, {"slave": "soft_top", "master": "hard_bottom"}), ""),
        ("master missing", "bad", drop(G + ["master"]), ""),
        ("glue is a string", "bad", put(["scene", "glue"], "interface"), ""),
        ("glue empty (two free bodies)", "any", put(["scene", "glue"], {}), ""),
        ("glued twice", "bad", put(["scene", "glue", "again"], {"slave": "hard_bottom", "master": "soft_top"}), "inputs"),
        ("glue and a contact on the same sides", "bad",
         put(["scene", "contacts"], {"touch": {"slave": "hard_bottom", "master": "soft_top"}}), "inputs"),
        ("glue sides far apart (hard body lifted by 1 m)", "bad", edits(
            put(["scene", "bodies", "hard", "regions", 0, "shape"], {"rectangle": [0.0, 1.3, 1.0, 1.5]}),
            put(["scene", "boundaries", "hard_bottom"], {"body": "hard", "segment": [[0.0, 1.3], [1.0, 1.3]]}),
            put(["scene", "boundaries", "top"], {"segment": [[0.0, 1.5], [1.0, 1.5]]})), "inputs"),
        ("glue slave held fixed", "any", put(["scene", "supports", "hard_bottom"], {"u": [0.0, 0.0]}), "inputs"),
        ("glue with friction", "bad", put(G + ["friction"], {"slip_limit": 1.0}), ""),
        ("glue side of a 3D plane", "bad", put(G + ["slave"], {"plane": [0, 0, 1]}), ""),
    ])
    return Mutant("glue", c[0], "glue", c[1], c[2], known=c[3])


def refine(rng):
    R = ["scene", "mesh", "refine", 0]
    c = rng.choice([
        ("size 0", "bad", put(R + ["size"], 0)),
        ("size -0.05", "bad", put(R + ["size"], -0.05)),
        ("size NaN", "bad", put(R + ["size"], NAN)),
        ("size 1e-300", "bad", put(R + ["size"], 1e-300)),
        ("size 1e-4 (resource guard)", "any", put(R + ["size"], 1e-4)),
        ("size 1e-6 over the whole scene (resource guard)", "any", put(R, {"box": [0, 0, 2, 1.5], "size": 1e-6})),
        ("box reversed", "bad", put(R + ["box"], [1.6, 1.1, 0.4, 0.9])),
        ("unknown boundary", "bad", put(R, {"boundary": "ghost", "size": 0.05})),
        ("boundary zone", "any", put(R, {"boundary": "pad_bottom", "size": 0.05})),
        ("disc radius 0", "bad", put(R, {"disc": {"center": [1, 1], "radius": 0}, "size": 0.05})),
        ("disc zone", "any", put(R, {"disc": {"center": [1, 1], "radius": 0.2}, "size": 0.05})),
        ("zone outside the scene", "any", put(R + ["box"], [10, 10, 11, 11])),
        ("size missing", "bad", drop(R + ["size"])),
        ("two selectors", "bad", put(R + ["disc"], {"center": [1, 1], "radius": 0.2})),
        ("200 zones", "any", put(["scene", "mesh", "refine"],
                                 [{"box": [0.01 * i, 0.0, 0.01 * i + 0.01, 0.1], "size": 0.05} for i in range(200)])),
        ("refine is a mapping", "bad", put(["scene", "mesh", "refine"], {"box": [0, 0, 1, 1], "size": 0.05})),
        ("grading -1", "bad", put(["scene", "mesh", "grading"], -1)),
        ("grading NaN", "bad", put(["scene", "mesh", "grading"], NAN)),
        ("grading 0", "any", put(["scene", "mesh", "grading"], 0)),
    ])
    return Mutant("refine", c[0], "2d", c[1], c[2])


def refine3d(rng):
    R = ["scene", "mesh", "refine"]
    c = rng.choice([
        ("ball zone", "any", [{"ball": {"center": [0.5, 0.5, 0], "radius": 0.3}, "size": 0.25}]),
        ("ball radius 0", "bad", [{"ball": {"center": [0.5, 0.5, 0], "radius": 0}, "size": 0.25}]),
        ("cylinder zone in one body", "any", [{"cylinder": {"start": [0.5, 0.5, -0.5], "end": [0.5, 0.5, 0],
                                                             "radius": 0.3}, "size": 0.25, "body": "base"}]),
        ("zone in an unknown body", "bad", [{"box": [0, 0, -0.5, 1, 1, 0], "size": 0.25, "body": "ghost"}]),
        ("boundary zone", "any", [{"boundary": "block_bottom", "size": 0.25}]),
        ("size 1e-3 (resource guard)", "any", [{"box": [0, 0, -0.5, 1, 1, 0.5], "size": 1e-3}]),
        ("box zone of zero thickness", "bad", [{"box": [0, 0, 0, 1, 1, 0], "size": 0.25}]),
        ("a 2D disc zone", "bad", [{"disc": {"center": [0, 0], "radius": 1}, "size": 0.25}]),
    ])
    return Mutant("refine", "3D " + c[0], "3d", c[1], put(R, c[2]))


def _msh_text(base_name, change):
    """A mesh file made by `change(nodes, groups) -> text`."""
    def files(folder):
        nodes, groups = grid2d() if base_name == "msh2d" else cube3d()
        (folder / "mesh.msh").write_text(change(nodes, groups), encoding="utf-8")
    return files


def _truncate(fraction):
    """The file cut at `fraction` of its length, and at the latest inside its last element line
    (gmsh reads a file whose data are whole and only `$EndElements` is missing: no data lost)."""
    def change(nodes, groups):
        text = msh22(nodes, groups)
        last = text.rindex("\n", 0, text.index("$EndElements") - 1)       # the last element line starts after it
        return text[:min(int(len(text) * fraction), last + 4)]
    return change


def _sparse(tag):
    return lambda nodes, groups: msh22(nodes, groups, tags=[tag + i for i in range(len(nodes))])


def _swap_dim(name, dim):
    def change(nodes, groups):
        groups = dict(groups)
        _, etype, cells = groups[name]
        groups[name] = (dim, etype, cells)
        return msh22(nodes, groups)
    return change


def _nodes(f):
    return lambda nodes, groups: msh22([f(i, p) for i, p in enumerate(nodes)], groups)


def _cells(name, f):
    def change(nodes, groups):
        groups = dict(groups)
        dim, etype, cells = groups[name]
        groups[name] = (dim, etype, f(cells))
        return msh22(nodes, groups)
    return change


def _named(name, new):
    return lambda nodes, groups: msh22(nodes, groups, names={name: new})


def meshfile(rng):
    which = rng.choice(["msh2d", "msh3d"])
    cell = "a"
    c = rng.choice([
        ("truncated at 30 %", "bad", _truncate(0.3), ""),
        ("truncated at 75 %", "bad", _truncate(0.75), ""),
        ("truncated at 97 %", "bad", _truncate(0.97), ""),
        ("without $EndElements (the data whole)", "any", lambda n, g: msh22(n, g).replace("$EndElements\n", ""), ""),
        ("empty file", "bad", lambda n, g: "", ""),
        ("binary noise", "bad", lambda n, g: "\x00\x01\xff" * 100, ""),
        ("sparse node tags from 1e12", "any", _sparse(10**12), "crashes"),
        ("sparse node tags from 1e6", "any", _sparse(10**6), ""),
        ("node tags 2**62", "any", _sparse(2**62), "crashes"),
        ("negative node tags", "any", _sparse(-100), "crashes"),
        ("duplicate node tags", "bad", lambda n, g: msh22(n, g, tags=[1] * len(n)), ""),
        ("body group of the boundary's dimension", "bad", _swap_dim(cell, 1 if which == "msh2d" else 2), ""),
        ("boundary group of the body's dimension", "bad", _swap_dim("top", 2 if which == "msh2d" else 3), ""),
        ("a node at NaN", "bad", _nodes(lambda i, p: (NAN, p[1], p[2]) if i == 1 else p), ""),
        ("a node at 1e300", "bad", _nodes(lambda i, p: (1e300, p[1], p[2]) if i == 1 else p), ""),
        ("all nodes on one point", "bad", _nodes(lambda i, p: (0.0, 0.0, 0.0)), ""),
        ("a cell naming a missing node", "bad", _cells(cell, lambda cs: cs + [[0, 1, 999][:len(cs[0])]
                                                                                + [2] * (len(cs[0]) - 3)]), ""),
        ("a repeated cell", "bad", _cells(cell, lambda cs: cs + [cs[0]]), ""),
        ("a degenerate cell", "bad", _cells(cell, lambda cs: cs + [[cs[0][0]] * len(cs[0])]), ""),
        ("the body without cells", "bad", _cells(cell, lambda cs: []), ""),
        ("the top without facets", "bad", _cells("top", lambda cs: []), ""),
        ("non-manifold: cells touching at one vertex only", "any", _cells(cell, lambda cs: cs[:1] + cs[-1:]), ""),
        ("group name with a NUL", "bad", _named("top", "to\\0p"), ""),
        ("group name 'base:'", "bad", _named(cell, cell + ":"), ""),
        ("group name of 10,000 characters", "bad", _named("top", "t" * 10_000), ""),
    ])
    planar = [("off the plane (z = 0.5) in 2D", "bad", _nodes(lambda i, p: (p[0], p[1], 0.5 if i == 2 else 0.0)), "")]
    if which == "msh2d" and rng.random() < 0.1:
        c = planar[0]
    return Mutant("meshfile", f"{which}: {c[0]}", which, c[1], files=_msh_text(which, c[2]), known=c[3])


def meshfile_study(rng):
    """The study's side of a mesh file: special files and wrong names (the file itself is valid)."""
    which = rng.choice(["msh2d", "msh3d"])
    M = ["scene", "mesh"]
    c = rng.choice([
        ("file missing", "bad", put(M, {"file": "nothing.msh"}), ""),
        ("file is the study folder", "bad", put(M, {"file": "."}), "crashes"),
        ("file is /dev/zero", "bad", put(M, {"file": "/dev/zero"}), "crashes"),
        ("file with size too", "bad", put(M + ["size"], 0.1), ""),
        ("body missing from the file", "bad", rename_everywhere("a", "b"), ""),
        ("a boundary group the file lacks", "bad", put(["scene", "loads"], {"side": {"pressure": 1.0}}), ""),
        ("file is a YAML file", "bad", put(M, {"file": "study.yaml"}), ""),
    ])
    return Mutant("meshfile", f"{which}: {c[0]}", which, c[1], c[2], known=c[3])


def ranges(rng):
    U = ["uncertain"]
    E, NU, P = "materials.rubber.E", "materials.rubber.nu", "loads.pad_top.pressure"
    c = rng.choice([
        ("E box lower above upper", "bad", put(U + [E], [1.2e7, 0.8e7]), ""),
        ("E box of one point", "any", put(U + [E], [1.0e7, 1.0e7]), ""),
        ("E box with NaN", "bad", put(U + [E], [NAN, 1.2e7]), ""),
        ("E box with inf", "bad", put(U + [E], [0.8e7, INF]), ""),
        ("E box of one number", "bad", put(U + [E], [1.0e7]), ""),
        ("E box of three numbers", "bad", put(U + [E], [0.8e7, 1.0e7, 1.2e7]), ""),
        ("E box of strings", "bad", put(U + [E], ["low", "high"]), ""),
        ("E box from 0", "bad", put(U + [E], [0.0, 1.2e7]), "inputs"),
        ("E box negative", "bad", put(U + [E], [-1.0e7, 1.2e7]), "inputs"),
        ("nominal E outside its box", "bad", put(U + [E], [2.0e7, 3.0e7]), ""),
        ("nu box up to 0.5", "bad", put(U + [NU], [0.35, 0.5]), "inputs"),
        ("nu box from -1", "bad", put(U + [NU], [-1.0, 0.42]), "inputs"),
        ("box of an unknown path", "bad", put(U + ["materials.gum.E"], [1, 2]), ""),
        ("box of a non-number", "bad", put(U + ["materials.rubber"], [1, 2]), ""),
        ("box of a boolean", "bad", put(U + [P], True), ""),
        ("box is a number", "bad", put(U + [P], 2.0e6), ""),
        ("pressure box past 1e12", "bad", put(U + [P], [1.5e6, 1e13]), ""),
        ("box of a support value", "any", put(U + ["supports.pad_left.normal"], [-1e-3, 1e-3]), ""),
        ("box of a body force", "any", put(U + ["body_forces.base.1"], [-8e4, -7e4]), ""),
        ("box of an index past the end", "bad", put(U + ["body_forces.base.2"], [-8e4, -7e4]), ""),
        ("box of a negative index", "bad", put(U + ["body_forces.base.-1"], [-8e4, -7e4]), ""),
        ("box of thermal.reference to 0", "bad", put(U + ["thermal.reference"], [0.0, 300.0]), ""),
        ("Lame box with lambda + mu <= 0", "bad", edits(
            put(["scene", "materials", "rubber"], {"lambda": 1.0e7, "mu": 3.0e6, "conductivity": 0.2,
                                                   "expansion": 2.0e-4}),
            drop(U + [E]), drop(U + [NU]), put(U + ["materials.rubber.lambda"], [-5.0e6, 1.2e7])), "inputs"),
        ("Lame box with nu below -1 at a corner (3 lambda + 2 mu < 0)", "bad", edits(
            put(["scene", "materials", "rubber"], {"lambda": 1.0e7, "mu": 3.0e6, "conductivity": 0.2,
                                                   "expansion": 2.0e-4}),
            drop(U + [E]), drop(U + [NU]), put(U + ["materials.rubber.lambda"], [-2.5e6, 1.2e7])), "inputs"),
        ("uncertain is a list", "bad", put(U, [[1, 2]]), ""),
    ])
    return Mutant("range", c[0], "2d", c[1], c[2], known=c[3])


def fuzzy(rng):
    U = ["uncertain", "materials.rubber.E"]
    c = rng.choice([
        ("core outside the support", "bad", put(U, {"support": [0.8e7, 1.2e7], "core": [1.0e7, 1.3e7]})),
        ("core reversed", "bad", put(U, {"support": [0.8e7, 1.2e7], "core": [1.1e7, 0.9e7]})),
        ("support reversed", "bad", put(U, {"support": [1.2e7, 0.8e7], "core": [1.0e7, 1.0e7]})),
        ("triangle", "any", put(U, {"support": [0.8e7, 1.2e7], "core": [1.0e7, 1.0e7]})),
        ("trapezoid", "any", put(U, {"support": [0.8e7, 1.2e7], "core": [0.9e7, 1.1e7]})),
        ("nominal outside the core", "bad", put(U, {"support": [0.8e7, 1.2e7], "core": [1.1e7, 1.2e7]})),
        ("core with NaN", "bad", put(U, {"support": [0.8e7, 1.2e7], "core": [NAN, 1.0e7]})),
        ("core missing", "bad", put(U, {"support": [0.8e7, 1.2e7]})),
        ("support with an extra key", "bad", put(U, {"support": [0.8e7, 1.2e7], "core": [1e7, 1e7], "peak": 1})),
        ("support down to 0", "bad", put(U, {"support": [0.0, 1.2e7], "core": [1.0e7, 1.0e7]})),
        ("levels empty", "bad", put(["fuzzy"], {"levels": []})),
        ("level 1.5", "bad", put(["fuzzy"], {"levels": [0.0, 1.5]})),
        ("level -0.1", "bad", put(["fuzzy"], {"levels": [-0.1, 1.0]})),
        ("level twice", "bad", put(["fuzzy"], {"levels": [0.5, 0.5]})),
        ("level NaN", "bad", put(["fuzzy"], {"levels": [NAN]})),
        ("level True", "bad", put(["fuzzy"], {"levels": [True]})),
        ("1000 levels", "any", put(["fuzzy"], {"levels": [i / 999 for i in range(1000)]})),
        ("levels with no fuzzy number", "any", put(["fuzzy"], {"levels": [0.0, 1.0]})),
    ])
    return Mutant("fuzzy", c[0], "2d", c[1], c[2])


def lipschitz(rng):
    dim = rng.choice(["2d", "3d"])
    L = ["uncertain", "contacts.interface.friction.slip_limit"]
    lo, hi = (0.5e5, 1.5e5) if dim == "2d" else (2.0e5, 4.0e5)
    good_points = 6 if dim == "2d" else [2, 2]
    c = rng.choice([
        ("points [2**62, 4]", "bad", [2**62, 4], {}, "crashes" if dim == "3d" else ""),
        ("points [1, 3]", "bad", [1, 3], {}, ""),
        ("points [2, 2.5]", "bad", [2, 2.5], {}, ""),
        ("points [0, 0]", "bad", [0, 0], {}, ""),
        ("points [-2, -3]", "bad", [-2, -3], {}, ""),
        ("points [2, 2, 2]", "bad", [2, 2, 2], {}, ""),
        ("points [31, 33] (1023 values)", "bad", [31, 33], {}, ""),
        ("points [10, 10]", "any" if dim == "3d" else "bad", [10, 10], {}, ""),
        ("points 7", "any" if dim == "2d" else "bad", 7, {}, ""),
        ("points 1", "bad", 1, {}, ""),
        ("points 1001", "bad", 1001, {}, ""),
        ("points 2**62", "bad", 2**62, {}, "crashes"),
        ("points True", "bad", True, {}, ""),
        ("points 7.0", "bad", 7.0, {}, ""),
        ("lipschitz 0", "bad", good_points, {"lipschitz": 0}, ""),
        ("lipschitz -1", "bad", good_points, {"lipschitz": -1}, ""),
        ("lipschitz NaN", "bad", good_points, {"lipschitz": NAN}, ""),
        ("lipschitz inf", "bad", good_points, {"lipschitz": INF}, ""),
        ("lipschitz 1e-300", "any", good_points, {"lipschitz": 1e-300}, ""),
        ("lipschitz 1e300", "any", good_points, {"lipschitz": 1e300}, ""),
        ("range reversed", "bad", good_points, {"range": [hi, lo]}, ""),
        ("range below 0", "bad", good_points, {"range": [-1.0, hi]}, ""),
        ("range and support", "bad", good_points, {"support": [lo, hi], "core": [lo, hi]}, ""),
        ("fuzzy profile", "any", good_points, {"range": None, "support": [lo, hi], "core": [(lo + hi) / 2 - 1,
                                                                                          (lo + hi) / 2 + 1]}, ""),
        ("fuzzy profile, core outside", "bad", good_points, {"range": None, "support": [lo, hi],
                                                            "core": [hi, hi * 2]}, ""),
        ("nominal outside the range", "bad", good_points, {"range": [lo * 3, hi * 3]}, ""),
    ])
    name, expect, points, more, known = c

    def edit(doc):
        spec = {"range": [lo, hi], "lipschitz": 2.0e5 if dim == "2d" else 1.0e6, "points": points}
        spec.update(more)
        at(doc, L[:-1])[L[-1]] = {k: v for k, v in spec.items() if v is not None}
    return Mutant("lipschitz", f"{dim}: {name}", dim, expect, edit, known=known)


def lipschitz_elsewhere(rng):
    path = rng.choice(["materials.rubber.E", "loads.pad_top.pressure"])
    return Mutant("lipschitz", f"a profile on {path}", "2d", "bad",
                  put(["uncertain", path], {"range": [1, 2], "lipschitz": 1.0, "points": 4}))


def sweep(rng):
    E = "materials.rubber.E"

    def grid(g):
        return edits(put(["sweep"], {"grid": g}), put(["uncertain"], {}))
    c = rng.choice([
        ("two points", "any", grid({E: [0.9e7, 1.1e7]}), ""),
        ("one point", "any", grid({E: [1.0e7]}), ""),
        ("grid empty", "bad", grid({}), ""),
        ("no values", "bad", grid({E: []}), ""),
        ("a NaN value", "bad", grid({E: [NAN, 1.0e7]}), ""),
        ("an inf value", "bad", grid({E: [INF]}), ""),
        ("E = -1", "bad", grid({E: [-1.0]}), ""),
        ("E = 0", "bad", grid({E: [0.0]}), ""),
        ("nu = 0.5", "bad", grid({"materials.rubber.nu": [0.5]}), ""),
        ("unknown path", "bad", grid({"materials.gum.E": [1.0e7]}), ""),
        ("a string value", "bad", grid({E: ["soft"]}), ""),
        ("a boolean value", "bad", grid({E: [True]}), ""),
        ("grid is a list", "bad", put(["sweep"], {"grid": [[E, 1.0e7]]}), ""),
        ("1e18 points", "bad", grid({p: [1.0e7 + i for i in range(1000)] if "E" in p else
                                     [0.3 + i * 1e-4 for i in range(1000)] if "nu" in p else
                                     [1.0e6 + i for i in range(1000)]
                                     for p in (E, "materials.steel.E", "materials.rubber.nu", "materials.steel.nu",
                                               "loads.pad_top.pressure", "body_forces.base.1")}), "crashes"),
        ("sweep and uncertain on one path", "any", put(["sweep"], {"grid": {E: [0.9e7, 1.1e7]}}), ""),
    ])
    return Mutant("sweep", c[0], "2d", c[1], c[2], command="sweep", known=c[3])


def solver(rng):
    S = ["solver"]
    c = rng.choice([
        ("method 'fast'", "bad", put(S + ["method"], "fast"), ""),
        ("method qp", "any", put(S + ["method"], "qp"), ""),
        ("method dd", "any", put(S + ["method"], "dd"), ""),
        ("method monolithic", "any", put(S + ["method"], "monolithic"), ""),
        ("tolerance 0", "bad", put(S + ["tolerance"], 0), ""),
        ("tolerance 1e-300", "any", put(S + ["tolerance"], 1e-300), "crashes"),
        ("tolerance 1e-20", "any", put(S + ["tolerance"], 1e-20), "crashes"),
        ("tolerance 1", "bad", put(S + ["tolerance"], 1), ""),
        ("tolerance NaN", "bad", put(S + ["tolerance"], NAN), ""),
        ("tolerance '1.0e-8' (a string)", "bad", put(S + ["tolerance"], "1.0e-8"), ""),
        ("max_iterations 0", "bad", put(S + ["max_iterations"], 0), ""),
        ("max_iterations 1", "any", put(S + ["max_iterations"], 1), ""),
        ("max_iterations True", "bad", put(S + ["max_iterations"], True), ""),
        ("max_iterations 2**62", "bad", put(S + ["max_iterations"], 2**62), ""),
        ("max_iterations 3.5", "bad", put(S + ["max_iterations"], 3.5), ""),
        ("dd with 4096 subdomains", "any", put(S, {"method": "dd", "dd": {"subdomains": 4096}}), "crashes"),
        ("dd with 1 subdomain", "any", put(S, {"method": "dd", "dd": {"subdomains": 1}}), ""),
        ("dd subdomains 0", "bad", put(S + ["dd", "subdomains"], 0), ""),
        ("dd subdomains 4097", "bad", put(S + ["dd", "subdomains"], 4097), ""),
        ("dd relaxation 'fast'", "bad", put(S + ["dd", "relaxation"], "fast"), ""),
        ("dd relaxation 2.5", "bad", put(S + ["dd", "relaxation"], 2.5), ""),
        ("dd relaxation anderson", "any", put(S, {"method": "dd", "dd": {"relaxation": "anderson"}}), ""),
        ("dd pcg_tolerance 1", "bad", put(S + ["dd", "pcg_tolerance"], 1), ""),
        ("fallback 'yes'", "bad", put(S + ["fallback"], "yes"), ""),
        ("unknown key", "bad", put(S + ["precision"], "high"), ""),
        ("solver is a string", "bad", put(S, "dd"), ""),
        ("search budget 0", "bad", put(["search", "budget"], 0), ""),
        ("search budget 1e12", "bad", put(["search", "budget"], 10**12), ""),
        ("sample n 0", "bad", put(["search", "sample", "n"], 0), ""),
        ("sample seed -1", "bad", put(["search", "sample", "seed"], -1), ""),
        ("sample seed 2**64", "bad", put(["search", "sample", "seed"], 2**64), ""),
        ("sample design 'halton'", "bad", put(["search", "sample", "design"], "halton"), ""),
        ("kkt_tol 1", "bad", put(["search", "kkt_tol"], 1), ""),
        ("max_fixed_point_iterations 0", "bad", put(S + ["max_fixed_point_iterations"], 0), ""),
    ])
    return Mutant("solver", c[0], rng.choice(["2d", "2d", "glue"]) if "dd" not in c[0] else "2d", c[1], c[2],
                  known=c[3])


def contact(rng):
    """Contacts and supports that contradict each other (the semantic checks of `wcs check`)."""
    C, S = ["scene", "contacts"], ["scene", "supports"]
    c = rng.choice([
        ("the same pair twice", "bad", put(C + ["again"], {"slave": "pad_bottom", "master": "base_top"})),
        ("the pair and its reverse", "bad", put(C + ["again"], {"slave": "base_top", "master": "pad_bottom"})),
        ("a support on the contact's slave side", "bad", put(S + ["pad_bottom"], {"u": [0.0, 0.0]})),
        ("a support on the contact's master side (a rigid obstacle)", "any", put(S + ["base_top"], {"normal": 0.0})),
        ("contradictory supports on one edge", "bad", edits(
            put(["scene", "boundaries", "floor"], {"body": "base", "segment": [[0.0, 0.0], [2.0, 0.0]]}),
            put(S + ["floor"], {"u": [1.0e-3, 0.0]}))),
        ("contact sides 1 m apart", "bad", edits(
            put(["scene", "bodies", "pad", "regions", 0, "shape"], {"rectangle": [0.5, 2.0, 1.5, 2.5]}),
            put(["scene", "boundaries", "pad_top"], {"body": "pad", "segment": [[0.5, 2.5], [1.5, 2.5]]}),
            put(["scene", "boundaries", "pad_left"], {"body": "pad", "segment": [[0.5, 2.0], [0.5, 2.5]]}),
            put(["scene", "boundaries", "pad_bottom"], {"body": "pad", "segment": [[0.5, 2.0], [1.5, 2.0]]}))),
        ("overlapping regions (pad sunk into the base)", "bad", edits(
            put(["scene", "bodies", "pad", "regions", 0, "shape"], {"rectangle": [0.5, 0.8, 1.5, 1.3]}),
            put(["scene", "boundaries", "pad_top"], {"body": "pad", "segment": [[0.5, 1.3], [1.5, 1.3]]}),
            put(["scene", "boundaries", "pad_left"], {"body": "pad", "segment": [[0.5, 0.8], [0.5, 1.3]]}),
            put(["scene", "boundaries", "pad_bottom"], {"body": "pad", "segment": [[0.5, 0.8], [1.5, 0.8]]}))),
        ("the base slid 1000 m under the pad (a rigid translation, Tresca slip 1000 m)", "any",
         put(S + ["base_bottom", "u", 0], 1000.0)),
    ])
    return Mutant("contact", c[0], "2d", c[1], c[2], known="" if "slid" in c[0] else "inputs")


LONG = "b" * 100_000


def names(rng):
    c = rng.choice([
        ("body of 100,000 characters", "any", rename_everywhere("pad", LONG), "crashes"),
        ("body of 1,000 characters", "any", rename_everywhere("pad", "p" * 1000), ""),
        ("unicode body", "any", rename_everywhere("pad", "Pölster_垫"), ""),
        ("body with a right-to-left mark", "any", rename_everywhere("pad", "pad\u202e"), ""),
        ("body with a NUL", "bad", rename_everywhere("pad", "pa\x00d"), "crashes"),
        ("body with a lone surrogate", "bad", rename_everywhere("pad", "pa\ud800d"), "crashes"),
        ("material with a lone surrogate", "bad", rename_everywhere("rubber", "rub\udfffber"), "crashes"),
        ("criterion with a NUL", "bad", rename_everywhere("shear", "sh\x00ear"), "crashes"),
        ("region of interest with a surrogate", "bad", rename_everywhere("under_pad", "under\ud83dpad"), "crashes"),
        ("boundary with a newline", "bad", rename_everywhere("pad_top", "pad\ntop"), ""),
        ("body with a dot", "bad", rename_everywhere("pad", "pad.v2"), ""),
        ("body with brackets", "bad", rename_everywhere("pad", "pad[0]"), ""),
        ("empty body name", "bad", rename_everywhere("pad", ""), ""),
        ("body named 'null'", "any", rename_everywhere("pad", "null"), ""),
        ("body named '1'", "any", rename_everywhere("pad", "1"), ""),
        ("body named like a material", "any", rename_everywhere("pad", "rubber"), ""),
        ("region named like the other body", "bad",
         put(["scene", "bodies", "pad", "regions", 0, "name"], "base"), ""),
        ("criterion name twice", "bad", put(["criteria", 1, "name"], "settlement"), ""),
        ("contact named like a boundary", "any", rename_everywhere("interface", "pad_top"), ""),
        ("study name with a NUL", "bad", put(["study"], "fu\x00zz"), "crashes"),
        ("study name of 100,000 characters", "any", put(["study"], LONG), "crashes"),
        ("output with a NUL", "bad", put(["output"], "o\x00ut.nc"), ""),
        ("body key is a number", "bad", edits(rename_everywhere("pad", "7"),
                                              lambda d: d["scene"]["bodies"].__setitem__(7, d["scene"]["bodies"].pop("7"))), ""),
    ])
    return Mutant("names", c[0], "2d", c[1], c[2], known=c[3])


def duplicates(rng):
    """Duplicate names in the YAML text itself (a mapping key given twice)."""
    c = rng.choice([                      # as yaml.safe_dump writes the base (block style)
        ("body key given twice", "\n    pad:\n      regions:", "\n    base:\n      regions:"),
        ("boundary key given twice", "\n    pad_left:\n", "\n    pad_top:\n"),
        ("top-level key given twice", "output: out.nc", "search:\n  budget: 3"),
        ("uncertain path given twice", "\n  materials.rubber.nu:\n", "\n  materials.rubber.E:\n"),
    ])
    return Mutant("names", c[0], "2d", "bad", text=lambda t: t.replace(c[1], c[2], 1))


def _fifo(folder):
    os.mkfifo(folder / "fifo")


def _sparse_file(name, size):
    def files(folder):
        with open(folder / name, "wb") as f:
            f.truncate(size)
    return files


def special(rng):
    c = rng.choice([
        ("study is a FIFO", "bad", _fifo, lambda f: str(f / "fifo"), None, "crashes"),
        ("study is /dev/zero", "bad", None, lambda f: "/dev/zero", None, "crashes"),
        ("study is a directory", "bad", None, lambda f: str(f), None, "crashes"),
        ("study is /dev/null", "bad", None, lambda f: "/dev/null", None, ""),
        ("study is a 1 GB sparse file", "bad", _sparse_file("huge.yaml", 2**30), lambda f: str(f / "huge.yaml"),
         None, "crashes"),
        ("study is missing", "bad", None, lambda f: str(f / "none.yaml"), None, ""),
        ("study is not UTF-8", "bad", lambda f: (f / "latin.yaml").write_bytes(b"study: caf\xe9\n"),
         lambda f: str(f / "latin.yaml"), None, ""),
        ("study is a symlink loop", "bad", lambda f: os.symlink(f / "loop.yaml", f / "loop.yaml"),
         lambda f: str(f / "loop.yaml"), None, ""),
        ("scene is a FIFO", "bad", _fifo, None, put(["scene"], "fifo"), "crashes"),
        ("scene is /dev/zero", "bad", None, None, put(["scene"], "/dev/zero"), "crashes"),
        ("scene is the folder", "bad", None, None, put(["scene"], "."), "crashes"),
        ("materials file is a FIFO", "bad", _fifo, None, put(["scene", "materials"], "fifo"), "crashes"),
        ("materials file is /dev/zero", "bad", None, None, put(["scene", "materials"], "/dev/zero"), "crashes"),
        ("materials file is a 1 GB sparse file", "bad", _sparse_file("huge.yaml", 2**30), None,
         put(["scene", "materials"], "huge.yaml"), "crashes"),
        ("output is a FIFO", "any", _fifo, None, put(["output"], "fifo"), "crashes"),
        ("output is /dev/zero", "any", None, None, put(["output"], "/dev/zero"), ""),
        ("output is the folder", "bad", None, None, put(["output"], "."), ""),
        ("output in a missing folder", "any", None, None, put(["output"], "no/such/out.nc"), ""),
    ])
    return Mutant("special", c[0], "2d", c[1], c[4], files=c[2], study=c[3], known=c[5])


def _alias_bomb(levels: int, where: str) -> Callable[[str], str]:
    """A billion-laughs YAML: level i is a list of ten aliases of level i - 1 (10^levels leaves),
    as items of `criteria` or under an unknown top-level key."""
    items = ["&a0 [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]"]
    items += [f"&a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    if where == "criteria":
        return lambda t: t.replace("criteria:\n", "criteria:\n" + "".join(f"- {x}\n" for x in items), 1)
    return lambda t: t + "extra:\n" + "".join(f"- {x}\n" for x in items)


def yaml_text(rng):
    c = rng.choice([
        ("alias bomb (10^9 leaves) in criteria", "bad", _alias_bomb(9, "criteria"), "crashes"),
        ("alias bomb (10^9 leaves) under an unknown key", "bad", _alias_bomb(9, "extra"), "crashes"),
        ("alias bomb (10^4 leaves) in criteria", "bad", _alias_bomb(4, "criteria"), ""),
        ("60 levels of nesting", "bad", lambda t: t + "extra: " + "[" * 60 + "]" * 60 + "\n", ""),
        ("a tab for indentation", "bad", lambda t: t.replace("\n  dimension", "\n\tdimension", 1), ""),
        ("a YAML document stream", "bad", lambda t: t + "---\nstudy: again\n", ""),
        ("a custom tag", "bad", lambda t: t.replace("out.nc", "!!python/object:os.system out.nc", 1), ""),
        ("a NUL in the text", "bad", lambda t: t.replace("out.nc", "out\x00.nc", 1), ""),
        ("a 200,000-vertex polygon", "any", lambda t: t.replace("POLYGON", repr(_circle(200_000)), 1), "crashes"),
    ])
    polygon = put(["scene", "bodies", "base", "regions", 0, "shape"], {"polygon": "POLYGON"})
    return Mutant("special", c[0], "2d", c[1], polygon if "polygon" in c[0] else None, text=c[2], known=c[3])


def _circle(n):
    return [[round(1.0 + 0.5 * math.cos(2 * math.pi * k / n), 12), round(0.5 + 0.5 * math.sin(2 * math.pi * k / n), 12)]
            for k in range(n)]


# numeric slots: (base, key path, rule: is a value wrong there?, known items by value)
SLOTS = [
    ("2d", ["scene", "mesh", "size"], out_of(1e-6, 1e6)),
    ("2d", ["scene", "mesh", "max_cells"], out_of(1, 10**10, integer=True)),
    ("2d", ["scene", "materials", "steel", "E"], out_of(1.0, 1e13)),
    ("2d", ["scene", "materials", "steel", "nu"], out_of(-1, 0.5, lo_open=True, hi_open=True)),
    ("2d", ["scene", "materials", "steel", "conductivity"], out_of(1e-6, 1e6)),
    ("2d", ["scene", "materials", "steel", "expansion"], out_of(-1e-2, 1e-2)),
    ("2d", ["scene", "bodies", "base", "regions", 0, "shape", "rectangle", 2], out_of(-1e6, 1e6)),
    ("2d", ["scene", "supports", "base_bottom", "u", 0], out_of(-1e6, 1e6)),
    ("2d", ["scene", "supports", "pad_left", "normal"], out_of(-1e6, 1e6)),
    ("2d", ["scene", "loads", "pad_top", "pressure"], out_of(1.5e6, 2.5e6)),       # in its box
    ("2d", ["scene", "body_forces", "base", 1], out_of(-1e10, 1e10)),
    ("2d", ["scene", "thermal", "reference"], out_of(0, 1e5, lo_open=True)),
    ("2d", ["scene", "thermal", "sources", "pad"], out_of(-1e12, 1e12)),
    ("2d", ["scene", "regions_of_interest", "under_pad", "box", 3], out_of(0.9, 1.5)),   # a box in the scene
    ("2d", ["criteria", 0, "point", 0], out_of(-1e6, 1e6)),
    ("2d", ["limits", "shear"], out_of()),
    ("2d", ["search", "budget"], out_of(1, 10**6, integer=True)),
    ("2d", ["search", "sample", "n"], out_of(1, 10**6, integer=True)),
    ("2d", ["search", "sample", "seed"], out_of(0, 2**32 - 1, integer=True)),
    ("2d", ["solver", "tolerance"], out_of(0, 1e-2, lo_open=True)),
    ("2d", ["solver", "dd", "subdomains"], out_of(1, 4096, integer=True)),
    ("2d", ["uncertain", "contacts.interface.friction.slip_limit", "points"], out_of(2, 1000, integer=True)),
    ("2d", ["uncertain", "materials.rubber.E", 1], out_of(1.0e7, 1e13)),
    ("3d", ["scene", "mesh", "size"], out_of(1e-6, 1e6)),
    ("3d", ["scene", "mesh", "max_cells"], out_of(1, 10**10, integer=True)),
    ("3d", ["scene", "bodies", "block", "regions", 0, "shape", "box", 5], out_of(0, 1e6, lo_open=True)),
    ("3d", ["scene", "boundaries", "block_top", "plane", "point", 2], out_of(-1e6, 1e6)),
    ("3d", ["scene", "contacts", "interface", "friction", "slip_limit"], out_of(2.0e5, 4.0e5)),
    ("3d", ["scene", "supports", "base_bottom", "u", 2], out_of(-1e6, 1e6)),
    ("3d", ["uncertain", "contacts.interface.friction.slip_limit", "lipschitz"], out_of(0, INF, lo_open=True)),
    ("glue", ["scene", "bodies", "hard", "mesh", "size"], out_of(1e-6, 1e6)),
    ("glue", ["scene", "materials", "concrete", "nu"], out_of(-1, 0.5, lo_open=True, hi_open=True)),
]
KNOWN_NUMBERS = {("max_cells", 10**10): "crashes", ("tolerance", 1e-300): "crashes", ("subdomains", 4096): "crashes"}


def numbers(rng):
    where, path, bad = rng.choice(SLOTS)
    now = repr(at(_parsed(where), path))
    value = rng.choice([v for v in EDGE + [10**10, 4096, 0.5, 1e-7] if repr(v) != now])
    expect = "bad" if bad(value) else "any"
    known = KNOWN_NUMBERS.get((path[-1], value), "")
    return Mutant("numbers", f"{where}: {'.'.join(map(str, path))} = {value!r}", where, expect,
                  put(path, value), known=known)


KINDS = {                  # kind: (generator, weight)
    "solid3d": ((solid3d, overlapping_bodies), 30),
    "selector": ((selector3d, selector2d), 30),
    "glue": ((glue,), 20),
    "contact": ((contact,), 20),
    "refine": ((refine, refine3d), 25),
    "meshfile": ((meshfile, meshfile, meshfile_study), 35),
    "range": ((ranges, fuzzy), 35),
    "lipschitz": ((lipschitz, lipschitz, lipschitz_elsewhere), 25),
    "sweep": ((sweep,), 12),
    "solver": ((solver,), 25),
    "names": ((names, duplicates), 25),
    "special": ((special, yaml_text), 25),
    "numbers": ((numbers,), 50),
}


def mutants(count: int, seed: int = 26, patience: int = 0) -> list[Mutant]:
    """`count` distinct mutants (by id) drawn with weights of their kind, the same for the same
    seed (with `patience`: fewer, once that many draws in a row brought nothing new)."""
    rng = random.Random(seed)
    kinds = list(KINDS)
    weights = [KINDS[k][1] for k in kinds]
    out, seen, stale = [], set(), 0
    while len(out) < count and stale < (patience or 50 * count):
        generators = KINDS[rng.choices(kinds, weights)[0]][0]
        m = rng.choice(generators)(rng)
        stale = stale + 1 if m.id in seen else 0
        if m.id not in seen:
            seen.add(m.id)
            out.append(m)
    return out


def every(seed: int = 26) -> list[Mutant]:
    """All distinct mutants the generators make (drawn until 3000 draws in a row bring no new one)."""
    return mutants(10**6, seed, patience=3000)


def find(ids: list[str], tries: int = 2000) -> list[Mutant]:
    """The mutants of these ids, whatever the seeded draw (each generator called with seeds 0, 1, ...)."""
    generators = sorted({g for gens, _ in KINDS.values() for g in gens}, key=lambda g: g.__name__)
    found: dict[str, Mutant] = {}
    for seed in range(tries):
        for g in generators:
            m = g(random.Random(seed))
            if m.id in ids:
                found.setdefault(m.id, m)
        if len(found) == len(set(ids)):
            break
    missing = [i for i in ids if i not in found]
    assert not missing, f"no generator makes {missing}"
    return [found[i] for i in ids]
