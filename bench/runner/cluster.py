"""Where a campaign's runs execute: a Dask cluster.

By default a local cluster of worker processes on this machine (one thread
each, no dashboard, quiet logs), started once per process and reused by
later campaigns; with ``--scheduler tcp://HOST:PORT`` an existing cluster
whose workers have this project installed (docs/CAMPAIGNS.md). Dask's
nanny starts every worker process with one BLAS / OpenMP thread, so a run
computes the same bits on any worker.
"""

from __future__ import annotations

import atexit
import logging
import os
import warnings

_LOCAL: dict = {}  # workers -> (cluster, client)
_DEFAULTS = {"scheduler": None, "workers": None}
# How long a scheduler's address may take to accept a connection: nothing
# listening is refused at once, an unreachable host within this.
REACH_TIMEOUT_S = 2.0


def default_workers() -> int:
    return os.cpu_count() or 1


def configure(scheduler: str | None = None, workers: int | None = None) -> None:
    """The cluster campaigns in this process use unless told otherwise (the
    command line sets it once, so nested campaigns such as a log's own null
    calibration follow it). A scheduler address is checked here, before any
    run starts: one that accepts no connection is refused (ValueError)."""
    if scheduler is not None:
        check_reachable(scheduler)
    _DEFAULTS.update(scheduler=scheduler, workers=workers)


def check_reachable(scheduler: str, timeout_s: float = REACH_TIMEOUT_S) -> None:
    """Refuse (ValueError, naming --scheduler) an address that is not
    tcp://HOST:PORT or tls://HOST:PORT, or where nothing accepts a TCP
    connection within ``timeout_s`` (Dask's own client retries for its whole
    timeout before it says so)."""
    import socket
    from urllib.parse import urlsplit

    try:
        parts = urlsplit(scheduler)
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if parts.scheme not in ("tcp", "tls") or not host or port is None:
        raise ValueError(f"--scheduler {scheduler}: expected an address such as tcp://HOST:PORT")
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except OSError as exc:
        reason = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
        raise ValueError(f"--scheduler {scheduler}: cannot connect ({reason})") from None


def inside_worker() -> bool:
    try:
        from distributed import get_worker

        get_worker()
        return True
    except (ImportError, ValueError):
        return False


def describe(scheduler: str | None = None, workers: int | None = None) -> str:
    scheduler = scheduler or _DEFAULTS["scheduler"]
    if scheduler:
        return f"the Dask scheduler at {scheduler}"
    n = workers or _DEFAULTS["workers"] or default_workers()
    return f"a local Dask cluster of {n} worker process{'es' if n != 1 else ''}"


def client(scheduler: str | None = None, workers: int | None = None):
    """A connected ``distributed.Client``."""
    from distributed import Client, LocalCluster

    scheduler = scheduler or _DEFAULTS["scheduler"]
    if scheduler:
        key = ("scheduler", scheduler)
        if key not in _LOCAL:
            try:
                _LOCAL[key] = (None, Client(scheduler, timeout="20s"))
            except Exception as exc:  # noqa: BLE001 - whatever answers there, it is no Dask scheduler we can use
                raise ValueError(
                    f"--scheduler {scheduler}: cannot connect, or not a Dask scheduler ({type(exc).__name__})"
                ) from None
        return _LOCAL[key][1]
    n = int(workers or _DEFAULTS["workers"] or default_workers())
    key = ("local", n)
    if key not in _LOCAL or _LOCAL[key][1].status != "running":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
            )
        _LOCAL[key] = (cluster, Client(cluster))
    return _LOCAL[key][1]


def close_all() -> None:
    while _LOCAL:
        _, (cluster, cl) = _LOCAL.popitem()
        try:
            cl.close()
            if cluster is not None:
                cluster.close()
        except Exception:  # noqa: BLE001 - shutting down at exit; nothing to report to
            pass


atexit.register(close_all)
