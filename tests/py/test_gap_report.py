"""The diagnosis report's Markdown (bench/gap/report.py)."""

from bench.gap.report import TABLE_PARAMETERS, _parameters_cell, _ranking_lines


def _p(value, sigma, identified=None):
    p = {"value": value, "sigma": sigma}
    if identified is not None:
        p["identified"] = identified
    return p


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
    assert (
        cell
        == "2 of 24 beyond 2 sigma, 1 not identified: a_17 [rad] = -0.009 +/- 0.001; a_5 [rad] = 0.004 +/- 0.001 (all below)"
    )
    none = _parameters_cell({f"a_{i}": _p(0.0, 1.0) for i in range(8)})
    assert none == "0 of 8 beyond 2 sigma (all below)"


def test_parameters_not_identified_show_no_value_and_are_counted():
    """A nozzle tilt fitted with sigmas of 1 to 16 rad (bound 0.5 rad): the
    values say nothing, the page says "not identified" and how many."""
    short = _parameters_cell({"c_x [m]": _p(0.05, 0.3, False), "c_y [m]": _p(0.02, 0.001, True)})
    assert short == "c_x [m]: not identified (sigma 0.3 beyond the physical bound); c_y [m] = 0.02 +/- 0.001"
    params = {f"a_{i} [rad]": _p(0.3, 1.0 + i, False) for i in range(16)}
    params |= {f"a_{i} [rad]": _p(1e-4, 1e-3, True) for i in range(16, 24)}
    params["a_20 [rad]"] = _p(5e-3, 1e-3, True)
    params["a_0 [rad]"] = _p(40.0, 1.0, False)  # beyond 2 sigma, but not identified
    cell = _parameters_cell(params)
    assert cell == "1 of 24 beyond 2 sigma, 16 not identified: a_20 [rad] = 0.005 +/- 0.001 (all below)"
    row = {
        "effect": "thruster_misalignment",
        "kind": "dynamics",
        "evidence": {"ln_bf": 1.0, "bic": 1.0, "dll_train": 1.0, "dll_heldout": -1.0},
        "shrink_heldout": {"measurable": False},
        "explains_heldout": False,
        "parameters": params,
    }
    text = "\n".join(_ranking_lines({"attribution": [row], "screening": []}))
    assert "thruster_misalignment, every parameter (24 parameters, 16 not identified):" in text
    assert "- a_0 [rad]: not identified (sigma 1 beyond the physical bound)" in text
    assert "a_0 [rad] = " not in text and "- a_20 [rad] = 0.005 +/- 0.001" in text


def test_the_gap_map_says_how_its_gyro_regime_columns_differ():
    """The firing columns of a thrust loss's gyro rows read near zero while
    the answer says the effect acts while firing: the page says why."""
    from bench.gap.report import _gap_map_lines

    text = " ".join(_gap_map_lines({"top_cells": []}))
    assert "raw sample-to-sample differences" in text and "'all' columns test the whitened rows" in text
