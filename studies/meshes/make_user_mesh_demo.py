"""Write studies/meshes/two-blocks.msh: the mesh of studies/user-mesh-demo.yaml.

A steel base [0, 2] x [0, 1] (two regions: `base:lower`, `base:upper`, split at
y = 0.5) and a rubber pad [0.5, 1.5] x [1, 1.5] on top, meshed by gmsh with
physical groups named by the wcs rule (README, "Scenes from your own mesh"):

* 2D: `base:lower`, `base:upper`, `pad`          -> bodies and their regions
* 1D: `base_bottom`, `pad_top`, `pad_left`       -> boundary pieces
* 1D: `base:base_top`, `pad:pad_bottom`          -> the SAME curve (y = 1, 0.5 <= x <= 1.5)
  in two groups, one per body: the two sides of the contact.

The pad and the base share the nodes of that curve; wcs gives each body its own copy.

    python studies/meshes/make_user_mesh_demo.py      # rewrites two-blocks.msh
"""
from pathlib import Path

import gmsh

OUT = Path(__file__).with_name("two-blocks.msh")


def main(out: Path = OUT, size: float = 0.08) -> None:
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add("two-blocks")
    geo = gmsh.model.geo
    pts = {xy: geo.addPoint(*xy, 0.0, size) for xy in [
        (0, 0), (2, 0), (2, 0.5), (0, 0.5), (2, 1), (1.5, 1), (0.5, 1), (0, 1),
        (1.5, 1.5), (0.5, 1.5)]}
    P = pts.__getitem__
    line = lambda a, b: geo.addLine(P(a), P(b))
    bottom = line((0, 0), (2, 0))
    r_low = line((2, 0), (2, 0.5))
    mid = line((2, 0.5), (0, 0.5))
    l_low = line((0, 0.5), (0, 0))
    r_up = line((2, 0.5), (2, 1))
    top_r = line((2, 1), (1.5, 1))
    contact = line((1.5, 1), (0.5, 1))          # shared by base and pad
    top_l = line((0.5, 1), (0, 1))
    l_up = line((0, 1), (0, 0.5))
    pad_r = line((1.5, 1), (1.5, 1.5))
    pad_t = line((1.5, 1.5), (0.5, 1.5))
    pad_l = line((0.5, 1.5), (0.5, 1))
    lower = geo.addPlaneSurface([geo.addCurveLoop([bottom, r_low, mid, l_low])])
    upper = geo.addPlaneSurface([geo.addCurveLoop([-mid, r_up, top_r, contact, top_l, l_up])])
    pad = geo.addPlaneSurface([geo.addCurveLoop([-contact, pad_r, pad_t, pad_l])])
    geo.synchronize()
    for dim, tags, name in [
        (2, [lower], "base:lower"), (2, [upper], "base:upper"), (2, [pad], "pad"),
        (1, [bottom], "base_bottom"), (1, [pad_t], "pad_top"), (1, [pad_l], "pad_left"),
        (1, [contact], "base:base_top"), (1, [contact], "pad:pad_bottom"),
    ]:
        gmsh.model.addPhysicalGroup(dim, tags, name=name)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(out))
    gmsh.finalize()


if __name__ == "__main__":
    main()
    print(f"wrote {OUT}")
