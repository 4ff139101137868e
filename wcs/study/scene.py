"""The scene of a study: loaded (inline, or a file relative to the study file; a material
library by name), resolved (regions named, a mesh file's physical groups turned into regions and
boundaries) and checked: every name a scene key gives exists, contacts join two bodies, a
thermal scene's materials conduct."""
from __future__ import annotations

from pathlib import Path

from pydantic import ValidationError

from ..errors import StudyError
from ..options import did_you_mean as _did_you_mean
from ..scene.spec import GroupBoundary, Material, Scene
from .schema import _LIBRARY, _SCENE, _SCENE3D
from .source import _locate, _read_yaml, _shown_key, _Source


def _load_scene(raw, study_src: _Source) -> tuple[Scene, _Source, list[tuple[Path, str]], list[str]]:
    """The validated scene, where it lives, the extra files it came from, and notes on it."""
    extra = []
    src = _Source(study_src.file, ("scene",), study_src.folder)
    if isinstance(raw, str):
        path = _locate(raw, study_src, "scene")
        raw, text = _read_yaml(path)
        src = _Source(path)
        extra.append((path, text))
    if isinstance(raw, dict) and isinstance(raw.get("materials"), str):
        raw = dict(raw)
        raw["materials"], library = _load_materials(raw["materials"], src)   # validated Material models
        extra.append(library)
    three = isinstance(raw, dict) and raw.get("dimension") == 3
    try:
        scene = src.validate(_SCENE3D if three else _SCENE, raw)
    except StudyError:
        if isinstance(raw, dict) and "dimension" not in raw and _reads_as_3d(raw):
            raise src.error(("dimension",), "required key is missing: the scene is a 3D one (its shapes, "
                                            "vectors and selectors are those of dimension: 3)") from None
        raise
    notes = []
    if scene.mesh.file is not None:   # regions come from the file's physical groups
        from ..scene.meshfile import prepare_scene   # scikit-fem loads only for a scene meshed by a file
        file, names, groups, notes = prepare_scene(scene, src.base, src.error)
        scene = scene.model_copy(update={
            "mesh": scene.mesh.model_copy(update={"file": file}),
            "bodies": {b: _named(body, names[b]) for b, body in scene.bodies.items()},
            "boundaries": scene.boundaries | {piece: GroupBoundary(group=group, body=body)
                                              for piece, group, body in groups}})
    else:
        _require_shapes(scene, src)
        scene = scene.model_copy(update={"bodies": {
            b: _named(body, [r.name or f"{b}_{i}" for i, r in enumerate(body.regions)])
            for b, body in scene.bodies.items()}})
    return scene, src, extra, notes


def _reads_as_3d(raw: dict) -> bool:
    """Whether a scene without `dimension` is a valid 3D scene (a 2D scene is the default)."""
    try:
        _SCENE3D.validate_python({**raw, "dimension": 3})
    except ValidationError:
        return False
    return True


def _named(body, names: list[str]):
    """The body with its regions named `names` (in order)."""
    return body.model_copy(update={"regions": [r.model_copy(update={"name": n}) for r, n in zip(body.regions, names)]})


def _require_shapes(scene: Scene, src: _Source) -> None:
    for name, body in scene.bodies.items():
        for i, region in enumerate(body.regions):
            if region.shape is None:
                raise src.error(("bodies", name, "regions", i, "shape"),
                                "required key is missing (a region needs a shape unless the "
                                "scene's mesh is a file: `mesh: {file: ...}`)")


def _load_materials(name: str, src: _Source) -> tuple[dict[str, Material], tuple[Path, str]]:
    path = _locate(name, src, "materials", shipped=True)
    raw, text = _read_yaml(path)
    return _Source(path).validate(_LIBRARY, raw), (path, text)


def _region_names(scene: Scene) -> list[str]:
    return [r.name for body in scene.bodies.values() for r in body.regions]


def _used_materials(scene: Scene) -> list[str]:
    """The materials the regions use, each once, in scene order."""
    return list(dict.fromkeys(r.material for body in scene.bodies.values() for r in body.regions))


def _require(name: str, known, what: str, src: _Source, path) -> None:
    if name not in known:
        raise src.error(path, f"unknown {what} '{_shown_key(name)}'{_did_you_mean(name, known)}")


def _check_regions(scene: Scene, src: _Source) -> None:
    """Materials exist; region names are unique and differ from other bodies' names."""
    seen = set()
    for body, spec in scene.bodies.items():
        for i, region in enumerate(spec.regions):
            path = ("bodies", body, "regions", i)
            _require(region.material, scene.materials, "material", src, path + ("material",))
            name = region.name
            if name in seen:
                raise src.error(path + ("name",), f"region name '{name}' is used twice")
            own_name = name == body and len(spec.regions) == 1
            if name in scene.bodies and not own_name:
                raise src.error(path + ("name",), f"region name '{name}' is also a body's name")
            seen.add(name)


