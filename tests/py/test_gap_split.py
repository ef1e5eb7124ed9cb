"""The training / held-out split excites every fired valve in both halves
where any blocking can (bench/gap/quantify.py excitation_split), names the
valves none can, and their parameters are reported not identifiable, never
as a value with zero uncertainty (bench/gap/diagnose.py parameters)."""

from types import SimpleNamespace

import numpy as np

from bench.gap.quantify import MIN_SHARE, Split, block_edges, excitation_split

T = np.arange(1, 6001) * 0.1  # a 600 s log at 10 Hz


def _fired(windows: dict, k: int = 4) -> np.ndarray:
    """(N, K) open seconds per sample: valve i open in each of its windows."""
    f = np.zeros((T.size, k))
    for i, spans in windows.items():
        for a, b in spans:
            f[(T > a) & (T <= b), i] = 0.1
    return f


def _halves(sp: Split, fired: np.ndarray) -> np.ndarray:
    tr, ho = sp.masks(T)
    return np.stack([fired[tr].sum(axis=0), fired[ho].sum(axis=0)], axis=1)


def test_six_even_blocks_are_kept_when_they_excite_every_valve():
    fired = _fired({i: [(10 + 100 * j + 5 * i, 30 + 100 * j + 5 * i) for j in range(6)] for i in range(4)})
    sp = excitation_split(T, fired)
    np.testing.assert_array_equal(sp.edges, block_edges(T[0], T[-1]))
    assert sp.train_parity == 0 and not sp.unexcited


def test_a_valve_fired_only_in_held_out_blocks_is_given_to_both_halves():
    # Valve 3 fires only inside the second and fourth of six blocks (held out by default).
    windows = {i: [(10 + 100 * j, 40 + 100 * j) for j in range(6)] for i in range(3)}
    windows[3] = [(120.0, 170.0), (320.0, 370.0)]
    fired = _fired(windows)
    default = _halves(Split(block_edges(T[0], T[-1])), fired)
    assert default[3, 0] == 0.0  # the six-block split never trains on valve 3
    sp = excitation_split(T, fired)
    h = _halves(sp, fired)
    assert np.all(h > 0.0) and not sp.unexcited
    assert np.all(h.min(axis=1) >= MIN_SHARE * h.sum(axis=1) - 1e-9)


def test_a_valve_fired_in_one_short_window_is_named_with_its_times():
    windows = {i: [(10 + 100 * j, 40 + 100 * j) for j in range(6)] for i in range(3)}
    windows[3] = [(130.0, 130.25)]  # fired 0.2 s, once
    sp = excitation_split(T, _fired(windows))
    assert [u["valve"] for u in sp.unexcited] == [3]
    assert "thruster 3 fired only at 130 s, never in the" in sp.unexcited[0]["why"]


def test_parameters_of_an_unexcited_valve_or_without_spread_have_no_value():
    from bench.gap.load import LogData
    from bench.gap.verdict import parameters

    d = LogData.__new__(LogData)
    d.desc = None
    sp = Split(block_edges(0.0, 1.0), unexcited=[{"valve": 2, "why": "thruster 2 fired only at 130-150 s"}])
    ctx = SimpleNamespace(d=d, split=sp)
    theta, sigma = np.full(8, 0.1), np.full(8, 0.01)
    sigma[5] = 0.0
    p = parameters(ctx, "thrust_loss", theta, sigma)
    assert p["loss_0 [1]"] == {"value": 0.1, "sigma": 0.01, "identified": True}
    assert (
        p["loss_2 [1]"]["value"] is None and "thruster 2 fired only at 130-150 s" in p["loss_2 [1]"]["not_identifiable"]
    )
    assert p["loss_5 [1]"]["value"] is None and "no signature" in p["loss_5 [1]"]["not_identifiable"]
    tilt = parameters(ctx, "thruster_misalignment", np.full(24, 0.01), np.full(24, 0.001))
    assert [k for k, v in tilt.items() if v["value"] is None] == ["phi_2x [rad]", "phi_2y [rad]", "phi_2z [rad]"]
