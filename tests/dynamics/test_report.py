"""`wcs report` of a dynamic run: each criterion against time at its worst data with the level
that gives its value marked, the limits table naming the reduction, the worst-case fields
drawn at an output time."""
import re

import numpy as np
import pytest

from tests.support.bad_studies import write_study
from tests.dynamics.test_run import tiny
from wcs.cli import main
from wcs.report.timeline import Histories, defining_level, in_time, when


@pytest.mark.parametrize("over, level", [("max", 2), ("min", 0), ("final", 4), ("mean", None)])
def test_the_defining_level_of_each_reduction(over, level):
    assert defining_level(np.array([-1.0, 3.0, 5.0, 4.0, 2.0]), over) == level


def test_the_fields_are_drawn_at_the_defining_level_or_say_how_far_from_it():
    t = np.arange(11.0)
    h = Histories(t, np.array([np.sin(t / 3), t, t]), ["max", "final", "mean"], np.array([0.0, 5.0, 10.0]))
    assert when(h, 0) == "at t = 5 s, the level of its peak"          # sin(t/3) peaks at level 5, an output level
    assert when(h, 1) == "at t = 10 s, the level of its end"
    assert when(h, 2).startswith("at t = 10 s (the mean over time has no one level")
    h.values[0] = -(t - 2.0) ** 2           # the peak at t = 2: drawn at t = 0, and said
    assert when(h, 0) == ("at t = 0 s, the output time nearest its peak at t = 2 s "
                          "(fields are kept every `output_every` levels)")


@pytest.mark.parametrize("over, words", [("max", "the peak over time of Φ"), ("min", "the least over time of Φ"),
                                         ("final", "Φ at the end time"), ("mean", "the mean over time of Φ")])
def test_each_reduction_in_words(over, words):
    assert in_time("Φ", over) == words


def test_report_plots_each_history_and_names_the_reduction(tmp_path, capsys):
    doc = tiny(budget=2)
    doc["criteria"] = doc["criteria"][:2]                   # the peak (max) and the end (final)
    doc["limits"] = {"peak": 1.0e8}
    path = write_study(doc, tmp_path, "study.yaml")
    nc, html = tmp_path / "run.nc", tmp_path / "run.html"
    assert main(["run", str(path), "-o", str(nc), "--no-mesh-check"]) == 0
    printed = capsys.readouterr().out       # the terminal names the reductions too
    assert "peak: the peak over time of mean contact pressure" in printed and "at the end time [m]" in printed
    assert main(["report", str(nc), "-o", str(html)]) == 0
    assert "could not be drawn" not in capsys.readouterr().err
    page = html.read_text()
    section = page[page.index('id="histories"'):page.index('id="scene"')]
    assert section.count("<img") == 2
    for name, words in (("peak", "the peak over time of"), ("travel", "at the end time")):
        row = re.search(rf'<tr data-criterion="{name}">.*?</tr>', page, re.S).group(0)
        assert words in row, name
        assert words in re.search(rf'class="history-what" data-criterion="{name}">[^<]*', section).group(0)
    fields = page[page.index('id="worst-fields"'):page.index('id="contact"')]
    assert "<img" in fields
    assert "the worst case of travel at t = 0.00017 s, the level of its end" in fields


def test_criteria_worst_at_the_same_data_but_other_times_are_drawn_apart(tmp_path):
    """The contact plots draw each worst case's fields: two criteria worst at the same data set
    (one evaluation) but at different times — the peak's level and the end — are two cases, each
    labelled with the time of its fields, not one labelled with both names."""
    from wcs.report.data import load
    from wcs.report.plots import distinct_cases
    from wcs.report.timeline import output_index
    doc = tiny(budget=1)
    doc["criteria"] = doc["criteria"][:2]                   # the peak (max) and the end (final)
    doc["search"] = {"method": "sample", "sample": {"design": "lhs", "n": 1, "seed": 3}, "budget": 1}
    path = write_study(doc, tmp_path, "study.yaml")
    nc = tmp_path / "run.nc"
    assert main(["run", str(path), "-o", str(nc), "--quiet", "--no-mesh-check"]) == 0
    res = load(nc)
    at = [float(res.histories.output_time[output_index(res.histories, j)]) for j in range(2)]
    assert at[0] < at[1] == pytest.approx(float(res.histories.time[-1]))
    assert distinct_cases(res) == [(0, f"worst peak at t = {at[0]:.4g} s"), (1, f"worst travel at t = {at[1]:.4g} s")]