def _check_references(scene: Scene, src: _Source) -> None:
    """Every boundary, body and region a scene key refers to exists."""
    bodies, boundaries = scene.bodies, scene.boundaries
    parts = set(bodies) | set(_region_names(scene))
    for name, spec in boundaries.items():
        if spec.body is not None:
            _require(spec.body, bodies, "body", src, ("boundaries", name, "body"))
    for block in ("supports", "loads"):
        for name in getattr(scene, block):
            _require(name, boundaries, "boundary", src, (block, name))
    for name in scene.body_forces:
        _require(name, parts, "body or region", src, ("body_forces", name))
    _check_mesh_references(scene, src)
    for name, roi in scene.regions_of_interest.items():
        path = ("regions_of_interest", name)
        if roi.boundary is not None:
            _require(roi.boundary, boundaries, "boundary", src, path + ("boundary",))
        if roi.body is not None:
            _require(roi.body, bodies, "body", src, path + ("body",))


def _check_mesh_references(scene: Scene, src: _Source) -> None:
    """The boundaries refine zones name exist; a mesh file leaves no size to the bodies."""
    bodies, boundaries = scene.bodies, scene.boundaries
    for i, refinement in enumerate(scene.mesh.refine):
        if refinement.boundary is not None:
            _require(refinement.boundary, boundaries, "boundary", src, ("mesh", "refine", i, "boundary"))
        if getattr(refinement, "body", None) is not None:     # 3D: a zone of one body
            _require(refinement.body, bodies, "body", src, ("mesh", "refine", i, "body"))
    for body, spec in bodies.items():
        for i, refinement in enumerate(spec.mesh.refine if spec.mesh else []):
            if refinement.boundary is not None:
                _require(refinement.boundary, boundaries, "boundary", src,
                         ("bodies", body, "mesh", "refine", i, "boundary"))
        if scene.mesh.file is not None:     # (a body's own mesh: refused by prepare_scene)
            for i, region in enumerate(spec.regions):
                if region.mesh is not None:
                    raise src.error(("bodies", body, "regions", i, "mesh"), "the scene's mesh is a "
                                    "file: a region cannot have its own mesh size")


def _check_contacts(scene: Scene, src: _Source) -> None:
    """Both sides of a contact (or a glued interface) are boundaries, of two different
    bodies when they say which; a side is not both contact and glue."""
    boundaries = scene.boundaries
    glued = {}
    for name, glue in scene.glue.items():
        for side in (glue.slave, glue.master):
            glued.setdefault(side, name)
    for name, contact in scene.contacts.items():
        for key in ("slave", "master"):
            side = getattr(contact, key)
            if side in glued:
                raise src.error(("contacts", name, key), f"boundary '{side}' is glued "
                                f"(glue '{glued[side]}'); a side is either in contact or glued")
    blocks = [("contacts", n, c) for n, c in scene.contacts.items()]
    blocks += [("glue", n, g) for n, g in scene.glue.items()]
    for block, name, contact in blocks:
        path = (block, name)
        for key in ("slave", "master"):
            _require(getattr(contact, key), boundaries, "boundary", src, path + (key,))
        slave, master = boundaries[contact.slave], boundaries[contact.master]
        if contact.slave == contact.master:
            raise src.error(path + ("master",), "slave and master are the same boundary")
        if slave.body is not None and slave.body == master.body:
            raise src.error(path + ("master",),
                            f"slave and master both belong to body '{slave.body}'; "
                            f"a {'contact' if block == 'contacts' else 'glue'} joins two different bodies")


def _check_thermal(scene: Scene, src: _Source) -> list[str]:
    """Thermal references exist and used materials conduct; notes on materials without expansion."""
    thermal = scene.thermal
    if thermal is None:
        return []
    for name in thermal.temperature:
        _require(name, scene.boundaries, "boundary", src, ("thermal", "temperature", name))
    parts = set(scene.bodies) | set(_region_names(scene))
    for name in thermal.sources:
        _require(name, parts, "body or region", src, ("thermal", "sources", name))
    notes = []
    for name in _used_materials(scene):
        material = scene.materials[name]
        if material.conductivity is None:
            raise src.error(("materials", name),
                            "needs 'conductivity' because the scene has a thermal block")
        if material.expansion is None:
            notes.append(f"material '{name}' has no 'expansion': no thermal strain in it")
    return notes
