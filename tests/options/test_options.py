"""Every search and solver option the code reads is settable from a study file, has one
default (the schema's), reaches the code that uses it, and is listed in docs/study-format.md; an
unknown or misspelt option is exit 2 with "did you mean"."""
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from pydantic import BaseModel

import wcs
from tests.support.search_problems import drive, interior
from wcs.app import runner
from wcs.cli import main
from wcs.dd import solver as dds
from wcs.model.evaluation import Evaluator
from wcs.search import Worst
from wcs.options import Search, Solver

ROOT = Path(__file__).resolve().parents[2]
PAD = ROOT / "studies" / "validation" / "tresca-pad.yaml"


def leaves(model: type[BaseModel], prefix: str):
    """(dotted key, field) of every option of a block, nested blocks walked."""
    for name, f in model.model_fields.items():
        if isinstance(f.annotation, type) and issubclass(f.annotation, BaseModel):
            yield from leaves(f.annotation, f"{prefix}.{name}")
        else:
            yield f"{prefix}.{name}", f


OPTIONS = dict(leaves(Search, "search")) | dict(leaves(Solver, "solver"))

# a valid value other than the default, per option
OTHER = {
    "search.method": "sample", "search.sample.design": "sobol", "search.sample.n": 16, "search.sample.seed": 5,
    "search.budget": 50, "search.local.starts": 2, "search.kkt_tol": 1e-4, "search.safeguard": 4,
    "solver.method": "dd", "solver.tolerance": 1e-6, "solver.max_iterations": 50,
    "solver.max_fixed_point_iterations": 20, "solver.fallback": False,
    "solver.dd.subdomains": 4, "solver.dd.pair_size": 2.0, "solver.dd.relaxation": "anderson",
    "solver.dd.patience": 3, "solver.dd.step": "glued", "solver.dd.seed_rho": 0.9, "solver.dd.rho_steps": 3, "solver.dd.pcg_tolerance": 1e-7,
    "solver.dd.pcg_max_iterations": 100, "solver.dd.inner_tolerance": 1e-9, "solver.dd.forcing": 0.2,
    "solver.dd.contact_tolerance": 1e-9, "solver.dd.anderson": 3, "solver.dd.anderson_restart": 10.0,
    "solver.dd.mixing": 0.5, "solver.iterative.preconditioner": "amg", "solver.iterative.tolerance": 1e-10,
    "solver.ranks_per_evaluation": 2,
}
NEEDS = {"solver.ranks_per_evaluation": {"method": "iterative"}}      # the other options an option's test value needs

# the values the code used before the options were typed (its `.get(name, default)` calls and
# the schema's dump), and the changes measured since
BEFORE = {
    "subdomains": 8, "pair_size": 1.0, "relaxation": "aitken", "tolerance": 1e-8, "max_iterations": 200,
    "pcg_tolerance": 1e-8, "pcg_max_iterations": 500, "inner_tolerance": 1e-9, "contact_tolerance": 1e-10,
    "patience": 8, "forcing": 0.1, "anderson": 5, "anderson_restart": 0.0, "mixing": 1.0,
    # pair_size 1.0 (measured: against 0.5, tunnel PCG1 22 instead of 45 and one DD solve
    # 3.7× a warm monolithic evaluation instead of 11.5×, Hertz 11.9× instead of 15.1×);
    # the outer iteration's choice (interface Newton unless ρ(S0⁻¹ dS_con) < seed_rho), and
    # the Coulomb fixed point's budget it reads from the solver block
    "step": "auto", "seed_rho": 0.5, "rho_steps": 5, "max_fixed_point_iterations": 100,
}


def pad_doc(**solver):
    doc = yaml.safe_load(PAD.read_text())
    doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05}]}
    doc["solver"] = solver
    return doc


def with_option(doc: dict, key: str, value) -> dict:
    node = doc
    *parents, last = key.split(".")
    for k in parents:
        node = node.setdefault(k, {})
    node[last] = value
    return doc


def typed(study, key: str):
    node = study
    for k in key.split("."):
        node = getattr(node, k)
    return node


def test_every_option_has_a_test_value():
    assert set(OTHER) == set(OPTIONS)


@pytest.mark.parametrize("key", sorted(OPTIONS))
def test_every_option_is_settable(key):
    value = OTHER[key]
    assert value != OPTIONS[key].get_default(call_default_factory=True)
    assert OPTIONS[key].description                          # documented in the schema
    study = wcs.load_study(with_option(pad_doc(**NEEDS.get(key, {})), key, value), base_dir=PAD.parent)
    assert typed(study, key) == value
    if key.startswith("solver.dd.") and key != "solver.dd.step":     # what the DD iteration reads
        assert dds._dd_options(study.solver)[key.removeprefix("solver.dd.")] == value


def test_defaults_are_the_ones_used_before():
    assert dds._dd_options(Solver()) == BEFORE
    study = wcs.load_study(pad_doc(), base_dir=PAD.parent)
    assert study.solver == Solver() and study.search == Search(sample=study.search.sample)
    assert dds._dd_options(study.solver) == BEFORE
    assert dds._dd_options({"tolerance": 1e-6})["pcg_tolerance"] == 1e-6     # max(tolerance, 1e-8)
    assert dds._dd_options({"tolerance": 1e-6})["inner_tolerance"] == 1e-7   # tolerance / 10


