"""The diagnosis report's Markdown (bench/gap/report.py)."""

from bench.gap.report import TABLE_PARAMETERS, _parameters_cell


def _p(value, sigma):
    return {"value": value, "sigma": sigma}


def test_a_short_parameter_list_is_shown_whole():
    cell = _parameters_cell(
        {"b_x [m/s^2]": _p(1e-3, 1e-4), "b_y [m/s^2]": _p(1e-5, 1e-4), "b_z [m/s^2]": _p(None, None)}
    )
    assert cell == "b_x [m/s^2] = 0.001 +/- 0.0001; b_y [m/s^2] = 1e-05 +/- 0.0001; b_z [m/s^2]: not identifiable"


def test_a_long_parameter_list_shows_the_significant_ones_first():
    """A nozzle tilt has two angles per valve: 24 for twelve valves, which
    made one cell of 24 entries."""
    params = {f"a_{i} [rad]": _p(1e-4, 1e-3) for i in range(24)}
    params["a_5 [rad]"] = _p(4e-3, 1e-3)  # 4 sigma
    params["a_17 [rad]"] = _p(-9e-3, 1e-3)  # 9 sigma
    params["a_20 [rad]"] = _p(None, None)
    cell = _parameters_cell(params)
    assert len(params) > TABLE_PARAMETERS
    assert cell == "2 of 24 beyond 2 sigma: a_17 [rad] = -0.009 +/- 0.001; a_5 [rad] = 0.004 +/- 0.001 (all below)"
    none = _parameters_cell({f"a_{i}": _p(0.0, 1.0) for i in range(8)})
    assert none == "0 of 8 beyond 2 sigma (all below)"


def test_the_gap_map_says_how_its_gyro_regime_columns_differ():
    """The firing columns of a thrust loss's gyro rows read near zero while
    the answer says the effect acts while firing: the page says why."""
    from bench.gap.report import _gap_map_lines

    text = " ".join(_gap_map_lines({"top_cells": []}))
    assert "raw sample-to-sample differences" in text and "'all' columns test the whitened rows" in text
