"""The answer in words (bench/gap/answers.py): the fitted parameters it
shows."""

from bench.gap.answers import fitted_text, identified, not_identified_count


def _p(value, sigma, ok=True):
    return {"value": value, "sigma": sigma, "identified": ok}


def _tilt(n_not: int) -> dict:
    """A 24-parameter nozzle tilt: valve 3's x tilt well beyond 2 sigma, the
    first ``n_not`` not identified (sigmas of 1 to 16 rad against a bound
    of 0.5 rad, values kept inside it)."""
    p = {f"phi_{i // 3}{'xyz'[i % 3]} [rad]": _p(1e-3, 2e-3) for i in range(24)}
    p["phi_3x [rad]"] = _p(0.04, 0.005)
    for i, k in enumerate(list(p)[:n_not]):
        p[k] = _p(0.45, 1.0 + i, ok=False)
    return p


def _answer(params: dict, verdict="partly_explained") -> dict:
    return {
        "gap_detected": True,
        "verdict": verdict,
        "attribution": [],
        "effects": [{"effect": "thruster_misalignment", "parameters": params}],
    }


def test_parameters_not_identified_are_counted_never_shown():
    p = _tilt(8)
    p["phi_0y [rad]"] = _p(2.5, 1.0, ok=False)  # beyond 2 sigma, but not identified
    text = fitted_text(_answer(p))
    assert text == "fitted (beyond 2 sigma): phi_3x [rad] 0.04 +/- 0.005 (24 parameters, 8 not identified)"


def test_an_effect_with_nothing_identified_beyond_2_sigma_says_so():
    p = _tilt(16)  # valve 3's x tilt among them
    assert fitted_text(_answer(p)) == "fitted (beyond 2 sigma): none (24 parameters, 16 not identified)"


def test_every_parameter_identified_reads_as_before():
    assert fitted_text(_answer(_tilt(0))) == "fitted (beyond 2 sigma): phi_3x [rad] 0.04 +/- 0.005"


def test_an_answer_without_the_flag_counts_only_the_missing_values():
    old = {"a": {"value": 0.1, "sigma": 0.01}, "b": {"value": None, "sigma": None, "not_identifiable": "why"}}
    assert identified(old["a"]) and not identified(old["b"]) and not_identified_count(old) == 1


def test_a_parameter_held_at_its_bound_is_never_beyond_2_sigma():
    """A loss of 4.45e-15 pinned at its lower bound 0 was listed first as
    beyond 2 sigma (its "sigma" 1.8e-18): it is said to be at the bound."""
    from bench.gap.answers import at_bound, significant

    loss = {f"loss_{i} [1]": _p(2e-3, 4e-3) for i in range(8)}
    loss["loss_3 [1]"] = _p(0.0616, 0.0036)
    for k in ("loss_5 [1]", "loss_7 [1]"):
        loss[k] = {"value": 4.45e-15, "sigma": None, "identified": True, "at_bound": "lower", "bound": 0.0}
    assert at_bound(loss["loss_5 [1]"]) and not significant(loss["loss_5 [1]"]) and significant(loss["loss_3 [1]"])
    # the flag alone, whatever sigma an older answer kept, is never beyond 2 sigma
    assert not significant(loss["loss_7 [1]"] | {"sigma": 2e-18})
    r = _answer(loss, "explained") | {"effects": [{"effect": "thrust_loss", "parameters": loss}]}
    assert (
        fitted_text(r)
        == "fitted (beyond 2 sigma): loss_3 [1] 0.0616 +/- 0.0036 (at the lower bound 0: loss_5 [1], loss_7 [1])"
    )
