"""`wcs check` on mutated study files stays quick: a timing goal, so a benchmark (a loaded machine
must not fail the test suite). The mutations and the runner are tests/acceptance/test_fuzz_check.py's."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.acceptance.test_fuzz_check import run_cases  # noqa: E402

SECONDS = 10.0      # a mutated study is checked (or refused) within this wall time


@pytest.mark.bench
@pytest.mark.timeout(900)
def test_check_fuzz_no_case_over_10_s(tmp_path):
    """360 mutations of every shipped study, the heavy 3D ones too, each timed; prints the slowest."""
    results = run_cases(360, tmp_path)
    worst = sorted(results, key=lambda r: -r[-1])[:5]
    print("slowest checks:", [(s, w, round(t, 2)) for s, w, _, _, t in worst])
    slow = [(s, w, t) for s, w, _, _, t in results if t > SECONDS]
    assert not slow, slow
