"""The 3D block-on-block patch (studies/validation/block-on-block-3d.yaml) as one gmsh file that
wcs and Kratos both read: two boxes fragmented (matching faces at z = 0), the contact band
|z| < 2 face meshed at `face`, the rest at 0.2. Written as MSH 2.2 ASCII so that the Kratos
driver (tests/bench/kratos_patch.py, run in Kratos' own venv without gmsh) parses it itself.

Physical groups: 3D `base`, `block`; 2D `base_bottom`, `block_top`, `x0`, `y0` (both bodies'
faces) and the contact face twice, `base:base_top` and `block:block_bottom`."""
from __future__ import annotations

import gmsh

SIZE = 0.2


def _faces(axis: int, value: float) -> list[int]:
    """Tags of the surfaces lying in the plane x[axis] = value."""
    out = []
    for _, tag in gmsh.model.getEntities(2):
        box = gmsh.model.getBoundingBox(2, tag)
        if abs(box[axis] - value) < 1e-6 and abs(box[axis + 3] - value) < 1e-6:
            out.append(tag)
    return out


def write_patch_msh(path, face: float) -> None:
    gmsh.initialize(["-nt", "1"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        base, block = occ.addBox(0, 0, -0.5, 1, 1, 0.5), occ.addBox(0, 0, 0, 1, 1, 0.5)
        _, pieces = occ.fragment([(3, base)], [(3, block)])
        occ.synchronize()
        base, block = pieces[0][0][1], pieces[1][0][1]
        contact = _faces(2, 0.0)
        for dim, tags, name in [(3, [base], "base"), (3, [block], "block"), (2, _faces(2, -0.5), "base_bottom"),
                                (2, _faces(2, 0.5), "block_top"), (2, _faces(0, 0.0), "x0"), (2, _faces(1, 0.0), "y0"),
                                (2, contact, "base:base_top"), (2, contact, "block:block_bottom")]:
            gmsh.model.addPhysicalGroup(dim, tags, name=name)
        field = gmsh.model.mesh.field
        box = field.add("Box")
        for key, value in dict(VIn=face, VOut=SIZE, XMin=-1, XMax=2, YMin=-1, YMax=2,
                               ZMin=-2 * face, ZMax=2 * face).items():
            field.setNumber(box, key, value)
        field.setAsBackgroundMesh(box)
        for key, value in {"Mesh.MeshSizeExtendFromBoundary": 0, "Mesh.MeshSizeFromPoints": 0,
                           "Mesh.Algorithm3D": 1, "Mesh.MshFileVersion": 2.2}.items():
            gmsh.option.setNumber(key, value)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def write_hertz_msh(path, h: float) -> None:
    """The 3D Hertz quarter model of studies/validation/hertz-3d.yaml: the lower quarter of the
    hemisphere (R = 1, centre (0, 0, 1)) on the quarter block [0, 1]^2 x [-1, 0], each body meshed
    on its own (nonmatching faces; they touch at the origin), `h` within 0.13 of the origin
    growing by 0.3 per unit distance up to 0.25. Groups: 3D `sphere`, `block`; 2D `sphere_top`,
    `sphere:sphere_surface`, `block:block_top`, `block_bottom`, `x0`, `y0`."""
    gmsh.initialize(["-nt", "1"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        ball = occ.addSphere(0, 0, 1, 1)
        quarter = occ.addBox(0, 0, 0, 1, 1, 1)
        (sphere,), _ = occ.intersect([(3, ball)], [(3, quarter)])
        block = occ.addBox(0, 0, -1, 1, 1, 1)
        occ.synchronize()
        sphere = sphere[1]
        curved = [t for _, t in gmsh.model.getBoundary([(3, sphere)], oriented=False)
                  if gmsh.model.getType(2, t) == "Sphere"]
        block_faces = {t for _, t in gmsh.model.getBoundary([(3, block)], oriented=False)}
        sphere_faces = {t for _, t in gmsh.model.getBoundary([(3, sphere)], oriented=False)}
        on = lambda faces, axis, value: [t for t in faces if _in_plane(t, axis, value)]
        for dim, tags, name in [(3, [sphere], "sphere"), (3, [block], "block"),
                                (2, on(sphere_faces, 2, 1.0), "sphere_top"), (2, curved, "sphere:sphere_surface"),
                                (2, on(block_faces, 2, 0.0), "block:block_top"),
                                (2, on(block_faces, 2, -1.0), "block_bottom"),
                                (2, on(block_faces, 0, 0.0) + on(sphere_faces, 0, 0.0), "x0"),
                                (2, on(block_faces, 1, 0.0) + on(sphere_faces, 1, 0.0), "y0")]:
            gmsh.model.addPhysicalGroup(dim, tags, name=name)
        field = gmsh.model.mesh.field
        ball = field.add("Ball")                  # h inside, growing linearly by 0.3 to 0.25 outside
        for key, value in dict(XCenter=0, YCenter=0, ZCenter=0, Radius=0.13, Thickness=(0.25 - h) / 0.3,
                               VIn=h, VOut=0.25).items():
            field.setNumber(ball, key, value)
        field.setAsBackgroundMesh(ball)
        for key, value in {"Mesh.MeshSizeExtendFromBoundary": 0, "Mesh.MeshSizeFromPoints": 0,
                           "Mesh.MeshSizeFromCurvature": 0, "Mesh.Algorithm3D": 1,
                           "Mesh.MshFileVersion": 2.2}.items():
            gmsh.option.setNumber(key, value)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def _in_plane(tag: int, axis: int, value: float) -> bool:
    box = gmsh.model.getBoundingBox(2, tag)
    return abs(box[axis] - value) < 1e-6 and abs(box[axis + 3] - value) < 1e-6


if __name__ == "__main__":
    import sys
    (write_hertz_msh if "hertz" in sys.argv[1] else write_patch_msh)(sys.argv[1], float(sys.argv[2]))
