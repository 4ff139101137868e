"""The DD solver's units distributed over 2 MPI ranks (`solve_dd(..., comm=)`): the same
iterates and results as 1 rank, bit for bit.

Why bitwise: interface vectors are not summed by a floating-point Allreduce; every
rank gathers the contributions of all units (Allgatherv) and adds them in unit order,
exactly as the serial loop does (wcs/dd/team.py), so PCG sees identical replicated
vectors on every rank and for any number of ranks. The local solves are the same
factorizations of the same matrices (one BLAS thread per rank)."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

STUDY = Path(__file__).resolve().parents[2] / "studies" / "validation" / "tresca-pad.yaml"
BIN = Path(sys.executable).parent
DD_BENCH = Path(__file__).resolve().parents[1] / "bench" / "dd_bench.py"


def _pad(tmp_path):
    doc = yaml.safe_load(STUDY.read_text())
    doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05}]}
    for f in STUDY.parent.glob("materials*.yaml"):
        (tmp_path / f.name).write_text(f.read_text())
    (tmp_path / "pad.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return tmp_path / "pad.yaml"


def test_dd_on_two_ranks_is_bitwise_the_one_rank_solve(tmp_path):
    mpiexec = BIN / "mpiexec"
    if not mpiexec.exists():
        pytest.fail("mpiexec is missing from the environment (the mpich wheel provides it)")
    study = _pad(tmp_path)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_", "MPI_LOCAL"))}
    env["WCS_THREADS"] = "1"
    out = {}
    for n in (1, 2):
        cmd = [str(mpiexec), "-n", str(n), sys.executable, str(DD_BENCH), "solve", str(study),
               "--subdomains", "8", "--tolerance", "1e-10", "--max-iterations", "300", "--repeat", "2",
               "--save", str(tmp_path / f"r{n}.npz"), "--json", str(tmp_path / f"r{n}.json")]
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stdout + p.stderr
        out[n] = dict(np.load(tmp_path / f"r{n}.npz"))
        assert f"{n} rank(s)" in p.stdout
    import json
    run2 = json.loads((tmp_path / "r2.json").read_text())
    ranks = run2["per_rank"]
    assert [r["rank"] for r in ranks] == [0, 1] and all(r["units"] >= 1 for r in ranks)
    assert all(r["assigned_by"] == "measured" for r in ranks)    # the second solve: by the first's costs
    assert sum(r["pairs"] for r in ranks) == run2["pairs"]
    assert sum(r["pairs"] > 0 for r in ranks) == min(run2["pairs"], 2)     # pairs spread over the ranks
    assert out[1]["u"].size > 0 and np.any(out[1]["lam_t"])     # Tresca: tangential forces present
    assert out[1]["residual"].size >= 2                        # step auto: interface Newton on the pad
    for key in ("u", "lam_n", "lam_t", "pcg1_residuals", "residual", "pcg2"):
        assert np.array_equal(out[1][key], out[2][key]), key


def _units(sizes, rng):
    """Stand-ins of units: (kind, DOFs, interface DOFs, contact DOFs, contact nodes)."""
    from types import SimpleNamespace as NS
    out = []
    for i, (kind, n, b, c, m) in enumerate(sizes):
        B = np.arange(b)
        out.append(NS(index=i, kind=kind, dofs=np.arange(n), B=B, X=np.arange(b + c), c=np.arange(c),
                      rows=np.arange(m), gamma=np.sort(rng.choice(4000, b, replace=False))))
    return out


def test_team_reduction_is_the_serial_sum_and_assignment_is_balanced():
    from wcs.dd.team import Team, assign
    rng = np.random.default_rng(1)
    units = _units([("pair", 7000, 560, 526, 132), ("pair", 7000, 548, 524, 132)]
                   + [("linear", 3800, b, 0, 0) for b in (394, 251, 408, 336, 348, 416, 247, 388)], rng)
    own = assign(units, 2, 2)
    assert {own[0], own[1]} == {0, 1}                           # the two pairs on different ranks
    assert sorted(sum(1 for u in units if own[u.index] == r) for r in (0, 1)) == [5, 5]
    pieces = {u.index: rng.random(u.B.size) for u in units}
    serial = np.zeros(4000)
    for u in units:
        serial[u.gamma] += pieces[u.index]
    assert np.array_equal(Team(None, units).sum(units, pieces, 4000), serial)


def test_assignment_balances_every_phase_of_one_large_pair():
    """Hertz at 1.05e5 unknowns, 12 subdomains (the sizes of its units): one pair with a third
    of the DOFs and a Schur block of 1517 against ten linear subdomains. Longest-processing-time
    per kind put the pair and five linear subdomains on one rank: the iterations' products
    (|B|² each) 0.40 s there against 0.28 s; by the phases' sum of maxima the pair's rank takes
    fewer linear subdomains."""
    from wcs.dd.team import PHASES, assign, phase_costs
    rng = np.random.default_rng(2)
    units = _units([("pair", 25489, 669, 848, 212)]
                   + [("linear", 8300, b, 0, 0) for b in (488, 808, 758, 384, 676, 502, 311, 728, 748, 518)], rng)
    own = assign(units, 2, 2)
    load = np.zeros((2, len(PHASES)))
    for u in units:
        load[own[u.index]] += phase_costs(u, 2)
    pair_rank = own[0]
    assert sum(1 for u in units[1:] if own[u.index] == pair_rank) <= 4      # of ten
    it = PHASES.index("iterate")
    assert load[:, it].max() <= 0.56 * load[:, it].sum()        # the iterations within 12 % of balance
    assert load.max(axis=0).sum() <= 0.70 * load.sum()          # 1.4× at least on these estimates


def test_assignment_by_measured_costs():
    """Hertz's units (as above) with the costs of one evaluation on new data as measured on
    this machine (1.05e5 unknowns, serial: the factorizations and dense blocks 1.70 s against
    0.79 s estimated, the products 0.56 s against 0.67 s): by the estimates the pair's rank
    takes four linear subdomains and assembles 1.18 s against 0.52 s; by the measured costs
    the pair goes alone and both ranks assemble within 3 % (Σ_phase max: 1.46× → 1.56×). On
    the same data again (factors kept) the assembly weighs nothing and the products decide."""
    from wcs.dd.team import PHASES, Team, assign, phase_costs
    rng = np.random.default_rng(2)
    units = _units([("pair", 25489, 669, 848, 212)]
                   + [("linear", 8300, b, 0, 0) for b in (488, 808, 758, 384, 676, 502, 311, 728, 748, 518)], rng)
    measured = {u.index: phase_costs(u, 2) * [2.15, 0.83, 1.0] for u in units}
    by_estimate, by_measure = assign(units, 2, 2), assign(units, 2, 2, measured)
    with_pair = lambda own: sum(1 for u in units[1:] if own[u.index] == own[0])  # noqa: E731
    assert with_pair(by_estimate) == 4 and with_pair(by_measure) == 0
    speedup = {}
    for name, own in (("estimate", by_estimate), ("measured", by_measure)):
        load = np.zeros((2, len(PHASES)))
        for u in units:
            load[own[u.index]] += measured[u.index]
        speedup[name] = load.sum() / load.max(axis=0).sum()
    assert speedup["estimate"] < 1.5 < 1.55 < speedup["measured"], speedup
    same = {i: c * [0.0, 1.0, 1.0] for i, c in measured.items()}     # the same data again: no refactor
    assert with_pair(assign(units, 2, 2, same)) > with_pair(by_measure)  # the products balanced instead
    assert Team(None, units, 2, {1: measured}, refactor=False).cost[PHASES.index("assemble")] == 0
    team = Team(None, units, 2, {2: measured})                  # serial: every unit on rank 0
    assert team.assigned_by == "estimate" and set(team.owner.values()) == {0}
    assert Team(None, units, 2, {1: measured}).assigned_by == "measured"


def test_dd_study_on_two_ranks_shares_the_evaluations(tmp_path):
    """`mpiexec -n 2 wcs run` of a `dd` study: each rank solves its share of every batch with
    a serial DD (measured on the tunnel, 22 evaluations: 0.50× with each DD solve spread over
    the 2 ranks, 1.50× with the evaluations spread), not every evaluation on both ranks."""
    import json
    doc = yaml.safe_load((STUDY.parent / "contact-patch.yaml").read_text())
    doc["solver"] = {"method": "dd", "dd": {"subdomains": 6}}
    doc["search"] = {"method": "auto", "budget": 8}
    for f in STUDY.parent.glob("materials*.yaml"):
        (tmp_path / f.name).write_text(f.read_text())
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(doc))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "OMPI_", "PMIX_", "MPI_LOCAL"))}
    env["WCS_THREADS"] = "1"
    p = subprocess.run([str(BIN / "mpiexec"), "-n", "2", sys.executable, str(DD_BENCH), "study",
                        str(tmp_path / "study.yaml"), "--json", str(tmp_path / "t.json"), "--quiet"],
                       env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    ranks = json.loads((tmp_path / "t.json").read_text())
    records = ranks[0]["evals_total"]
    assert records >= 5
    assert all(0 < r["evaluations"] < records for r in ranks), ranks      # each rank a share, none all
