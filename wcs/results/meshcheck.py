"""The mesh's share of an extreme value: each extreme data set solved again on the study's mesh
refined once and twice, Richardson's extrapolation, and a verdict that knows the error.

Refinement: every triangle of gmsh's mesh split into four at its edge midpoints (gmsh's
`refine`), every tetrahedron into eight, once and twice, the new nodes of a curve or a surface
placed on it. Of the two uniform refinements of the same geometry this one keeps the geometry
(a circle's or a sphere's new nodes lie on it) and halves h exactly everywhere: a halved gmsh
size would not halve the cells where the curvature bound (24 per turn) or a graded refine zone
sets the size, and a new Delaunay mesh is not a refinement of the old one, so its error does
not follow C h^p from mesh to mesh. A mesh read from a file has no geometry to refine on: the check says so.

With f0, f1, f2 the values on h, h/2, h/4 and r = (f1 − f0)/(f2 − f1) > 1 (the differences
shrink), the observed order is p = log2 r, the extrapolated value f∞ = f2 + (f2 − f1)/(r − 1)
(Richardson: f = f∞ + C h^p), and the estimated error of the reported value f0 is f∞ − f0
(signed: the exact value is about f0 + error). Otherwise no order is observed: the three
values agree to the solver's tolerance (the mesh's share is below it), or the differences do
not shrink (not in the asymptotic range, no extrapolation). The verdict against a limit L is
MARGINAL when |L − f0| ≤ |error| (without an error estimate: the spread max|f_k − f0| of the
three values, and the note says so), else PASS or FAIL.

When the mesh split twice would pass `mesh.max_cells` (4 or 8 times the cells per split, in 2D
or 3D) or its dense contact condensation would not fit in memory or take more than minutes, the
mesh is split once only: the two values f0, f1, no observed order, the error estimated with
the linear elements' theoretical order 1 (f∞ − f0 = 2 (f1 − f0)), as the note says; when the
mesh split once would pass it too, the check is not run (verdict NOT CHECKED where a limit is
set) — unless an extreme lies within CLOSE (5 %) of its limit: its verdict hangs on the mesh's
share, so the mesh is split once if it stays within STRETCH times `mesh.max_cells`, as the note says. The contact
solve condenses onto the k = d × m contact rows of the m contact nodes (about 2^(d − 1) times
more per split) with dense k × k blocks (the Delassus operator, in 3D minus the Schur complement
of the bordered matrix [[K, Cᵀ], [C, 0]]): DENSE_BLOCKS[d] × 8 k² bytes at the peak of a solve,
against MEMORY_SHARE of the machine's memory (`machine_memory`: a fixed property of the
machine), and CONDENSATION's seconds grown as k³, against MAX_SOLVE_SECONDS a solve. The plan
depends only on the study and the machine.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import StudyError
from ..dynamics.history import evaluator_for
from .extremes import Extreme, kinds, pairs
from ..progress import phase
from ..scene.estimate import (BYTES_PER_CELL, DEFAULT_MAX_CELLS, ITERATIVE_BYTES_PER_CELL, ITERATIVE_STEP_SECONDS,
                              ITERATIVE_STEPS, EvaluationFacts, evaluation_cost, machine_memory)
from .store import key
from .verdict import CLOSE

if TYPE_CHECKING:
    import xarray as xr


SPLITS = (1, 2)                 # the refined meshes: split once (h/2) and twice (h/4)
LEVELS = ("h", "h/2", "h/4")    # the study's mesh and the refined meshes
ORDER_RANGE = (0.5, 4.0)        # observed orders outside it: the extrapolation is not to be trusted
THEORETICAL_ORDER = 1.0         # P1 elements: stresses, tractions (and criteria of them) converge as h^1
STRETCH = 2.0                   # a margin within CLOSE of its limit: the mesh split once may have up to this many
                                # times mesh.max_cells (the knee in 3D: 1.08e6 cells against the default 1e6)
SOLVE_GROWTH = {2: 1.15,        # a solve's time grows as nodes^1.15 (1.1-1.25 from h/2 to h/4: knee, tunnel, Hertz),
                3: 1.5}         # in 3D as nodes^1.5 (1.2-1.3 from h to h/2: hertz-3d; 1.4-1.7 h/2 to h/4: block-on-block-3d)
ASSEMBLY_GROWTH = {2: 1.0,      # the assembly's as the nodes,
                   3: 1.35}     # in 3D as nodes^1.35 (1.3 hertz-3d, 1.4 block-on-block-3d, as the solves)
DENSE_BLOCKS = {2: 24,          # k × k float64 blocks at a contact solve's peak (its rise over the built evaluator,
                3: 8}           # one cold solve): 2D tunnel 24.9 at k = 1348, 22.2 at k = 2692 ((K⁺)_SS on about 2k
                                # DOFs); 3D tunnel 7.6 at k = 3672, 7.4 at k = 6141 (the process's peak 5.8 GB, 8.1
                                # blocks, at k = 9456)
MEMORY_SHARE = 0.5              # of the machine's memory, the rest for the system, the study's own evaluator, the mesh
CONDENSATION = {2: (40.0, 2692),    # (seconds, k) of a cold contact solve on k contact rows, its dense condensation
                3: (58.0, 6141)}    # growing as k³ (one core, a loaded machine: 2D tunnel; 3D tunnel, 25.7 s of it the
                                    # bordered factorization; 141 s at k = 9456 on a quieter one)
MAX_SOLVE_SECONDS = 120.0       # the condensation's estimated time a solve of a refined mesh may take (the 3D tunnel
                                # split once: 64 s; hertz-3d split twice, 570 s, is not made)
NNZ_PER_CELL = {2: 12.0,       # entries of the stiffness K a cell (P1 elasticity on scikit-fem's tensor meshes:
                3: 20.0}        # 12.1 a triangle, 19.9 a tetrahedron): the iterative method's cost is O(nnz)
FIRST_SOLVE_EXTRA = 4           # a new mesh's first solve: its nominal state and analysis, about 4 solves more


@dataclass(frozen=True)
class Richardson:
    order: float                # observed order p (NaN where none)
    extrapolated: float         # f∞ (NaN where none)
    error: float                # estimated error of f0: f∞ − f0 (NaN where none)
    spread: float               # max |f_k − f0|
    note: str


def richardson(f0: float, f1: float, f2: float, tol: float) -> Richardson:
    """Observed order, extrapolated value and estimated error of f0 from the values on h, h/2,
    h/4; `tol`: relative differences at most this are the solver's, not the mesh's."""
    vals = (f0, f1, f2)
    if not all(map(math.isfinite, vals)):
        return Richardson(math.nan, math.nan, math.nan, math.nan, "a value is missing: no estimate")
    d1, d2 = f1 - f0, f2 - f1
    spread = max(abs(d1), abs(f2 - f0))
    if spread <= tol * max(map(abs, vals)):
        return Richardson(math.nan, math.nan, math.nan, spread,
                          f"the three values agree within the solver tolerance {tol:g}: the mesh's share "
                          f"is below it (no order observed)")
    r = d1 / d2 if d2 != 0 else math.inf
    if not (1 < r < math.inf):
        return Richardson(math.nan, math.nan, math.nan, spread,
                          f"the differences do not shrink (f(h/2) − f(h) = {d1:.4g}, f(h/4) − f(h/2) = {d2:.4g}): "
                          f"not in the asymptotic range, no extrapolation; the verdict uses the spread of "
                          f"the three values")
    p = math.log2(r)
    f_inf = f2 + d2 / (r - 1)
    note = f"observed order {p:.2f}"
    if not ORDER_RANGE[0] <= p <= ORDER_RANGE[1]:
        note += (f", outside {ORDER_RANGE[0]:g}–{ORDER_RANGE[1]:g}: far from the asymptotic range, "
                 f"the extrapolation is not to be trusted")
    return Richardson(p, f_inf, f_inf - f0, spread, note)


def two_values(f0: float, f1: float, tol: float, why: str) -> Richardson:
    """The values on h and h/2 only (the mesh not split twice: `why`): no order observed, so the
    error of f0 is Richardson's with the element's theoretical order THEORETICAL_ORDER assumed,
    f∞ = f1 + (f1 − f0)/(2^p − 1), error f∞ − f0 = 2^p (f1 − f0)/(2^p − 1), as the note says."""
    if not (math.isfinite(f0) and math.isfinite(f1)):
        return Richardson(math.nan, math.nan, math.nan, math.nan, "a value is missing: no estimate")
    spread = abs(f1 - f0)
    if spread <= tol * max(abs(f0), abs(f1)):
        return Richardson(math.nan, math.nan, math.nan, spread,
                          f"split once only ({why}): the two values agree within the solver tolerance {tol:g}; "
                          f"no order observed, the verdict uses the spread of the two values")
    grow = 2.0 ** THEORETICAL_ORDER
    f_inf = f1 + (f1 - f0) / (grow - 1)
    return Richardson(math.nan, f_inf, f_inf - f0, spread,
                      f"split once only ({why}): f(h/2) − f(h) = {f1 - f0:.4g}; no order observed: the error "
                      f"assumes the linear elements' theoretical order {THEORETICAL_ORDER:g} (stresses and contact "
                      f"tractions converge as h; displacements faster, so it overstates theirs), "
                      f"extrapolated f(h/2) + (f(h/2) − f(h))/(2^{THEORETICAL_ORDER:g} − 1)")


def verdict(value: float, est: Richardson, limit: float, kind: str) -> str:
    """PASS / FAIL / MARGINAL of an extreme against its limit ("" without a limit or a value;
    NOT CHECKED without an estimate): an upper limit for the worst value, a lower limit for the best."""
    if not (math.isfinite(limit) and math.isfinite(value)):
        return ""
    width = abs(est.error) if math.isfinite(est.error) else est.spread
    if not math.isfinite(width):
        return "NOT CHECKED"
    if abs(limit - value) <= width:
        return "MARGINAL"
    return "PASS" if (value <= limit if kind == "worst" else value >= limit) else "FAIL"


def refined_nodes(mesh, splits: int) -> int:
    """Nodes of a triangle or tetrahedron mesh after `splits` splittings into four or eight, without
    building it. Each edge gains a node; a triangle gains three inner edges; a tetrahedron gains one
    inner edge and eight inner triangles."""
    n, t = mesh.p.shape[1], mesh.t.shape[1]
    if mesh.dim() == 2:
        e = mesh.facets.shape[1]
        for _ in range(splits):
            n, e, t = n + e, 2 * e + 3 * t, 4 * t
    else:
        e, f = mesh.edges.shape[1], mesh.facets.shape[1]
        for _ in range(splits):
            n, e, f, t = n + e, 2 * e + 3 * f + t, 4 * f + 8 * t, 8 * t
    return n


def max_cells(study) -> float:
    return float(DEFAULT_MAX_CELLS if study.scene.mesh.max_cells is None else study.scene.mesh.max_cells)


def contact_rows(d: int, contact_nodes: int, splits: int) -> int:
    """The contact rows k (a normal and d − 1 tangents per node) of the mesh split `splits` times:
    the contact nodes grow about 2^(d − 1) times a split."""
    return d * contact_nodes * 2 ** ((d - 1) * splits)


def condensation_bytes(d: int, k: int) -> float:
    """Memory of the dense contact condensation on k contact rows at the peak of a solve."""
    return DENSE_BLOCKS[d] * 8.0 * k * k


def iterative_seconds(d: int, cells: int, k: int) -> float:
    """Estimated seconds of a contact solve by the iterative method on a mesh of `cells` cells and
    k contact rows: `wcs.scene.estimate.evaluation_cost`'s, its stiffness entries NNZ_PER_CELL a cell."""
    facts = EvaluationFacts(dimension=d, unknowns=0, stiffness_nnz=int(NNZ_PER_CELL[d] * cells), contact_rows=k)
    return evaluation_cost(facts, "iterative")[1]       # (the unknowns size only a heat step's factor)


