"""Calibration of wcs.scene.estimate.evaluation_cost: one evaluation's facts, memory and time.

    PYTHONPATH=. python tests/bench/evaluation_cost.py STUDY.yaml METHOD

prints the assembled model's facts (reduced unknowns n, nnz of the reduced K, contact rows m,
an upper bound of the units), VmRSS after `Evaluator` (meshing and assembly), VmHWM after one
nominal `evaluate` with solver.method METHOD, the wall time of that evaluate, and the estimate
(bytes, seconds) of the same facts. Run one study per process (VmHWM is the process's peak)."""
import re
import sys
import time

import yaml


def status(key: str) -> float:
    """Bytes of a /proc/self/status entry (VmRSS, VmHWM)."""
    return float(re.search(key + r":\s+(\d+)", open("/proc/self/status").read()).group(1)) * 1024


def main(path: str, method: str) -> None:
    import dolfinx_solver  # noqa: F401  (PETSc's libraries, as the iterative method loads them)
    from wcs.model.evaluation import Evaluator
    from wcs.scene.estimate import EvaluationFacts, evaluation_cost
    from wcs import load_study
    doc = yaml.safe_load(open(path))
    doc["solver"] = {**doc.get("solver", {}), "method": method}
    study = load_study(doc)
    ev = Evaluator(study)
    model, built = ev.model, status("VmRSS")
    rows = model.Bn_r.shape[0] + model.Bt_r.shape[0] if model.zone is not None else 0
    facts = EvaluationFacts(dimension=model.dim, unknowns=model.elim.T.shape[1],
                            stiffness_nnz=model.reduce.pattern.nnz, contact_rows=rows,
                            units=min(len(set(model.region_material)), len(model.smesh.bodies)),
                            thermal=model.thermal)
    t0 = time.perf_counter()
    res = ev.evaluate(study.nominal())
    seconds = time.perf_counter() - t0
    need, guess = evaluation_cost(facts, method)
    print(f"{path} {method}: {facts}; built {built / 1e9:.2f} GB, peak {status('VmHWM') / 1e9:.2f} GB "
          f"(estimate {need / 1e9:.2f}), evaluate {seconds:.1f} s (estimate {guess:.1f}); status {res.status} {res.message}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
