"""The boundary facets a scene's supports, contacts and glue claim, checked on the mesh.

The boundary parts of a contact problem are disjoint ([21, §2]): a face is held (Γ_u, Γ_0), in
contact (Γ_c) or glued, and each piece of an interface is one contact or glue. Scenes that break
this solve without complaint and give other physics than the study states, so `check_claims`
refuses them (StudyError at the key path of the later of two entries, or of the support on a
side). Data on one face are never merged: a face and direction takes one support, whatever the
values, so the file says once what holds it:

- two supports holding a common direction on a common face (u_z = 0 and u_z = 1e-3 on one face:
  the elimination averages them; the same value twice too). Supports on different directions
  of one face are fine;
- two prescribed temperatures on a common face (likewise);
- two supports that meet at nodes (a shared edge or corner) and hold a common direction there
  with values that differ, at the nominal data or anywhere in an uncertain box;
- a support holding a contact's slave face along its normal (the support would take the load
  the contact is there to carry: pressure 0), or any direction of a glued side's face (the glue
  would be cut there). A held master side is a rigid obstacle, the classic Signorini problem
  ([21, §2] with u = 0 on the obstacle): the slave rows still act and carry the whole contact
  force into the support's reaction, so it is accepted (the way to model a rigid foundation). Nodes on the
  edge where a supported side meets a contact or glued side (a fault reaching a held boundary)
  are fine: only common faces count;
- two contacts or glues with a common slave face (its nodes constrained twice), or whose
  sides are each other's reversed (the same interface twice): each would carry part of the
  force.
"""
from __future__ import annotations

import numpy as np

from ..errors import StudyError
from ..geometry import tet
from ..geometry.facets import facet_normals, nodal_normals

RANK = 1e-8     # singular values below this x the largest: dependent rows (as wcs.fem.constraints)
ALONG = 1e-6    # |a · n| above this: the held direction a moves a face along its normal n


def check_claims(scene, smesh, varying=frozenset()) -> None:
    """StudyError for the first overlapping claim (see the module doc); `varying`: the dotted
    paths whose values change over the study (uncertain or swept)."""
    _supports_on_common_faces(scene, smesh)
    _temperatures_on_common_faces(scene, smesh)
    _supports_at_common_nodes(scene, smesh, varying)
    _interfaces_twice(scene, smesh)
    _supported_sides(scene, smesh)


def _face_normals(mesh, facets) -> np.ndarray:
    return tet.face_normals(mesh, facets)[0] if mesh.p.shape[0] == 3 else facet_normals(mesh, facets)


def _rows(support, normal: np.ndarray) -> np.ndarray:
    """The directions a support holds where the boundary's normal is `normal`."""
    if support.u is None:
        return normal[None, :]
    return np.eye(normal.size)[[k for k, v in enumerate(support.u) if v is not None]]


def _values(name: str, support) -> list[tuple[float, str]]:
    """(value, dotted path) of each row of `_rows`."""
    if support.u is None:
        return [(support.normal, f"supports.{name}.normal")]
    return [(v, f"supports.{name}.u.{k}") for k, v in enumerate(support.u) if v is not None]


def _dependent(A: np.ndarray) -> np.ndarray:
    """The left null space of A (rows y with y A = 0), by its SVD with the RANK threshold."""
    u, s, _ = np.linalg.svd(A)
    rank = int(np.sum(s > RANK * s[0]))
    return u[:, rank:].T


def _where(mesh, nodes) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in mesh.p[:, int(np.min(nodes))]) + ")"


def _supports_on_common_faces(scene, smesh) -> None:
    mesh, names = smesh.mesh, list(scene.supports)
    what = "faces" if mesh.p.shape[0] == 3 else "edges"
    for j, b in enumerate(names):
        for a in names[:j]:
            common = np.intersect1d(smesh.boundaries[a], smesh.boundaries[b])
            if common.size == 0:
                continue
            normals = _face_normals(mesh, common)
            both = [np.vstack([_rows(scene.supports[a], n), _rows(scene.supports[b], n)]) for n in normals]
            clash = [k for k, A in enumerate(both) if _dependent(A).size]
            if clash:
                raise StudyError(
                    f"supports '{b}' and '{a}' hold the same direction on {len(clash)} common {what} (first "
                    f"node at {_where(mesh, mesh.facets[:, common[clash[0]]])}): a face and direction "
                    "takes one support (two would be averaged, whatever their values); give it once",
                    path=f"scene.supports.{b}")