def condensation_seconds(d: int, k: int) -> float:
    """Estimated seconds of a contact solve's dense condensation on k contact rows: CONDENSATION's
    measured solve grown as k³."""
    seconds_ref, k_ref = CONDENSATION[d]
    return seconds_ref * (k / k_ref) ** 3


def planned(study, cells: int, contact_nodes: int, memory: float | None = None,
            close: bool = False) -> tuple[tuple[int, ...], str]:
    """The splits of SPLITS made of a mesh of `cells` cells and `contact_nodes` contact nodes: within
    `mesh.max_cells` (a split multiplies the cells by 2^d; with `close`, a margin within CLOSE of
    its limit, the first split within STRETCH times it, and the cells' measured memory of such a
    split beyond mesh.max_cells within MEMORY_SHARE of `memory`: the 3D knee split once, 1.08e6
    tetrahedra, grew to 17.5 GB) and with the dense contact condensation
    of the split mesh within MEMORY_SHARE of `memory` bytes (None: `machine_memory()`) and
    MAX_SOLVE_SECONDS a solve (a study solved by `solver.method: iterative`: that method's memory
    and time of the split mesh instead, `iterative_seconds`); and why no more are made, or why one beyond mesh.max_cells is ("" when neither)."""
    d = study.scene.dimension
    memory = machine_memory() if memory is None else memory
    done: list[int] = []
    stretched = ""

    def why(text: str) -> str:
        return "; ".join(t for t in (text, stretched) if t)

    for s in SPLITS:
        split = f"the mesh split {'once' if s == 1 else f'{s} times'} would"
        n, k = cells * 2 ** (d * s), contact_rows(d, contact_nodes, s)
        allowed = max_cells(study) * (STRETCH if close and s == SPLITS[0] else 1.0)
        if n > allowed:
            return tuple(done), why(f"{split} have {n:.3g} cells, beyond "
                                    + (f"{STRETCH:g} × " if allowed > max_cells(study) else "")
                                    + f"mesh.max_cells = {max_cells(study):g}")
        if study.solver.method == "iterative" and k:     # the split study is solved so: no dense condensation
            need, seconds = n * ITERATIVE_BYTES_PER_CELL[d], iterative_seconds(d, n, k)
            if need > MEMORY_SHARE * memory:
                return tuple(done), why(f"{split} need about {need / 1e9:.3g} GB for an evaluation by the iterative "
                                        f"method ({ITERATIVE_BYTES_PER_CELL[d] / 1e3:g} kB a cell), beyond the "
                                        f"{MEMORY_SHARE * memory / 1e9:.3g} GB it may take ({MEMORY_SHARE:.0%} of "
                                        f"this machine's {memory / 1e9:.3g} GB of memory)")
            if seconds > MAX_SOLVE_SECONDS:
                return tuple(done), why(f"{split} take about {seconds:.3g} s a solve by the iterative method "
                                        f"({ITERATIVE_STEPS} Newton steps of {ITERATIVE_STEP_SECONDS:g} s an entry of "
                                        f"its {NNZ_PER_CELL[d] * n:.3g} stiffness entries), beyond the "
                                        f"{MAX_SOLVE_SECONDS:g} s a solve of the check may take")
        elif condensation_bytes(d, k) > MEMORY_SHARE * memory:
            return tuple(done), why(f"{split} need about {condensation_bytes(d, k) / 1e9:.3g} GB for its dense "
                                    f"contact condensation ({k} contact rows: {DENSE_BLOCKS[d]} blocks of {k} × {k} "
                                    f"float64), beyond the {MEMORY_SHARE * memory / 1e9:.3g} GB it may take "
                                    f"({MEMORY_SHARE:.0%} of this machine's {memory / 1e9:.3g} GB of memory)")
        elif condensation_seconds(d, k) > MAX_SOLVE_SECONDS:
            return tuple(done), why(f"{split} take about {condensation_seconds(d, k):.3g} s a solve for its dense "
                                    f"contact condensation ({k} contact rows, as k³ from {CONDENSATION[d][0]:g} s at "
                                    f"{CONDENSATION[d][1]}), beyond the {MAX_SOLVE_SECONDS:g} s a solve of the check "
                                    f"may take")
        if n > max_cells(study) and n * BYTES_PER_CELL[d] > MEMORY_SHARE * memory:
            return tuple(done), why(f"{split} have {n:.3g} cells, beyond mesh.max_cells = {max_cells(study):g}, "
                                    f"and need about {n * BYTES_PER_CELL[d] / 1e9:.3g} GB to mesh and solve "
                                    f"({BYTES_PER_CELL[d] / 1e3:g} kB a cell, measured), beyond the "
                                    f"{MEMORY_SHARE * memory / 1e9:.3g} GB it may take ({MEMORY_SHARE:.0%} of this "
                                    f"machine's {memory / 1e9:.3g} GB)")
        if n > max_cells(study):
            stretched = (f"the mesh split once has {n:.3g} cells, beyond mesh.max_cells = {max_cells(study):g}: "
                         f"made all the same (up to {STRETCH:g} × it) because a margin is within {CLOSE:.0%} "
                         f"of its limit")
        done.append(s)
    return tuple(done), stretched


