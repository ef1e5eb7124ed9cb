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


def _tilt(n_not: int) -> dict:
    """A 24-parameter nozzle tilt from a joint fit: a_20 well beyond 2 sigma,
    the first ``n_not`` not identified (sigmas of 1 rad and more against a
    bound of 0.5 rad, their values kept inside it)."""
    params = {f"a_{i} [rad]": _p(0.3, 1.0 + i, False) for i in range(n_not)}
    params |= {f"a_{i} [rad]": _p(1e-4, 1e-3, True) for i in range(n_not, 24)}
    params["a_20 [rad]"] = _p(5e-3, 1e-3, True)
    return params


def _set_answer(verdict: str, members: list, explains: bool) -> dict:
    return {
        "verdict": verdict,
        "gap_detected": True,
        "attribution": [],
        "effects": members if verdict != "unexplained" else [],
        "statistics": {"map_threshold": 4.74},
        "effect_set": {
            "members": members,
            "shrink_heldout": {"measurable": True, "fraction": 0.62, "ci95": [0.5, 0.7]},
            "dll_heldout": 120.0,
            "map_max_abs_z_after": 9.1,
            "explains_heldout": explains,
            "partly_explains": verdict == "partly_explained",
        },
    }


def test_a_set_answer_lists_each_member_its_share_and_its_parameters():
    """A partly explained answer of a nozzle tilt and a gyro bias, fitted
    together: the page shows each member's share and its jointly fitted
    parameters, the tilt's 16 not identified without a value."""
    from bench.gap.report import _set_lines

    tilt = {
        "effect": "thruster_misalignment",
        "kind": "dynamics",
        "adds_shrink": 0.41,
        "adds_dll_heldout": 80.2,
        "parameters": _tilt(16),
    }
    bias = {
        "effect": "gyro_bias",
        "kind": "sensor",
        "adds_shrink": None,
        "adds_dll_heldout": 12.5,
        "parameters": {"b_x [rad/s]": _p(2e-3, 2e-4, True), "b_y [rad/s]": _p(0.4, 3.0, False)},
    }
    text = "\n".join(_set_lines(_set_answer("partly_explained", [tilt, bias], explains=False)))
    assert "## The selected set: thruster_misalignment + gyro_bias" in text
    assert "The partial answer: each member earns its place on the held-out data" in text
    assert "shrink 0.62 [0.50, 0.70], log-likelihood +120.0" in text
    assert (
        "| thruster_misalignment | dynamics | 0.41 | +80.2 | 1 of 24 beyond 2 sigma, 16 not identified: "
        "a_20 [rad] = 0.005 +/- 0.001 (all below) |" in text
    )
    assert (
        "| gyro_bias | sensor | not measurable | +12.5 | b_x [rad/s] = 0.002 +/- 0.0002; "
        "b_y [rad/s]: not identified (sigma 3 beyond the physical bound) |" in text
    )
    assert "thruster_misalignment in the set, every parameter (24 parameters, 16 not identified):" in text
    assert "- a_3 [rad]: not identified (sigma 4 beyond the physical bound)" in text
    assert "a_3 [rad] = " not in text and "b_y [rad/s] = " not in text
    assert "17 of the set's 26 parameters are not identified" in text


