"""The scene figure draws each point source as a marker with its name, and its labels never
overlap: a label that would is placed beside the others or left out and named in a note."""
import matplotlib.pyplot as plt
import numpy as np

from tests.report.test_report import ROOT, synthetic_run
from wcs.report.data import from_dataset
from wcs.report.plots import SOURCE_COLOR, scene_plot


def test_sources_are_marked_and_labels_do_not_overlap():
    """granite-crack with a point source at its nominal point and each region of interest
    repeated four times under other names (their labels' points coincide): the source's star
    at its point with its name on every axes; in the last (the zoom where there is one) every region's name is
    drawn or named in the note, and no two label boxes overlap."""
    res = from_dataset(synthetic_run(ROOT / "studies/granite-crack.yaml", n=2))
    rois = res.scene["regions_of_interest"]
    names = list(rois)
    for name in names:
        for i in range(2, 6):
            rois[f"{name}{i}"] = rois[name]
    x, y = res.mesh.coords.mean(axis=0)
    res.scene["sources"] = {"quake": {"point": [float(x), float(y)], "force": [0.0, 1.0],
                                      "wavelet": {"ricker": {"frequency": 5.0, "delay": 0.2}}}}
    fig = scene_plot(res)
    try:
        for ax in fig.axes:
            stars = [line for line in ax.lines if line.get_marker() == "*"]
            assert len(stars) == 1 and np.allclose(stars[0].get_xydata(), [[x, y]])
            assert stars[0].get_color() == SOURCE_COLOR
        assert "quake" in [t.get_text() for t in fig.axes[0].texts]
        zoom = fig.axes[-1]
        renderer = fig.canvas.get_renderer()
        texts = [t for t in zoom.texts if not t.get_text().startswith("not labelled")]
        drawn = [t.get_text() for t in texts]
        note = " ".join(t.get_text() for t in zoom.texts if t.get_text().startswith("not labelled"))
        assert all(n in drawn or n in note for n in rois) and len(drawn) >= len(names) + 1
        boxes = [t.get_window_extent(renderer) for t in texts]
        assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
        assert any(h.get_label() == "point source (its nominal point)" for h in fig.legends[0].legend_handles)
    finally:
        plt.close(fig)