def close_margin(ds: xr.Dataset, found: list[Extreme]) -> bool:
    """Whether some found extreme lies within CLOSE of its limit (its verdict hangs on the mesh's share)."""
    return any(e.found and math.isfinite(lim := _limit(ds, e.kind, e.criterion))
               and abs(lim - e.value) <= CLOSE * abs(lim) for e in found)


def cost(evaluator, warm_solve: float, n_extremes: int, splits=SPLITS) -> list[tuple[int, int, float]]:
    """(splits, unknowns, estimated seconds) of each refined mesh of `splits`, from the study's mesh
    (evaluator.timings, and `warm_solve` seconds of a solve with the factorization's analysis
    reused): meshing as the study's (the geometry dominates), assembly growing as
    nodes^ASSEMBLY_GROWTH, a solve as nodes^SOLVE_GROWTH (of the dimension), a new mesh's first
    solve FIRST_SOLVE_EXTRA solves dearer; and the dense contact condensation on the split mesh's
    k contact rows (`condensation_seconds`; none by the iterative method), paid by the nominal
    state the contact solves start from and by each extreme. Measured (knee, tunnel, Hertz: both refined
    meshes, one solve per extreme): 12, 8.8 and 10 s estimated against about 17, 13 and 19 s
    taken: the estimate is good to a factor 2. In 3D (block-on-block-3d split once and twice,
    hertz-3d split once, on a loaded machine): 170 and 230 s estimated against 166 and 324 s
    taken; tunnel-fault-3d split once (6348 contact rows): 221 s against 172 s."""
    mesh = evaluator.smesh.mesh
    d, n = mesh.dim(), mesh.p.shape[1]
    per_node = d + evaluator.model.thermal
    dense = evaluator.model.zone is not None and evaluator.model.solver_method != "iterative"
    m = evaluator.model.zone.gap.size if dense else 0
    out = []
    for s in splits:
        r = refined_nodes(mesh, s) / n
        seconds = (evaluator.timings["mesh"] + evaluator.timings["assembly"] * r ** ASSEMBLY_GROWTH[d]
                   + (n_extremes + FIRST_SOLVE_EXTRA) * warm_solve * r ** SOLVE_GROWTH[d]
                   + (n_extremes + 1) * condensation_seconds(d, contact_rows(d, m, s)))
        out.append((s, per_node * refined_nodes(mesh, s), seconds))
    return out


