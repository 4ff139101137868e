"""The pieces both meshers (`mesher2d`, `mesher3d`) build a scene from, in one gmsh model: the
regions' names, the shapes fragmented into conforming pieces and each piece's owner (a body's
region; overlaps refused), per-region sizes on the pieces and every entity bounding them, and
the refusal of a region of interest meshed apart from its body. `dim` is 2 (surfaces) or 3
(volumes)."""
from __future__ import annotations

import numpy as np

from ..errors import StudyError
from .meshdata import SceneMesh
from .session import gmsh


def region_names(scene) -> list[tuple[str, str]]:
    """(body, region name) in scene order (the loader names every region)."""
    return [(body, reg.name) for body, bspec in scene.bodies.items() for reg in bspec.regions]


def closure(dimtags: list) -> list:
    """The entities `dimtags` and every entity bounding them, down to the points."""
    out, level = [], sorted(dimtags)
    while level:
        out += level
        level = sorted({(d, abs(t)) for d, t in gmsh.model.getBoundary(level, combined=False, oriented=False)})
    return out


def region_entity_sizes(owner: dict, regions_flat: list, dim: int = 2) -> dict:
    """{(dim, tag): size} for the pieces (surfaces in 2D, volumes in 3D) of regions with
    ``mesh: {size}`` and the entities bounding them, down to the points (the smallest size
    of the pieces around them)."""
    sizes = {}
    for tag, (_, rg) in owner.items():
        rs = regions_flat[rg].mesh
        if rs is not None:
            s = float(rs.size)
            for dt in closure([(dim, tag)]):
                sizes[dt] = min(sizes.get(dt, s), s)
    return sizes


def fragment_pieces(region_shapes: list, roi_shapes: list, dim: int = 2):
    """Fragment region and region-of-interest shapes of dimension `dim` (surfaces in 2D, solids
    in 3D) together; remove the pieces no region covers (parts of a region of interest outside
    every body). Returns {piece: [region input indices]} and {piece: [covered by region of
    interest j, for every j]}."""
    flat = [(k, dt) for k, dts in enumerate(region_shapes) for dt in dts]
    flat += [(-1 - j, dt) for j, dts in enumerate(roi_shapes) for dt in dts]
    outmap = _fragment([dt for _, dt in flat])
    covered: dict[int, list[int]] = {}
    rois: dict[int, set[int]] = {}
    for (k, _), pieces in zip(flat, outmap):
        for d, tag in pieces:
            if d == dim and k >= 0:
                covered.setdefault(tag, [])
                if k not in covered[tag]:
                    covered[tag].append(k)
            elif d == dim:
                rois.setdefault(tag, set()).add(-1 - k)
    outside = [(dim, tag) for tag in rois if tag not in covered]
    if outside:
        gmsh.model.occ.remove(outside, recursive=True)
        gmsh.model.occ.synchronize()
    inside = {tag: [j in rois.get(tag, ()) for j in range(len(roi_shapes))] for tag in covered}
    return covered, inside


def _fragment(dimtags: list) -> list:
    """Boolean fragment of the given shapes (conforming pieces): the pieces of each input, in order."""
    if len(dimtags) > 1:
        _, outmap = gmsh.model.occ.fragment(dimtags[:1], dimtags[1:])
    else:
        outmap = [[dimtags[0]]]
    gmsh.model.occ.synchronize()
    return outmap


def piece_owners(covered: dict, inputs: list, bodies: list, regions: list, dim: int = 2) -> dict:
    """piece tag -> (body, region) of the fragment's pieces (surfaces in 2D, volumes in 3D):
    the region covering a piece owns it; two bodies, or two regions of one body, on one piece
    are an overlap (the data of the common part would be one region's by the order of the file),
    and a region left without a piece is refused (StudyError at the body's / region's path)."""
    what, left = ("area", "shape") if dim == 2 else ("volume", "solid")
    owner: dict[int, tuple[int, int]] = {}
    for tag in sorted(covered):
        ks = sorted(covered[tag])
        bs = sorted({inputs[k][0] for k in ks})
        if len(bs) > 1:
            raise StudyError(
                f"body {bodies[bs[1]]!r} overlaps body {bodies[bs[0]]!r} "
                f"(common {what} {gmsh.model.occ.getMass(dim, tag):.6g}); bodies may touch but not overlap",
                path=f"scene.bodies.{bodies[bs[1]]}")
        if len(ks) > 1:
            _overlapping_regions(ks, inputs, bodies, regions, what, gmsh.model.occ.getMass(dim, tag))
        owner[tag] = (bs[0], inputs[ks[0]][1])
    used = {rg for _, rg in owner.values()}
    for b, rg, _ in inputs:
        if rg not in used:
            i = [j for j, (bb, _) in enumerate(regions) if bb == bodies[b]].index(rg)
            raise StudyError(
                f"region {regions[rg][1]!r} has no {what} (an empty {left})",
                path=f"scene.bodies.{bodies[b]}.regions.{i}")
    return owner


def _overlapping_regions(ks: list[int], inputs: list, bodies: list, regions: list, what: str, mass: float):
    """StudyError at the later of two regions of one body (`inputs` indices `ks`) that share a piece."""
    (b, first, _), (_, later, _) = inputs[ks[0]], inputs[ks[1]]
    i = [j for j, (bb, _) in enumerate(regions) if bb == bodies[b]].index(later)
    raise StudyError(
        f"region {regions[later][1]!r} overlaps region {regions[first][1]!r} of body {bodies[b]!r} "
        f"(common {what} {mass:.6g}); regions may touch but not overlap: cut the overlap out of one "
        "of them (`minus`)", path=f"scene.bodies.{bodies[b]}.regions.{i}")


def refuse_roi_apart(sm: SceneMesh, label: np.ndarray, b: int, rois: dict[str, np.ndarray]) -> None:
    """StudyError at the embedded region of interest whose cells alone form a piece of body `b`
    (`label`: the connected piece of every node): the mesher cut it out of the body without a
    shared node (a region of interest far smaller than the cells around it), a fault of the
    region of interest, not of the body's shape."""
    cells = np.flatnonzero(sm.cell_body == b)
    piece = label[sm.mesh.t[0, cells]]
    for name, roi in rois.items():
        inside = np.zeros(sm.cell_body.size, dtype=bool)
        inside[roi] = True
        if any(inside[cells[piece == k]].all() for k in np.unique(piece)):
            raise StudyError(f"the region of interest is meshed apart from body {sm.bodies[b]!r} (its cells share "
                             "no node with the rest of the body): it is far smaller than the cells around it; "
                             "enlarge it", path=f"scene.regions_of_interest.{name}")
