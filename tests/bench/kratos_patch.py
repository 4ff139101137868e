"""Kratos side of tests/bench/test_bench_kratos.py: solve the block-on-block patch of a gmsh
MSH 2.2 file (tests/bench/kratos_mesh.py) with Kratos' mortar ALM frictionless contact and
AMGCL, and print one JSON line: unknowns, contact nodes, the normal contact pressure on the
slave face (at the node nearest the face's centre, max and min; each | |LAGRANGE_MULTIPLIER_CONTACT_PRESSURE| x SCALE_FACTOR), the lowest
displacement of the loaded top (exact: -2.5e-4 m), the total reaction at the base
(the applied 2 MPa on 1 m^2 is 2 MN) and the analysis' wall seconds.

Run by the interpreter of a venv with KratosMultiphysics 10.4.4 (+ Structural-, Contact-
StructuralMechanics-, LinearSolversApplication):  python kratos_patch.py MESH.msh WORKDIR
Materials and loads are those of studies/validation/block-on-block-3d.yaml (nominal)."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

MATERIALS = {"base": (2.0e10, 0.25), "block": (5.0e9, 0.35)}
PRESSURE = 2.0e6


def read_msh22(path: Path):
    """Nodes {id: xyz}, physical names {tag: name}, and per physical tag the list of elements
    (node-id tuples): 4-node tetrahedra (type 4) and 3-node triangles (type 2)."""
    lines = path.read_text().splitlines()
    i = lines.index("$PhysicalNames")
    names = {}
    for line in lines[i + 2:i + 2 + int(lines[i + 1])]:
        dim, tag, name = line.split(maxsplit=2)
        names[int(tag)] = name.strip('"')
    i = lines.index("$Nodes")
    nodes = {}
    for line in lines[i + 2:i + 2 + int(lines[i + 1])]:
        k, x, y, z = line.split()
        nodes[int(k)] = (float(x), float(y), float(z))
    i = lines.index("$Elements")
    groups = {name: [] for name in names.values()}
    for line in lines[i + 2:i + 2 + int(lines[i + 1])]:
        v = [int(s) for s in line.split()]
        kind, ntags = v[1], v[2]
        if kind in (2, 4):
            groups[names[v[3]]].append(tuple(v[3 + ntags:]))
    return nodes, groups


def oriented(tri, nodes, sign: float):
    """The triangle ordered so that its normal's z has the given sign (+1 up, -1 down), or, for
    a side face, pointing away from the box's inside (0.5, 0.5)."""
    a, b, c = (nodes[k] for k in tri)
    n = [(b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]),
         (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]),
         (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])]
    return tri if n[2] * sign > 0 else (tri[0], tri[2], tri[1])


