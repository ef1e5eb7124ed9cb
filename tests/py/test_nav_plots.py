"""`proxops nav --plots`: the uncertainty per state block in its own unit
(no trace of P summing m^2, (m/s)^2 and rad^2) and the errors of every kept
run, each with its own 3-sigma bounds."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from bench.commands import nav
from bench.report import matplotlib_agg
from bench.sim.scenario_docking import ScenarioConfig, run_docking


@pytest.fixture(scope="module")
def runs():
    return [run_docking(seed, ScenarioConfig(t_max_s=10.0)) for seed in (1, 2, 3)]


def _figures(draw, runs, tmp_path) -> list:
    """The figures draw(plt, runs, ...) makes, kept instead of closed."""
    plt = matplotlib_agg()
    kept = []
    draw(SimpleNamespace(subplots=plt.subplots, close=kept.append), runs, tmp_path / "x.png")
    for f in kept:
        f.canvas.draw()  # drawn as saved, then released
        plt.close(f)
    return kept


def test_uncertainty_per_block_in_its_unit_for_every_run(runs, tmp_path):
    (fig,) = _figures(nav._sigma_plot, runs, tmp_path)
    labels = [a.get_ylabel() for a in fig.axes]
    assert labels == ["position 1-sigma [m]", "velocity 1-sigma [m/s]", "attitude 1-sigma [rad]"]
    assert all(len(a.lines) == len(runs) for a in fig.axes)
    assert "trace" not in fig.axes[0].get_title().lower()


def test_errors_of_every_kept_run_with_their_bounds(runs, tmp_path):
    figs = _figures(lambda plt, r, path: nav._error_plots(plt, r, tmp_path), runs, tmp_path)
    assert len(figs) == 3
    for fig in figs:
        for a in fig.axes:
            assert a.get_ylabel().endswith(("[m]", "[m/s]", "[rad]"))
            assert len(a.lines) == 3 * len(runs)  # error and +/- 3 sigma of each run
