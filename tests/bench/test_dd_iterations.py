"""Iteration counts of the DD solver (wcs.dd): PCG1 against H/h, and the seed's models.

1. H/h: the contact patch (studies/validation/contact-patch.yaml) at three mesh sizes
   h = 0.2, 0.1, 0.05 and two subdomain counts (4, 16): PCG1 iterations of the auxiliary
   problem at 1e-4 (the seed's tolerance) and 1e-8.
2. The seed's models, our versions: studies/tunnel-fault.yaml (12 subdomains) and
   studies/knee-replacement.yaml (13), tolerance 1e-4 as in [21, §8]: the seed's successive
   approximations (ω = 1, and Aitken relaxation) and step auto (interface Newton there, ρ ≫ 1);
   outer steps and PCG iterations beside the seed's (tunnel 21 PCG1 / 15 steps / 39 PCG2,
   knee 19 / 14 / 36). PCG1 to the seed's 1e-4 in the seed's rows; under step auto
   (interface Newton) PCG1 stops at the first Newton step's forcing (0.1): its U⁰ is a start.

Writes results/bench/dd_iterations.csv (stamped). Run by `make bench`, or
.venv/bin/python tests/bench/test_dd_iterations.py
"""
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import pytest  # noqa: E402

from common import write_table  # noqa: E402
from dd_common import build, run  # noqa: E402

FIELDS = ["case", "h", "subdomains_asked", "step", "relaxation", "tolerance", "ndof", "subdomains", "interface_dofs",
          "floating_units", "contact_nodes", "pcg1", "successive", "pcg2", "contraction", "status",
          "err_u", "err_lam_n", "time_dd", "time_mono"]


def main():
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for h in (0.2, 0.1, 0.05):
            def mesh(doc, h=h):
                doc["scene"]["mesh"] = {"size": h}
            study, model = build("validation/contact-patch.yaml", tmp, mesh)
            for n in (4, 16):
                for tol in (1e-4, 1e-8):
                    _, out = run(study, model, {"tolerance": tol, "dd": {"subdomains": n}})
                    rows.append({"case": "contact-patch", "h": h, "subdomains_asked": n, "step": "auto", "relaxation": "",
                                 "tolerance": tol, **out})
                    print(rows[-1], flush=True)
        for name, n in (("tunnel-fault.yaml", 12), ("knee-replacement.yaml", 13)):
            study, model = build(name, tmp)
            for step, relax in (("seed", 1.0), ("seed", "aitken"), ("auto", "")):
                _, out = run(study, model, {"tolerance": 1e-4, "max_iterations": 100,
                                            "dd": {"subdomains": n, "step": step, **({"relaxation": relax} if relax else {})}})
                rows.append({"case": name.removesuffix(".yaml"), "h": "", "subdomains_asked": n, "step": step,
                             "relaxation": relax, "tolerance": 1e-4, **out})
                print(rows[-1], flush=True)
    write_table("dd_iterations", FIELDS, [[r.get(k, "") for k in FIELDS] for r in rows])
    print(f"{'case':16s} {'h':>5s} {'N':>3s} {'step':>6s} {'relax':>7s} {'tol':>6s} {'ndof':>6s} {'nΓ':>5s} {'PCG1':>5s} "
          f"{'succ':>5s} {'PCG2':>5s} status")
    for r in rows:
        print(f"{r['case']:16s} {r['h']!s:>5s} {r['subdomains']!s:>3s} {r['step']:>6s} {r['relaxation']!s:>7s} {r['tolerance']:6.0e} "
              f"{r['ndof']:6d} {r['interface_dofs']!s:>5s} {r['pcg1']!s:>5s} {r['successive']!s:>5s} "
              f"{r['pcg2']!s:>5s} {r['status']}")
    return rows


@pytest.mark.bench
def test_dd_iterations():
    rows = main()
    assert rows and all(r["status"] == "converged" for r in rows if r["step"] == "auto")


if __name__ == "__main__":
    main()