def write_mdpa(msh: Path, out: Path) -> dict:
    """The model: the block's nodes on the contact face doubled (the file's bodies share them)."""
    nodes, g = read_msh22(msh)
    base_nodes = {k for t in g["base"] for k in t}
    block_nodes = {k for t in g["block"] for k in t}
    shared = base_nodes & block_nodes
    top = max(nodes) + 1
    copy = {k: top + j for j, k in enumerate(sorted(shared))}
    coords = dict(nodes)
    coords.update({copy[k]: nodes[k] for k in shared})
    on_block = lambda t: tuple(copy.get(k, k) for k in t)
    parts = {
        "base": ([t for t in g["base"]], []),
        "block": ([on_block(t) for t in g["block"]], []),
    }
    surf = {
        "base_bottom": [oriented(t, coords, -1) for t in g["base_bottom"]],
        "block_top": [oriented(on_block(t), coords, +1) for t in g["block_top"]],
        "master": [oriented(t, coords, +1) for t in g["base:base_top"]],
        "slave": [oriented(on_block(t), coords, -1) for t in g["block:block_bottom"]],
    }
    x0 = {k for t in g["x0"] for k in t}
    y0 = {k for t in g["y0"] for k in t}
    x0 |= {copy[k] for k in x0 & shared}
    y0 |= {copy[k] for k in y0 & shared}
    w = ["Begin ModelPartData", "End ModelPartData"]
    for pid in (1, 2):
        w += [f"Begin Properties {pid}", "End Properties"]
    w += ["Begin Nodes"] + [f"{k} {x!r} {y!r} {z!r}" for k, (x, y, z) in sorted(coords.items())] + ["End Nodes"]
    eid, elems = 1, {}
    for pid, name in ((1, "base"), (2, "block")):
        w.append("Begin Elements SmallDisplacementElement3D4N")
        elems[name] = []
        for t in parts[name][0]:
            w.append(f"{eid} {pid} {' '.join(map(str, t))}")
            elems[name].append(eid)
            eid += 1
        w.append("End Elements")
    cid, conds = 1, {}
    for name, ctype, pid in (("block_top", "SurfaceLoadCondition3D3N", 2), ("master", "SurfaceCondition3D3N", 1),
                             ("slave", "SurfaceCondition3D3N", 2)):
        w.append(f"Begin Conditions {ctype}")
        conds[name] = []
        for t in surf[name]:
            w.append(f"{cid} {pid} {' '.join(map(str, t))}")
            conds[name].append(cid)
            cid += 1
        w.append("End Conditions")

    def sub(name, nset, eids=(), cids=()):
        w.extend([f"Begin SubModelPart {name}", "Begin SubModelPartNodes", *map(str, sorted(nset)),
                  "End SubModelPartNodes", "Begin SubModelPartElements", *map(str, eids), "End SubModelPartElements",
                  "Begin SubModelPartConditions", *map(str, cids), "End SubModelPartConditions", "End SubModelPart"])

    sub("Parts_base", base_nodes, elems["base"])
    sub("Parts_block", {copy.get(k, k) for k in block_nodes}, elems["block"])
    sub("DISP_base_bottom", {k for t in surf["base_bottom"] for k in t})
    sub("DISP_x0", x0)
    sub("DISP_y0", y0)
    sub("Load_block_top", {k for t in surf["block_top"] for k in t}, cids=conds["block_top"])
    sub("Contact_master", {k for t in surf["master"] for k in t}, cids=conds["master"])
    sub("Contact_slave", {k for t in surf["slave"] for k in t}, cids=conds["slave"])
    out.write_text("\n".join(w) + "\n")
    return {"unknowns": 3 * len(coords), "contact_nodes": len(shared)}


def fix(part: str, comp: list[bool]) -> dict:
    return {"python_module": "assign_vector_variable_process", "kratos_module": "KratosMultiphysics",
            "Parameters": {"model_part_name": f"Structure.{part}", "variable_name": "DISPLACEMENT",
                           "constrained": comp, "value": [0.0 if c else None for c in comp], "interval": [0.0, "End"]}}


def parameters(name: str) -> dict:
    amgcl = {"solver_type": "amgcl", "smoother_type": "ilu0", "krylov_type": "gmres", "coarsening_type": "aggregation",
             "max_iteration": 500, "tolerance": 1e-8, "scaling": False, "verbosity": 0}
    return {
        "problem_data": {"problem_name": name, "parallel_type": "OpenMP", "echo_level": 0,
                         "start_time": 0.0, "end_time": 1.0},
        "solver_settings": {
            "solver_type": "Static", "model_part_name": "Structure", "domain_size": 3, "echo_level": 0,
            "analysis_type": "non_linear",
            "model_import_settings": {"input_type": "mdpa", "input_filename": name},
            "material_import_settings": {"materials_filename": "materials.json"},
            "time_stepping": {"time_step": 1.0},
            "contact_settings": {"mortar_type": "ALMContactFrictionless",     # to 1e-8 as wcs solves
                                 "contact_displacement_relative_tolerance": 1e-8,
                                 "contact_residual_relative_tolerance": 1e-8},
            "convergence_criterion": "contact_residual_criterion",
            "displacement_relative_tolerance": 1e-8, "displacement_absolute_tolerance": 1e-12,
            "residual_relative_tolerance": 1e-8, "residual_absolute_tolerance": 1e-12,
            "max_iteration": 30, "linear_solver_settings": amgcl},
        "processes": {
            "constraints_process_list": [fix("DISP_base_bottom", [False, False, True]),
                                         fix("DISP_x0", [True, False, False]), fix("DISP_y0", [False, True, False])],
            "loads_process_list": [{
                "python_module": "assign_scalar_variable_to_conditions_process", "kratos_module": "KratosMultiphysics",
                "Parameters": {"model_part_name": "Structure.Load_block_top", "variable_name": "POSITIVE_FACE_PRESSURE",
                               "value": PRESSURE, "interval": [0.0, "End"]}}],
            "contact_process_list": [{
                "python_module": "alm_contact_process",
                "kratos_module": "KratosMultiphysics.ContactStructuralMechanicsApplication",
                "process_name": "ALMContactProcess",
                "Parameters": {"model_part_name": "Structure",
                               "contact_model_part": {"0": ["Contact_slave", "Contact_master"]},
                               "assume_master_slave": {"0": ["Contact_slave"]},
                               "contact_type": "Frictionless"}}]},
        "output_processes": {}}