@pytest.mark.parametrize("block, key, close", [
    ("solver.dd", "pcg_tolerence", "pcg_tolerance"),
    ("solver", "max_fixed_point_iteration", "max_fixed_point_iterations"),
    ("search", "kkt_tolerance", "kkt_tol"),
    ("search.sample", "seeds", "seed"),
])
def test_misspelt_option_is_exit_2_with_did_you_mean(tmp_path, capsys, block, key, close):
    doc = with_option(pad_doc(), f"{block}.{key}", 1)
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: {block}.{key}: unknown key '{key}' (did you mean '{close}'?)" in err, err
    assert "Traceback" not in err


@pytest.mark.parametrize("value", ["andersen", 3.0, True])
def test_bad_relaxation_is_one_clear_message(tmp_path, capsys, value):
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(pad_doc(dd={"relaxation": value}), sort_keys=False))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == f"error: {path}: solver.dd.relaxation: must be 'aitken', 'anderson' or a fixed ω in (0, 2] " \
                  f"(got {value!r})\n"


def test_model_and_runner_use_the_study_options(monkeypatch):
    study = wcs.load_study(pad_doc(method="monolithic", dd={"subdomains": 4}), base_dir=PAD.parent)
    assert Evaluator(study).model.options is study.solver
    seen = []

    def strategy(problem, config, rng):
        seen.append(config)
        yield from ()
        return Worst(x={}, value={}, certificate={})

    monkeypatch.setattr(runner, "get_strategy", lambda name: strategy)
    runner.Runner(study, False).run()
    assert seen == [study.search] and seen[0] is study.search


def dd_evaluation(**dd):
    """The seed's successive approximations (step seed), whose options these tests reach, on
    contact bands of half a mean subdomain share (pair_size 0.5: the counts below)."""
    study = wcs.load_study(pad_doc(method="dd", tolerance=1e-10, max_iterations=300,
                                   dd={"step": "seed", "pair_size": 0.5, **dd}),
                           base_dir=PAD.parent)
    return study.evaluate(study.nominal())


def test_relaxation_anderson_is_accepted_and_used():
    """On the small Tresca pad (the seed's step) Aitken converges, β unused (the same run with
    β = 0.5); Anderson with β = 0.5 and with β = 1 converge in other numbers of steps (β is
    used). The DD answers agree with the monolithic one to 1e-6 relative (the DD stops at
    ‖ΔU‖ ≤ 1e-10 ‖U‖)."""
    study = wcs.load_study(pad_doc(method="monolithic"), base_dir=PAD.parent)
    mono = study.evaluate(study.nominal())
    aitken, aitken_mixed = dd_evaluation(), dd_evaluation(mixing=0.5)
    anderson, anderson_undamped = dd_evaluation(relaxation="anderson", mixing=0.5), dd_evaluation(relaxation="anderson")
    for ev in (aitken, aitken_mixed, anderson, anderson_undamped):
        assert ev.state.solver.startswith("dd: converged in")
    assert aitken.iterations == aitken_mixed.iterations != anderson.iterations != anderson_undamped.iterations
    for ev in (aitken, anderson, anderson_undamped):
        for c in mono.phi:
            assert ev.phi[c] == pytest.approx(mono.phi[c], rel=1e-6)


def test_dd_options_reach_the_iteration():
    pcg = dd_evaluation(pcg_max_iterations=1)
    assert pcg.state.solver == "monolithic after dd PCG2 did not converge in 1 iterations at step 1"
    # the seed's plain step (ω = 1) on the pad: q ≥ 1, stopped after `patience` such steps
    impatient, patient = dd_evaluation(patience=1, relaxation=1.0), dd_evaluation(relaxation=1.0)
    at = [int(re.search(r"stagnated at step (\d+)", e.state.solver).group(1)) for e in (impatient, patient)]
    assert impatient.state.solver.startswith("monolithic after dd successive approximations stagnated")
    assert "over the last 1 step" in impatient.state.solver and "over the last 8 steps" in patient.state.solver
    assert 1 < at[0] < at[1]                  # patience 1 stops at the first step with q ≥ 1 after the start


def test_kkt_tol_decides_the_certificate():
    """An interior maximum: the local ascent ends with a KKT gap near 1e-10 of scale,
    certified at the default 1e-6, not at 1e-300."""
    tp = interior()
    config = {"method": "local", "budget": 200, "sample": {"design": "lhs", "n": 8, "seed": 0}}
    plain, strict = drive("local", tp, config), drive("local", tp, {**config, "kkt_tol": 1e-300})
    for c in tp.problem.criteria:
        assert plain.worst.certificate[c] == "local-kkt"
        assert strict.worst.certificate[c] == "heuristic" and "> 1e-300" in strict.worst.notes[c]


def test_the_docs_list_every_option_with_its_default():
    text = (ROOT / "docs" / "study-format.md").read_text()
    listed = dict(re.findall(r"^- `((?:search|solver)\.[\w.]+)` \(([^)]*)\)", text, re.M))
    assert set(listed) == set(OPTIONS)
    for key, f in OPTIONS.items():
        default = f.get_default(call_default_factory=True)
        text = listed[key].strip("`")
        if default is None or isinstance(default, (bool, str)):
            assert text == {None: "null", True: "true", False: "false"}.get(default, default), key
        else:
            assert float(text) == default, key
