"""Kratos side of tests/bench/test_bench_kratos.py: solve a two-body contact case of a gmsh
MSH 2.2 file (tests/bench/kratos_mesh.py) with Kratos' mortar ALM frictionless contact and
AMGCL, and print one JSON line: unknowns, contact nodes, the normal contact pressure on the
slave face (at the slave node nearest the case's centre, max and min; each
|LAGRANGE_MULTIPLIER_CONTACT_PRESSURE| x SCALE_FACTOR), the lowest z-displacement of the loaded
face, the total z-reaction of the held face, the Newton iterations (not converged when it
stopped at MAX_NEWTON: Kratos then goes on without an error) and the analysis' wall seconds.

Run by the interpreter of a venv with KratosMultiphysics 10.4.4 (+ Structural-, Contact-
StructuralMechanics-, LinearSolversApplication):  python kratos_patch.py CASE MESH.msh WORKDIR
with CASE `patch` (studies/validation/block-on-block-3d.yaml) or `hertz`
(studies/validation/hertz-3d.yaml), nominal materials and loads of those studies."""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

CASES = {
    "patch": dict(bodies={"base": (2.0e10, 0.25, (0.5, 0.5, -0.25)), "block": (5.0e9, 0.35, (0.5, 0.5, 0.25))},
                  fixes={"base_bottom": [False, False, True], "x0": [True, False, False],
                         "y0": [False, True, False]},
                  load=("block_top", 2.0e6), slave="block:block_bottom", master="base:base_top",
                  held="base_bottom", centre=(0.5, 0.5), steps=1),
    "hertz": dict(bodies={"sphere": (2.0e11, 0.3, (0.2, 0.2, 0.7)), "block": (2.0e11, 0.3, (0.5, 0.5, -0.5))},
                  fixes={"block_bottom": [False, False, True], "x0": [True, False, False],
                         "y0": [False, True, False]},
                  load=("sphere_top", 4.6624e7), slave="sphere:sphere_surface", master="block:block_top",
                  held="block_bottom", centre=(0.0, 0.0), steps=5),
}


MAX_NEWTON = 30             # per load step
# The load is ramped over `steps` equal load steps (time 0 to 1). The patch is linear: 1 step. Hertz
# (the sphere held along z by the contact alone, touching at one point) in 1 step diverged (a/24:
# the Newton residual blew up, "Zero pivot in ILU"; a/8: unconverged after MAX_NEWTON steps); in 5
# steps it converges at a/8 (the Newton steps and the axis pressure: bench_kratos_hertz*'s Kratos rows).


def read_msh22(path: Path):
    """Nodes {id: xyz} and per physical group name its elements (node-id tuples): 4-node
    tetrahedra (type 4) and 3-node triangles (type 2)."""
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


def outward(tri, coords, inside):
    """The triangle ordered so that its normal points away from a point inside its (convex) body."""
    a, b, c = (coords[k] for k in tri)
    u, v = [b[i] - a[i] for i in range(3)], [c[i] - a[i] for i in range(3)]
    n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    return tri if sum(n[i] * (a[i] - inside[i]) for i in range(3)) > 0 else (tri[0], tri[2], tri[1])


def body_of(group: str, case: dict) -> str:
    """The body a 2D group belongs to: `BODY:NAME`, or the body whose name prefixes it."""
    return group.split(":")[0] if ":" in group else next(b for b in case["bodies"] if group.startswith(b))


def write_mdpa(msh: Path, case: dict, out: Path) -> dict:
    """The model; nodes the file's bodies share are doubled for the slave's body."""
    nodes, g = read_msh22(msh)
    names = list(case["bodies"])
    owned = {b: {k for t in g[b] for k in t} for b in names}
    slave_body = body_of(case["slave"], case)
    shared = owned[names[0]] & owned[names[1]]
    top = max(nodes) + 1
    copy = {k: top + j for j, k in enumerate(sorted(shared))}
    coords = {**nodes, **{copy[k]: nodes[k] for k in shared}}
    ids = {b: (lambda t: tuple(copy.get(k, k) for k in t)) if b == slave_body else (lambda t: t) for b in names}
    faces = {}
    for group in (case["load"][0], case["slave"], case["master"]):
        b = body_of(group, case)
        faces[group] = [outward(ids[b](t), coords, case["bodies"][b][2]) for t in g[group]]
    w = ["Begin ModelPartData", "End ModelPartData"]
    for pid in (1, 2):
        w += [f"Begin Properties {pid}", "End Properties"]
    w += ["Begin Nodes"] + [f"{k} {x!r} {y!r} {z!r}" for k, (x, y, z) in sorted(coords.items())] + ["End Nodes"]
    eid, elems = 1, {}
    for pid, b in enumerate(names, start=1):
        w.append("Begin Elements SmallDisplacementElement3D4N")
        elems[b] = list(range(eid, eid + len(g[b])))
        w += [f"{e} {pid} {' '.join(map(str, ids[b](t)))}" for e, t in zip(elems[b], g[b])]
        eid += len(g[b])
        w.append("End Elements")
    cid, conds = 1, {}
    for group, ctype in ((case["load"][0], "SurfaceLoadCondition3D3N"), (case["slave"], "SurfaceCondition3D3N"),
                         (case["master"], "SurfaceCondition3D3N")):
        pid = names.index(body_of(group, case)) + 1
        w.append(f"Begin Conditions {ctype}")
        conds[group] = list(range(cid, cid + len(faces[group])))
        w += [f"{c} {pid} {' '.join(map(str, t))}" for c, t in zip(conds[group], faces[group])]
        cid += len(faces[group])
        w.append("End Conditions")

    def sub(name, nset, eids=(), cids=()):
        w.extend([f"Begin SubModelPart {name}", "Begin SubModelPartNodes", *map(str, sorted(nset)),
                  "End SubModelPartNodes", "Begin SubModelPartElements", *map(str, eids), "End SubModelPartElements",
                  "Begin SubModelPartConditions", *map(str, cids), "End SubModelPartConditions", "End SubModelPart"])

    for b in names:
        sub(f"Parts_{b}", {k for t in g[b] for k in ids[b](t)}, elems[b])
    for group in case["fixes"]:          # on every body: the file's nodes and their copies
        nset = {k for t in g[group] for k in t}
        sub(f"DISP_{group}", nset | {copy[k] for k in nset & shared})
    sub("Load", {k for t in faces[case["load"][0]] for k in t}, cids=conds[case["load"][0]])
    sub("Contact_slave", {k for t in faces[case["slave"]] for k in t}, cids=conds[case["slave"]])
    sub("Contact_master", {k for t in faces[case["master"]] for k in t}, cids=conds[case["master"]])
    out.write_text("\n".join(w) + "\n")
    return {"unknowns": 3 * len(coords), "contact_nodes": len({k for t in g[case["slave"]] for k in t})}