def _temperatures_on_common_faces(scene, smesh) -> None:
    """Two prescribed temperatures on a common face (averaged by the elimination). Where two
    temperature boundaries only meet (a corner), the node between them takes their mean: the
    data jump at a point, as a heated side next to a cooled one does."""
    mesh, names = smesh.mesh, list(scene.thermal.temperature if scene.thermal else ())
    for j, b in enumerate(names):
        for a in names[:j]:
            common = np.intersect1d(smesh.boundaries[a], smesh.boundaries[b])
            if common.size:
                raise StudyError(
                    f"temperatures on '{b}' and '{a}' are prescribed on {common.size} common boundary facets "
                    f"(first node at {_where(mesh, mesh.facets[:, common[0]])}): a face takes one temperature "
                    "(two would be averaged, whatever their values); give it once",
                    path=f"scene.thermal.temperature.{b}")


def _supports_at_common_nodes(scene, smesh, varying) -> None:
    """Nodes held by several supports whose rows are dependent: their values must agree at
    every data set (y · c = 0 for each left null vector y), or the elimination averages them."""
    mesh, dim = smesh.mesh, smesh.mesh.p.shape[0]
    rows: dict[int, list] = {}
    for name, support in scene.supports.items():
        facets = smesh.boundaries[name]
        if support.u is None:
            nodes, normals = (tet.nodal_normals if dim == 3 else nodal_normals)(mesh, facets)
        else:
            nodes = np.unique(mesh.facets[:, facets])
            normals = np.zeros((nodes.size, dim))
        values = _values(name, support)
        for node, n in zip(nodes.tolist(), normals):
            rows.setdefault(node, []).extend(
                (row, value, path, name) for row, (value, path) in zip(_rows(support, n), values))
    for node, held in rows.items():
        if len({name for *_, name in held}) < 2:
            continue
        A = np.array([row for row, *_ in held])
        c = np.array([value for _, value, _, _ in held])
        for y in _dependent(A):
            on = np.abs(y) > RANK
            paths = [held[i][2] for i in np.flatnonzero(on)]
            moving = [p for p in paths if p in varying]
            if moving or abs(y @ c) > RANK * max(np.abs(c).max(), 1e-300):
                later = max((held[i][3] for i in np.flatnonzero(on)), key=list(scene.supports).index)
                why = (f"and '{moving[0]}' varies over the study" if moving else "with different values")
                names = ", ".join(f"'{n}'" for n in sorted({held[i][3] for i in np.flatnonzero(on)}))
                raise StudyError(
                    f"supports {names} meet at "
                    f"{_where(mesh, [node])} and hold the same direction there ({', '.join(paths)}) {why}: "
                    "the displacement there would be an average; make the values agree or leave the "
                    "direction free in one of them", path=f"scene.supports.{later}")


def _entries(scene) -> list[tuple[str, str, object]]:
    return [("contacts", n, c) for n, c in scene.contacts.items()] + [("glue", n, g) for n, g in scene.glue.items()]


def _interfaces_twice(scene, smesh) -> None:
    faces = smesh.boundaries
    entries = _entries(scene)
    for j, (block, name, spec) in enumerate(entries):
        for block0, name0, spec0 in entries[:j]:
            same = np.intersect1d(faces[spec.slave], faces[spec0.slave]).size
            reversed_ = (np.intersect1d(faces[spec.slave], faces[spec0.master]).size
                         and np.intersect1d(faces[spec.master], faces[spec0.slave]).size)
            if same or reversed_:
                how = ("share part of their slave side" if same
                       else "are the same interface with slave and master reversed")
                raise StudyError(
                    f"{block[:-1] if block == 'contacts' else block} '{name}' and "
                    f"{block0[:-1] if block0 == 'contacts' else block0} '{name0}' {how} (boundaries "
                    f"'{spec.slave}', '{spec0.slave}'): an interface is one contact or glue (twice, each "
                    "would carry part of its force); keep one, or split a side that meets two bodies into "
                    "a boundary per body", path=f"scene.{block}.{name}")


def _supported_sides(scene, smesh) -> None:
    mesh, faces = smesh.mesh, smesh.boundaries
    for block, name, spec in _entries(scene):
        for key in ("slave", "master") if block == "glue" else ("slave",):
            side = getattr(spec, key)
            for sname, support in scene.supports.items():
                common = np.intersect1d(faces[side], faces[sname])
                if common.size == 0:
                    continue
                normals = _face_normals(mesh, common)
                along = [np.abs(_rows(support, n) @ n).max() > ALONG for n in normals]
                if block == "glue" or any(along):
                    k = int(np.argmax(along)) if block != "glue" else 0
                    held = "along its normal" if block != "glue" else "(glue ties every direction)"
                    kind = "contact" if block == "contacts" else "glue"
                    what = "faces" if mesh.p.shape[0] == 3 else "edges"
                    raise StudyError(
                        f"support '{sname}' holds {int(np.sum(along)) if block != 'glue' else common.size} "
                        f"{what} of the {key} side '{side}' of {kind} '{name}' {held} (first node at "
                        f"{_where(mesh, mesh.facets[:, common[k]])}): a face is either supported or "
                        f"in the {kind} (it would carry nothing there); hold the body elsewhere",
                        path=f"scene.supports.{sname}")