def _limit(ds: xr.Dataset, kind: str, criterion: str) -> float:
    name = "limit" if kind == "worst" else "limit_lower"
    return float(ds[name].sel(criterion=criterion)) if name in ds else math.nan


def mesh_check(study, ds: xr.Dataset, found: list[Extreme]) -> xr.Dataset:
    """The mesh-check variables (`mesh_check_*`) and attribute (`mesh_check`) of a results file
    `ds`: the `found` extremes re-solved on the mesh split once and twice (serially, on the root
    rank)."""
    crit = [str(c) for c in ds["criterion"].values]
    ext = kinds(ds)
    levels = (0, *SPLITS)
    values = np.full((len(ext), len(crit), len(levels)), np.nan)
    nodes = np.full(len(levels), -1, dtype=np.int64)
    seconds = np.full(len(levels), np.nan)
    nodes[0] = int(ds.attrs.get("mesh_nodes", -1))
    seconds[0] = 0.0
    failures: dict[tuple[str, str], list[str]] = {}
    for e in found:
        if e.found:
            values[ext.index(e.kind), crit.index(e.criterion), 0] = e.value
    splits, short = planned(study, int(ds.attrs.get("mesh_cells", 0)), ds.sizes.get("contact_node", 0),
                            close=close_margin(ds, found))
    status = "done"
    if not any(e.found for e in found):
        status = "not run: no extreme data set was solved"
    elif not splits:
        status = f"not run: {short}"
    else:
        distinct = len({key(study.sha256, e.x, None) for e in found if e.found})
        with phase("mesh check", distinct * len(splits)) as progress:   # a part: a data set on a mesh
            for j, s in enumerate(splits, start=1):
                t0 = time.perf_counter()
                try:
                    ev = evaluator_for(study, splits=s)
                except StudyError as err:
                    status = f"not available: {err.fault}"
                    break
                nodes[j] = ev.smesh.mesh.p.shape[1]
                solved = {}
                for e in found:
                    if not e.found:
                        continue
                    k = key(study.sha256, e.x, None)
                    if k not in solved:
                        try:
                            solved[k] = (ev.evaluate(e.x), "")
                        except StudyError:
                            raise
                        except Exception as err:  # noqa: BLE001 - a failed solve on a refined mesh is data
                            solved[k] = (None, f"{type(err).__name__}: {err}")
                        progress.step()
                    res, why = solved[k]
                    if res is not None and res.status == 0:
                        values[ext.index(e.kind), crit.index(e.criterion), j] = res.phi[e.criterion]
                    else:
                        why = why or f"status {int(res.status)}: {res.message}"
                        failures.setdefault((e.kind, e.criterion), []).append(f"h/{2 ** s}: {why}")
                seconds[j] = time.perf_counter() - t0
    tol = max(float(study.solver.tolerance), 1e-12)
    order, extrap, error = (np.full((len(ext), len(crit)), np.nan) for _ in range(3))
    verdicts = np.full((len(ext), len(crit)), "", dtype=object)
    notes = np.full((len(ext), len(crit)), "", dtype=object)
    for a, kind in enumerate(ext):
        for c, name in enumerate(crit):
            f = values[a, c]
            if not math.isfinite(f[0]):
                notes[a, c] = "no extreme found"
                continue
            if status != "done":
                notes[a, c] = status
                verdicts[a, c] = "NOT CHECKED" if math.isfinite(_limit(ds, kind, name)) else ""
                continue
            est = (richardson(*map(float, f), tol) if len(splits) == len(SPLITS)
                   else two_values(float(f[0]), float(f[1]), tol, short))
            order[a, c], extrap[a, c], error[a, c] = est.order, est.extrapolated, est.error
            verdicts[a, c] = verdict(float(f[0]), est, _limit(ds, kind, name), kind)
            fails = failures.get((kind, name))
            notes[a, c] = "; ".join([*(f"the refined solve failed at {w}" for w in fails or []), est.note])
    dims = ("extreme", "criterion")
    variables = {
        "mesh_check_value": (dims + ("refinement",), values,
                             {"long_name": "extreme value on the study's mesh (refinement 0, h), split once "
                                           "(1, h/2) and twice (2, h/4); NaN where not solved"}),
        "mesh_check_nodes": (("refinement",), nodes, {"long_name": "nodes of each mesh (-1: not built)"}),
        "mesh_check_time": (("refinement",), seconds,
                            {"long_name": "seconds spent on each refined mesh (meshing, assembly, solves)",
                             "units": "s"}),
        "mesh_check_order": (dims, order, {"long_name": "observed order p = log2((f1 - f0)/(f2 - f1)); NaN: none"}),
        "mesh_check_extrapolated": (dims, extrap, {"long_name": "Richardson-extrapolated value "
                                                                "f2 + (f2 - f1)/(2^p - 1); NaN: none"}),
        "mesh_check_error": (dims, error, {"long_name": "estimated discretisation error of the reported extreme: "
                                                        "extrapolated - value on the study's mesh; NaN: none"}),
        "mesh_check_verdict": (dims, verdicts, {"long_name": "PASS | FAIL | MARGINAL (the limit within the "
                                                             "extreme +- the estimated error) | NOT CHECKED (a limit, "
                                                             "but no estimate); empty: no limit"}),
        "mesh_check_note": (dims, notes, {"long_name": "what the mesh check observed"}),
    }
    coords = {"extreme": np.array(ext, dtype=object), "refinement": np.array(levels, dtype=np.int32)}
    if status != "done":
        said = status
    elif len(splits) == len(SPLITS):
        said = f"done: the extreme data sets re-solved on the mesh split once and twice ({nodes[1]} and {nodes[2]} nodes)"
    else:
        said = f"done: the extreme data sets re-solved on the mesh split once only ({nodes[1]} nodes): {short}"
    import xarray as xr     # lazy: xarray costs 0.25 s of `wcs check`'s start-up (it prints this module's cost)
    return xr.Dataset(variables, coords=coords, attrs={"mesh_check": said})