def test_a_selected_set_that_is_no_answer_is_shown_as_such():
    """An unexplained answer whose selected set is a nozzle tilt with 35 of
    its 36 parameters not identified (a 12 kg log with a hinged panel, as
    its set refit read before it was refitted as the tilt alone is): the
    page shows the fit and says it is no answer."""
    from bench.gap.report import _set_lines

    params = {f"phi_{i // 3}{'xyz'[i % 3]} [rad]": _p(0.01, 1e3 + i, False) for i in range(36)}
    params["phi_10y [rad]"] = _p(-0.0164, 0.024, True)
    tilt = {
        "effect": "thruster_misalignment",
        "kind": "dynamics",
        "adds_shrink": -0.04,
        "adds_dll_heldout": -148.4,
        "parameters": params,
    }
    text = "\n".join(_set_lines(_set_answer("unexplained", [tilt], explains=False)))
    assert "## The selected set: thruster_misalignment" in text
    assert "Not an answer: the set's refit does not pass the held-out tests" in text
    assert (
        "| thruster_misalignment | dynamics | -0.04 | -148.4 | 0 of 36 beyond 2 sigma, 35 not identified (all below) |"
        in text
    )
    assert "thruster_misalignment in the set, every parameter (36 parameters, 35 not identified):" in text
    assert "- phi_10y [rad] = -0.0164 +/- 0.024" in text and "- phi_0x [rad]: not identified (sigma 1e+03" in text
    assert "35 of the set's 36 parameters are not identified" in text
    # beside a single answer, the set that did not replace it
    single = _set_answer("ambiguous", [tilt], explains=False) | {"attribution": [{"effect": "thrust_loss"}]}
    assert "Not the answer (thrust_loss alone is)" in "\n".join(_set_lines(single))


def test_no_selected_set_no_section():
    from bench.gap.report import _set_lines

    assert _set_lines({"verdict": "explained", "effect_set": None}) == []


def test_the_page_and_the_printed_answer_count_a_member_alike():
    from bench.gap.answers import fitted_text
    from bench.gap.report import _set_lines

    tilt = {"effect": "thruster_misalignment", "kind": "dynamics", "adds_shrink": 0.5, "adds_dll_heldout": 9.0}
    bias = {"effect": "gyro_bias", "kind": "sensor", "adds_shrink": 0.4, "adds_dll_heldout": 7.0}
    out = _set_answer(
        "explained",
        [tilt | {"parameters": _tilt(16)}, bias | {"parameters": {"b_x [rad/s]": _p(2e-3, 2e-4, True)}}],
        explains=True,
    )
    printed, page = fitted_text(out), "\n".join(_set_lines(out))
    assert "thruster_misalignment: a_20 [rad] 0.005 +/- 0.001 (24 parameters, 16 not identified)" in printed
    assert "thruster_misalignment in the set, every parameter (24 parameters, 16 not identified):" in page
    assert "The answer: refitted together, the set explains the held-out data." in page


def test_a_parameter_held_at_its_bound_shows_the_bound_and_no_sigma():
    """Losses pinned at their lower bound 0 by the bounded fit: the page shows
    them at the bound, counts them, and never beyond 2 sigma."""
    from bench.gap.report import _set_lines

    held = {"value": 4.45e-15, "sigma": None, "identified": True, "at_bound": "lower", "bound": 0.0}
    loss = {f"loss_{i} [1]": _p(2e-3, 4e-3, True) for i in range(8)}
    loss["loss_3 [1]"] = _p(0.0616, 0.0036, True)
    loss["loss_5 [1]"] = loss["loss_7 [1]"] = held
    cell = _parameters_cell(loss)
    assert cell == "1 of 8 beyond 2 sigma, 2 at a bound: loss_3 [1] = 0.0616 +/- 0.0036 (all below)"
    member = {"effect": "thrust_loss", "kind": "dynamics", "adds_shrink": 0.98, "adds_dll_heldout": 5788.8}
    text = "\n".join(_set_lines(_set_answer("explained", [member | {"parameters": loss}], explains=True)))
    assert "- loss_5 [1] = 0, at its lower bound (no sampling sigma)" in text
    assert "4.45e-15" not in text
    assert "2 of the set's 8 parameters are held at a physical bound" in text
    short = _parameters_cell({"s_x [1]": held | {"value": -0.49999999975, "bound": -0.5}, "s_y [1]": _p(-0.02, 0.02)})
    assert short == "s_x [1] = -0.5, at its lower bound (no sampling sigma); s_y [1] = -0.02 +/- 0.02"
