"""The HIL report's navigation figure: every run, each state's error with
its own 3-sigma bound and unit, no sum of variances of mixed units, and a
legend that hides no point."""

from __future__ import annotations

import numpy as np
import pytest

from bench.sim.scenario_docking import ScenarioConfig, run_docking
from hil_sim import report


@pytest.fixture(scope="module")
def figure():
    import matplotlib.pyplot as plt

    runs = [run_docking(seed, ScenarioConfig(t_max_s=12.0)) for seed in (1, 2)]
    fig = report.nav_errors_figure(runs, "HIL")
    yield fig
    plt.close(fig)


def test_every_run_has_its_error_and_3_sigma_in_every_state(figure):
    panels = [a for a in figure.axes if a.get_title()]
    assert [a.get_title() for a in panels] == [f"{b} {x}" for b in ("pos", "vel", "att") for x in "xyz"]
    for a in panels:
        solid = [ln for ln in a.lines if ln.get_linestyle() == "-"]
        dashed = [ln for ln in a.lines if ln.get_linestyle() == "--"]
        assert len(solid) == 2 and len(dashed) == 4, a.get_title()  # two runs, +/- 3 sigma each
        for ln in solid:  # error and bound in one unit: of one size, not a factor 1000 apart
            y, sig = ln.get_ydata(), next(d for d in dashed if d.get_color() == ln.get_color()).get_ydata()
            assert 0.01 < np.median(np.abs(y)) / np.median(np.abs(sig)) < 3.0, a.get_title()


def test_units_on_every_axis_and_no_trace_of_p(figure):
    labels = [a.get_ylabel() for a in figure.axes if a.get_ylabel()]
    assert labels == ["pos error [m]", "vel error [mm/s]", "att error [mrad]", "NIS [-]"]
    assert not any("trace" in a.get_ylabel().lower() for a in figure.axes)
    assert "[s]" in figure.axes[-1].get_xlabel()


def test_the_legend_names_every_run_and_sits_below_the_points(figure):
    nis = figure.axes[-1]
    legend = nis.get_legend()
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts[0].startswith("run 1 (") and texts[1].startswith("run 2 (")
    figure.canvas.draw()
    box = legend.get_window_extent()
    assert box.y1 < nis.get_window_extent().y0  # outside the axes: it covers no NIS point