def skipped(why: str) -> xr.Dataset:
    """The attribute of a results file whose mesh check was not run."""
    import xarray as xr     # lazy: as in mesh_check
    return xr.Dataset(attrs={"mesh_check": why})


def summary(ds: xr.Dataset) -> str:
    """One line per extreme of the mesh check: the three values, the order, the error, the verdict."""
    lines = [f"mesh check: {ds.attrs.get('mesh_check', '')}"]
    for kind, c, pick in pairs(ds):
        f = ds["mesh_check_value"].sel(pick).values
        if not np.isfinite(f[0]):
            continue
        p, err = float(ds["mesh_check_order"].sel(pick)), float(ds["mesh_check_error"].sel(pick))
        n = 1 + int((ds["mesh_check_nodes"].values[1:] >= 0).sum())        # the meshes built
        lines.append(f"  {c} ({kind}): {' / '.join(f'{v:.7g}' for v in f[:n])} on {', '.join(LEVELS[:n])}; "
                     + (f"order {p:.2f}, estimated error {err:+.3g}" if math.isfinite(p) else "no observed order")
                     + f"; {ds['mesh_check_verdict'].sel(pick).values or 'no limit'}"
                     + (f" ({ds['mesh_check_note'].sel(pick).values})"
                        if str(ds['mesh_check_verdict'].sel(pick).values) == "NOT CHECKED" else ""))
    return "\n".join(lines)
