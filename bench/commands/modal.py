"""`proxops modal` and `proxops modal-timing`: the command lines of the modal
estimator's study (bench/campaigns/modal_study.py: the simulation and
experiment of "Shape, Motion, and Parameter Estimation of Large Flexible
Space Structures using Range Images" (Lichter and Dubowsky)) and of its
timing grid (bench/perf/modal_timing.py: that paper's Table I)."""

from __future__ import annotations

import os
from pathlib import Path

from bench.commands.args import HelpFormatter, number, one_line_errors, seed
from bench.commands.campaign_args import add_campaign_arguments, campaign_from
from bench.report import report_dir, write_json


def register(sub):
    _register_modal(sub)
    _register_timing(sub)


def _register_modal(sub):
    p = sub.add_parser(
        "modal",
        help="modal estimator: plate simulation or quadruple-pendulum experiment analogue",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops modal")
    periods = number(float, 0.0, 1000.0, lo_open=True)
    p.add_argument(
        "--scenario",
        choices=["structure", "pendulum"],
        required=True,
        help="structure: the vibrating plate seen in range images; pendulum: the quadruple pendulum",
    )
    p.add_argument(
        "--modes",
        type=number(int, 1, 50),
        default=None,
        help="modes estimated (structure: 1 to 50, default 10; pendulum: 3, the default)",
    )
    p.add_argument("--trials", type=number(int, 1, 1000), default=1, help="trials (1 to 1000, default 1)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the first trial (trial k: seed + k), any integer >= 0")
    p.add_argument(
        "--filter",
        choices=["bank", "joint"],
        default="bank",
        help="bank: one filter per mode (the default); joint: one filter over all modes",
    )
    p.add_argument(
        "--images",
        type=number(int, 2, 100000),
        default=None,
        help="images per trial, 2 to 100000 (default: structure 180, pendulum 150)",
    )
    p.add_argument(
        "--dt",
        type=number(float, 0.0, 1e5, lo_open=True),
        default=None,
        help="image interval [s], > 0 and <= 1e5 (default: structure 60, pendulum 1/15)",
    )
    _add_structure_options(p, periods)
    p.add_argument("--json", default=None, help="write the results here (JSON)")
    p.add_argument("--plots", default=None, help="folder for the figures")
    add_campaign_arguments(p)
    p.set_defaults(func=main)


def _add_structure_options(p, periods):
    """The options that apply to the plate (structure) scenario only."""
    p.add_argument(
        "--range-noise",
        type=number(float, 0.0, 1.0, lo_open=True, hi_open=True),
        default=0.03,
        metavar="FRAC",
        help="structure: range noise as a fraction of the range, in (0, 1) (default 0.03, the published experiment's)",
    )
    p.add_argument(
        "--batch-ml-at",
        type=periods,
        nargs="+",
        default=(),
        metavar="PERIODS",
        help="structure: also fit the batch maximum-likelihood reference to every coarse estimate up to "
        "these times [lowest-mode periods] and compare its shape error with the filter's",
    )
    p.add_argument(
        "--crb-at",
        type=periods,
        nargs="+",
        default=(),
        metavar="PERIODS",
        help="structure: also compute the Cramer-Rao bounds of each run's coarse estimates at these times "
        "[lowest-mode periods] and set the filter's frequency and shape errors beside them",
    )
    p.add_argument(
        "--acquire-at",
        type=periods,
        default=None,
        metavar="PERIODS",
        help="structure: also acquire the frequencies at this time [lowest-mode periods] by a search over "
        "every image so far, replay a new flight joint filter from them and run it on; scored at "
        "--crb-at",
    )
    p.add_argument(
        "--acquire-with",
        choices=["flight", "batch-ml"],
        default="flight",
        help="structure: the search for --acquire-at: the flight ModalAcquisition (default) or the "
        "bench's batch ML fit",
    )
    p.add_argument(
        "--acquire-grid-sigmas",
        type=number(float, 0.0, 100.0, lo_open=True),
        default=3.0,
        metavar="K",
        help="structure: the flight search's frequency grid spans +-K a priori sigmas (default 3; the "
        "a priori sigma is 10 %% of each frequency)",
    )
    p.add_argument(
        "--points-at",
        choices=["measured", "footprint"],
        default="measured",
        help="structure: evaluate the mode shapes at the measured point (default, as published) or where "
        "the ray meets the undeformed plane",
    )
    p.add_argument(
        "--coarse-check",
        action="store_true",
        help="structure: also check every image's coarse amplitudes against the truth with their "
        "covariance (NEES, per-mode bias)",
    )
    p.add_argument(
        "--ut-alpha",
        type=number(float, 0.0, 10.0, lo_open=True),
        default=1.0,
        help="structure: unscented-transform spread alpha of the filters (default 1: sigma points at "
        "sqrt(n) standard deviations)",
    )


def _register_timing(sub):
    t = sub.add_parser(
        "modal-timing",
        help="timing grid of the modal estimator: flight code vs numpy vs the published figures",
        formatter_class=HelpFormatter,
    )
    one_line_errors(t, "proxops modal-timing")
    t.add_argument(
        "--bench-exe",
        action="append",
        default=[],
        metavar="[LABEL=]PATH",
        help="bench_modal executable (Google Benchmark) for the full flight grid; repeat with labels "
        "(e.g. portable=build/bench-rel/bench_modal v3=build/bench-v3/bench_modal) to set builds "
        "side by side in one run",
    )
    t.add_argument("--max-points", type=number(int, 1, 10**7), default=100000, help="1 to 1e7 (default 100000)")
    t.add_argument("--repeats", type=number(int, 1, 1000), default=5, help="1 to 1000 (default 5)")
    t.add_argument("--json", default=None, help="write the timing grid here (JSON)")
    t.set_defaults(func=timing_main)


def _pendulum_spec(args) -> dict:
    if args.modes != 3:
        raise ValueError("the pendulum scenario estimates 3 modes (--modes 3)")
    dur = (args.images or 150) * (args.dt or 1 / 15)
    return {
        "scenario": "pendulum",
        "kwargs": {"kind": args.filter, "duration_s": dur, "rate_hz": 1 / (args.dt or 1 / 15)},
    }


def _structure_spec(args) -> dict:
    if not 0.0 < args.range_noise < 1.0:
        raise ValueError(f"--range-noise must be a fraction of the range in (0, 1), got {args.range_noise}")
    return {
        "scenario": "structure",
        "kwargs": dict(
            n_modes=args.modes,
            kind=args.filter,
            n_images=args.images or 180,
            dt_s=args.dt or 60.0,
            noise_frac=args.range_noise,
            batch_ml_periods=tuple(args.batch_ml_at),
            crb_periods=tuple(args.crb_at),
            acquire_periods=args.acquire_at,
            acquire_with=args.acquire_with,
            acquire_grid_sigmas=args.acquire_grid_sigmas,
            ut_alpha=args.ut_alpha,
            points_at=args.points_at,
            coarse_check=args.coarse_check,
        ),
    }


def main(args):
    """The study (bench/campaigns/modal_study.py) for the chosen scenario:
    its trials as a campaign, their summary, the first trial's figures."""
    from bench.campaigns import modal_study

    if args.modes is None:
        args.modes = 3 if args.scenario == "pendulum" else 10
    spec = _pendulum_spec(args) if args.scenario == "pendulum" else _structure_spec(args)
    campaign = campaign_from(args, f"modal-{spec['scenario']}", {"seed": args.seed, **spec})
    trials = modal_study.run_trials(campaign, spec, args.seed, args.trials, keep_first_series=bool(args.plots))
    out = modal_study.summarise(trials, spec)
    if args.plots:
        modal_study.plot(trials[0], spec, report_dir(args.plots))
    if args.json:
        write_json(args.json, out, strict=True)
    return 0


def timing_main(args):
    """The timing grid (bench/perf/modal_timing.py) of the builds given."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from bench.perf import modal_timing

    out = modal_timing.timing_grid(_labelled_exes(args.bench_exe), args.max_points, args.repeats)
    if args.json:
        write_json(args.json, out, strict=True)
    return 0


def _labelled_exes(specs):
    """[LABEL=]PATH -> {label: path}; one unlabelled exe is "flight"."""
    out = {}
    for spec in specs:
        label, sep, path = spec.partition("=")
        if not sep:
            label, path = "flight", spec
        if not label.isidentifier():
            raise SystemExit(f"--bench-exe {spec!r}: the label must be a word (letters, digits, _)")
        if label in out:
            raise SystemExit(f"--bench-exe: label {label!r} given twice")
        if not Path(path).is_file():
            raise SystemExit(f"--bench-exe {spec!r}: no such file {path}")
        out[label] = path
    return out