def fix(group: str, comp: list[bool]) -> dict:
    return {"python_module": "assign_vector_variable_process", "kratos_module": "KratosMultiphysics",
            "Parameters": {"model_part_name": f"Structure.DISP_{group}", "variable_name": "DISPLACEMENT",
                           "constrained": comp, "value": [0.0 if c else None for c in comp], "interval": [0.0, "End"]}}


def parameters(name: str, case: dict) -> dict:
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
            "time_stepping": {"time_step": 1.0 / case["steps"]},
            "contact_settings": {"mortar_type": "ALMContactFrictionless",     # to 1e-8 as wcs solves
                                 "contact_displacement_relative_tolerance": 1e-8,
                                 "contact_residual_relative_tolerance": 1e-8},
            "convergence_criterion": "contact_residual_criterion",
            "displacement_relative_tolerance": 1e-8, "displacement_absolute_tolerance": 1e-12,
            "residual_relative_tolerance": 1e-8, "residual_absolute_tolerance": 1e-12,
            "max_iteration": MAX_NEWTON, "linear_solver_settings": amgcl},
        "processes": {
            "constraints_process_list": [fix(group, comp) for group, comp in case["fixes"].items()],
            "loads_process_list": [{
                "python_module": "assign_scalar_variable_to_conditions_process", "kratos_module": "KratosMultiphysics",
                "Parameters": {"model_part_name": "Structure.Load", "variable_name": "POSITIVE_FACE_PRESSURE",
                               "value": f"{case['load'][1]!r}*t" if case["steps"] > 1 else case["load"][1],
                               "interval": [0.0, "End"]}}],
            "contact_process_list": [{
                "python_module": "alm_contact_process",
                "kratos_module": "KratosMultiphysics.ContactStructuralMechanicsApplication",
                "process_name": "ALMContactProcess",
                "Parameters": {"model_part_name": "Structure",
                               "contact_model_part": {"0": ["Contact_slave", "Contact_master"]},
                               "assume_master_slave": {"0": ["Contact_slave"]},
                               "contact_type": "Frictionless"}}]},
        "output_processes": {}}


def materials(case: dict) -> dict:
    return {"properties": [{"model_part_name": f"Structure.Parts_{name}", "properties_id": pid,
                            "Material": {"constitutive_law": {"name": "LinearElastic3DLaw"},
                                         "Variables": {"YOUNG_MODULUS": E, "POISSON_RATIO": nu, "DENSITY": 1.0},
                                         "Tables": {}}}
                           for pid, (name, (E, nu, _)) in enumerate(case["bodies"].items(), start=1)]}


def main(name: str, msh: Path, work: Path) -> dict:
    case = CASES[name]
    work.mkdir(parents=True, exist_ok=True)
    os.chdir(work)
    t0 = time.perf_counter()
    info = write_mdpa(msh, case, work / f"{name}.mdpa")
    (work / "materials.json").write_text(json.dumps(materials(case)))
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
    StructuralMechanicsAnalysis(model, KM.Parameters(json.dumps(parameters(name, case)))).Run()
    t_solve = time.perf_counter() - t1
    mp = model["Structure"]
    scale = mp.ProcessInfo[KM.SCALE_FACTOR]          # the ALM's multipliers are stored divided by it
    slave = list(mp.GetSubModelPart("Contact_slave").Nodes)
    lm = [abs(n.GetSolutionStepValue(CSMA.LAGRANGE_MULTIPLIER_CONTACT_PRESSURE)) * scale for n in slave]
    cx, cy = case["centre"]
    centre = min(range(len(slave)), key=lambda i: (slave[i].X0 - cx) ** 2 + (slave[i].Y0 - cy) ** 2)
    held = mp.GetSubModelPart(f"DISP_{case['held']}").Nodes
    load = mp.GetSubModelPart("Load").Nodes
    return {**info, "p_centre": lm[centre], "p_max": max(lm), "p_min": min(lm),
            "reaction_z": sum(n.GetSolutionStepValue(KM.REACTION_Z) for n in held),
            "top_uz_min": min(n.GetSolutionStepValue(KM.DISPLACEMENT_Z) for n in load),
            "newton": mp.ProcessInfo[KM.NL_ITERATION_NUMBER],
            "converged": mp.ProcessInfo[KM.NL_ITERATION_NUMBER] < MAX_NEWTON,   # Kratos goes on silently
            "mdpa_s": round(t_mdpa, 2),
            "analysis_s": round(t_solve, 2)}


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], Path(sys.argv[2]).resolve(), Path(sys.argv[3]).resolve())))
