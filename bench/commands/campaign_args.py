"""The arguments every campaign command shares: where its runs execute
(a local Dask cluster, or an existing one) and where their results are kept
(bench/runner, docs/CAMPAIGNS.md)."""

from __future__ import annotations

from bench.commands.args import number


def add_campaign_arguments(p, workers: bool = True) -> None:
    if workers:
        p.add_argument(
            "--workers",
            type=number(int, 1, 1024),
            default=None,
            help="local Dask worker processes (1 to 1024; default: all cores)",
        )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="run on the existing Dask cluster at this scheduler address (its workers need this project "
        "installed) instead of a local one",
    )
    p.add_argument(
        "--store",
        default=None,
        metavar="DIR",
        help="results store: each finished run is kept here at once, and a re-run with the same "
        "arguments skips the runs stored (default: $PROXOPS_CACHE/campaigns, else "
        "~/.cache/proxops/campaigns)",
    )
    p.add_argument(
        "--summarise-only", action="store_true", help="run nothing: the summary of the runs stored for these arguments"
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the runs stored as failed")


def campaign_from(args, name: str, arguments: dict, progress: bool = True):
    """The Campaign (bench/runner/runner.py) of a command's parsed args;
    ``arguments``: everything the runs' results depend on (the store's key)."""
    from bench.runner import cluster
    from bench.runner.runner import Campaign
    from bench.runner.store import RunStore

    if args.scheduler is not None and "://" not in args.scheduler:
        raise ValueError(f"--scheduler {args.scheduler}: expected an address such as tcp://HOST:PORT")
    workers = getattr(args, "workers", None)
    cluster.configure(args.scheduler, workers)
    return Campaign(
        RunStore(name, arguments, root=args.store),
        scheduler=args.scheduler,
        workers=workers,
        progress=progress,
        summarise_only=args.summarise_only,
        retry_failed=args.retry_failed,
    )


def report_campaign(res: dict) -> None:
    """One line on what the campaign ran, kept, and lost."""
    info = res.get("campaign") or {}
    if not info:
        return
    failed, missing = info.get("failed_runs", []), info.get("missing_runs", [])
    print(
        f"results store: {info.get('store') or 'none'}; scored {info.get('runs_scored')} of "
        f"{info.get('runs_drawn')} runs"
        + (f", {len(failed)} failed" if failed else "")
        + (f", {len(missing)} not stored yet" if missing else "")
    )
    for f in failed[:5]:
        print(f"  run {f['run']} (seed {f['seed']}) failed: {f['error']}")
