"""The diagnosis page's figures say what an engineer needs to trust them:
the detection threshold on the gap map and cells beyond it told apart from
those below, units on every axis, smoothed spectra against white noise,
and the channel where the gap was found."""

from __future__ import annotations

import numpy as np
import pytest

from bench.gap import localise
from bench.gap.report_plots import gap_map_figure, residuals_figure

THRESHOLD = 5.9


def _cells(z_of: dict) -> list:
    """Every cell of the map at z = 0 but those named {(stream, axis, regime, stat): z}."""
    streams = [s for s, _, _ in localise.STREAMS] + [s for s, _ in localise.DYN_STREAMS]
    return [
        {"stream": s, "axis": a, "regime": r, "stat": st, "z": z_of.get((s, a, r, st), 0.0)}
        for s in streams
        for a in "xyz"
        for r in localise.REGIMES
        for st in localise.STATS
    ]


@pytest.fixture(scope="module")
def gap_map():
    big = {
        ("gyro vs valve torques", "x", "all", "variance"): 200.0,
        ("gyro vs valve torques", "y", "all", "mean"): 7.0,
        ("gyro vs valve torques", "y", "all", "lag"): 4.7,  # below the threshold, between boxed cells
        ("imu accel vs valves", "z", "firing", "mean"): -9.0,
    }
    fig = gap_map_figure(_cells(big), THRESHOLD)
    yield fig
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_a_cell_beyond_the_threshold_is_coloured_when_another_is_at_200(gap_map):
    im = gap_map.axes[0].images[0]
    white = im.norm(0.0)
    # a quarter of the way to full colour; a linear scale to 200 gives 0.02: white
    assert abs(im.norm(7.0) - white) > 0.2 and abs(im.norm(THRESHOLD) - white) > 0.2


def test_exactly_the_cells_beyond_the_threshold_are_boxed(gap_map):
    ax = gap_map.axes[0]
    assert len(ax.patches) == 3  # 200, 7 and -9; not 4.7 nor the zeros


def test_the_threshold_is_marked_on_the_colour_bar(gap_map):
    bar = gap_map.axes[1]
    levels = sorted(round(float(line.get_ydata()[0]), 3) for line in bar.lines)
    assert levels == [-THRESHOLD, THRESHOLD]


def test_the_map_says_what_its_axes_and_colours_are(gap_map):
    ax, bar = gap_map.axes
    assert ax.get_xlabel() and ax.get_ylabel()
    assert "[noise sigmas]" in bar.get_ylabel()
    assert f"{THRESHOLD:.1f}" in ax.get_title()


def _series(n=1200, dt=0.1, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    white = rng.standard_normal(n)
    drift = white + 3.0 * (t > 20) * (t < 80)
    held = (t // 20) % 2 == 1
    return [("gyro diff x", t, drift, white, held, dt), ("gyro diff y", t, white, None, held, dt)]


def test_every_axis_of_the_residuals_has_units_and_the_spectra_are_welch():
    import matplotlib.pyplot as plt

    fig = residuals_figure(_series(), "thrust_loss", "accelerometer and gyro")
    try:
        left, right = fig.axes[0::2], fig.axes[1::2]
        assert all("[noise sigmas]" in a.get_ylabel() for a in left)
        assert all(a.get_ylabel() == "PSD [sigma^2/Hz]" for a in right)
        assert "[s]" in left[-1].get_xlabel() and "[Hz]" in right[-1].get_xlabel()
        # white noise of unit variance sits on the white line (one-sided 2 dt), within the
        # scatter of a Welch average (a raw periodogram scatters by a factor 10 and more)
        white = right[1].lines[0].get_ydata()
        assert 0.7 < np.median(white) / (2 * 0.1) < 1.3
        assert np.percentile(white, 95) / np.percentile(white, 5) < 4.0
        # both before and after drawn, each with its running mean, the after one not hiding the before
        labels = [line.get_label() for line in left[0].lines]
        assert any(s.startswith("nominal") for s in labels) and any(s.startswith("with thrust_loss") for s in labels)
    finally:
        plt.close(fig)


def test_the_residuals_shown_are_where_the_gap_was_found(tmp_path):
    import copy

    from bench.gap import bundled
    from bench.gap import null as nullmod
    from bench.gap.diagnose import diagnose
    from bench.gap.report import residual_series
    from bench.sim.flight_log import read_flight_log

    res = diagnose(read_flight_log(bundled.LOG), calibration=nullmod.load())
    assert res["location"]["where"]["stream"] == "gyro vs valve torques"
    series, what = residual_series(res)
    assert what.startswith("accelerometer and gyro") and series[3][0] == "gyro diff x"
    # the same answer with the gap found in the pose stream shows the pose innovations
    moved = copy.copy(res)
    moved["location"] = {**res["location"], "where": {**res["location"]["where"], "stream": "pose position"}}
    series, what = residual_series(moved)
    assert what.startswith("pose innovations") and series[0][0].startswith("r_x")
    # an answer with no effect to show (unexplained, or no gap) where the gap map's
    # largest cell is in the dynamics channel: the nominal rows alone, no "after"
    for verdict, attribution in (("unexplained", res["attribution"]), ("no_gap", [])):
        alone = {**copy.copy(res), "verdict": verdict, "attribution": attribution, "effect_set": None}
        series, what = residual_series(alone)
        assert what.startswith("accelerometer and gyro") and all(s[3] is None for s in series)