def materials() -> dict:
    return {"properties": [{"model_part_name": f"Structure.Parts_{name}", "properties_id": pid,
                            "Material": {"constitutive_law": {"name": "LinearElastic3DLaw"},
                                         "Variables": {"YOUNG_MODULUS": E, "POISSON_RATIO": nu, "DENSITY": 1.0},
                                         "Tables": {}}}
                           for pid, (name, (E, nu)) in enumerate(MATERIALS.items(), start=1)]}


def main(msh: Path, work: Path) -> dict:
    import os
    work.mkdir(parents=True, exist_ok=True)
    os.chdir(work)
    t0 = time.perf_counter()
    info = write_mdpa(msh, work / "patch.mdpa")
    (work / "materials.json").write_text(json.dumps(materials()))
    t_mdpa = time.perf_counter() - t0
    import KratosMultiphysics as KM
    import KratosMultiphysics.StructuralMechanicsApplication  # noqa: F401
    import KratosMultiphysics.ContactStructuralMechanicsApplication as CSMA
    import KratosMultiphysics.LinearSolversApplication  # noqa: F401
    from KratosMultiphysics.StructuralMechanicsApplication.structural_mechanics_analysis import \
        StructuralMechanicsAnalysis    # dispatches to the contact solver by `contact_settings`
    KM.Logger.GetDefaultOutput().SetSeverity(KM.Logger.Severity.WARNING)
    model = KM.Model()
    t1 = time.perf_counter()
    StructuralMechanicsAnalysis(model, KM.Parameters(json.dumps(parameters("patch")))).Run()
    t_solve = time.perf_counter() - t1
    mp = model["Structure"]
    scale = mp.ProcessInfo[KM.SCALE_FACTOR]          # the ALM's multipliers are stored divided by it
    slave = list(mp.GetSubModelPart("Contact_slave").Nodes)
    lm = [abs(n.GetSolutionStepValue(CSMA.LAGRANGE_MULTIPLIER_CONTACT_PRESSURE)) * scale for n in slave]
    centre = min(range(len(slave)), key=lambda i: (slave[i].X0 - 0.5) ** 2 + (slave[i].Y0 - 0.5) ** 2)
    reaction = sum(n.GetSolutionStepValue(KM.REACTION_Z) for n in mp.GetSubModelPart("DISP_base_bottom").Nodes)
    uz = min(n.GetSolutionStepValue(KM.DISPLACEMENT_Z) for n in mp.GetSubModelPart("Load_block_top").Nodes)
    return {**info, "p_centre": lm[centre], "p_max": max(lm), "p_min": min(lm), "reaction_z": reaction, "top_uz_min": uz, "newton": mp.ProcessInfo[KM.NL_ITERATION_NUMBER],
            "mdpa_s": round(t_mdpa, 2), "analysis_s": round(t_solve, 2)}


if __name__ == "__main__":
    print(json.dumps(main(Path(sys.argv[1]).resolve(), Path(sys.argv[2]).resolve())))
