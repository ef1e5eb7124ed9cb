"""Runs a campaign's runs as Dask tasks and keeps one record per run.

``Campaign.map(stage, fn, items)`` is the only way a campaign runs its runs:
it reads the store, leaves out the runs already there (same input, same
stage), submits the rest to the cluster, writes each record the moment its
run finishes, shows a progress bar, and gives back every record in run
order. Each run gets its whole input (seed included) from the campaign's
arguments and its index, never from the worker it lands on or from the
runs before it, so 1, 2 or 20 workers and a resumed campaign give the same
records. A run that raises is recorded as failed with its error, traceback
and seed; the campaign goes on. A worker that dies takes no record with it:
Dask runs its task again elsewhere.
"""

from __future__ import annotations

import socket
import sys
import time
import traceback

from bench.runner import cluster, records
from bench.runner.progress import ProgressBar
from bench.runner.store import MemoryStore

_NO_SHARED = "__no_shared__"


def _identity(x):
    return x


def execute(fn, index: int, item, shared=_NO_SHARED) -> str:
    """One run on a worker: its record as JSON text (encoded here, so a result
    the store cannot hold is a failed run too)."""
    t0 = time.perf_counter()
    rec = {"index": int(index), "worker": _worker_name()}
    try:
        out = fn(item) if isinstance(shared, str) and shared == _NO_SHARED else fn(item, shared)
        rec.update(ok=True, result=out)
        rec["elapsed_s"] = time.perf_counter() - t0
        return records.dumps(rec)
    except Exception as exc:  # noqa: BLE001 - a run's failure is recorded, not fatal
        rec.update(
            ok=False,
            error=f"{type(exc).__name__}: {exc}",
            message=str(exc),
            traceback=traceback.format_exc(),
            elapsed_s=time.perf_counter() - t0,
        )
        return records.dumps({k: v for k, v in rec.items() if k != "result"})


class MissingRuns(ValueError):
    """--summarise-only found no stored runs."""


class Campaign:
    """How and where a campaign's runs execute and are kept.

    store: a RunStore (on disk) or None (in memory, nothing kept).
    scheduler / workers: an existing cluster's address, or the local
    cluster's size (default: bench.runner.cluster's defaults).
    summarise_only: run nothing; missing runs come back as None.
    retry_failed: run again the runs stored as failed."""

    def __init__(
        self,
        store=None,
        scheduler: str | None = None,
        workers: int | None = None,
        progress: bool = True,
        summarise_only: bool = False,
        retry_failed: bool = False,
        stream=None,
    ):
        self.store = store if store is not None else MemoryStore()
        if summarise_only and not self.store.exists():
            raise MissingRuns(
                f"nothing stored for these arguments (no {self.store.path}); "
                "run the campaign without --summarise-only first"
            )
        if not summarise_only:
            self.store.open()
        self.scheduler, self.workers = scheduler, workers
        self.progress, self.summarise_only, self.retry_failed = progress, summarise_only, retry_failed
        self.stream = stream or sys.stderr
        self.stages: dict = {}  # stage -> counts

    def say(self, text: str) -> None:
        if self.progress or self.store.path is not None:
            print(text, file=self.stream, flush=True)

    def where(self) -> str:
        return cluster.describe(self.scheduler, self.workers)

    def map(self, stage: str, fn, items, idents=None, seeds=None, shared=_NO_SHARED, label: str | None = None) -> list:
        """[record] in item order (None: not stored, with summarise_only; and
        for an item that is None, which is not run). idents: what identifies each item's input (JSON; default the item);
        seeds: each run's seed, for the failure record (default ident["seed"]
        when ident is a dict)."""
        items = list(items)
        idents = list(items if idents is None else idents)
        if seeds is None:
            seeds = [i.get("seed") if isinstance(i, dict) else None for i in idents]
        label = label or stage
        want = [records.sha256({"stage": stage, "input": ident}) for ident in idents]
        stored = self.store.load(stage)
        bad = list(getattr(self.store, "damaged", []))
        if bad:
            self.say(
                f"{label}: {len(bad)} stored record(s) damaged, not used"
                + (" (counted missing)" if self.summarise_only else " (run again)")
                + f": {bad[0]}"
            )
        out: list = [None] * len(items)
        todo = []
        n_items = sum(it is not None for it in items)
        for i, sha in enumerate(want):
            if items[i] is None:
                continue
            rec = stored.get(i)
            if rec is not None and rec.get("input_sha256") == sha and (rec.get("ok") or not self.retry_failed):
                out[i] = rec
            else:
                todo.append(i)
        n_stored = n_items - len(todo)
        n_failed_stored = sum(1 for r in out if r is not None and not r.get("ok"))
        where = f"results store {self.store.path}: " if self.store.path is not None else ""
        if self.summarise_only:
            self.say(
                f"{label}: {where}{n_stored} of {n_items} runs stored"
                + (f" ({n_failed_stored} failed)" if n_failed_stored else "")
                + (f", {len(todo)} missing (left out of the summary)" if todo else "")
            )
            self.stages[stage] = {"runs": n_items, "stored": n_stored, "ran": 0, "missing": len(todo)}
            return out
        if n_stored:
            self.say(
                f"{label}: {where}{n_stored} of {n_items} runs already stored"
                + (f" ({n_failed_stored} failed)" if n_failed_stored else "")
                + (f", skipping them; running {len(todo)} on {self.where()}" if todo else ", nothing to run")
            )
        elif todo:
            self.say(f"{label}: {where}running {len(todo)} runs on {self.where()}")
        bar = ProgressBar(label, n_items, stored=n_stored, enabled=self.progress and bool(todo), stream=self.stream)
        try:
            for i, text in self._run(fn, items, todo, shared):
                rec = records.loads(text)
                rec["input_sha256"] = want[i]
                rec["seed"] = seeds[i]
                if rec.get("ok"):  # a damaged or edited result is then seen when read back (store.damaged)
                    rec["result_sha256"] = records.sha256(rec.get("result"))
                self.store.write(stage, rec)
                out[i] = records.roundtrip(rec)
                bar.update(failed=not rec["ok"])
        finally:
            bar.close()
        self.stages[stage] = {"runs": n_items, "stored": n_stored, "ran": len(todo), "missing": 0}
        return out

    def _run(self, fn, items, todo, shared):
        """(index, record text) as runs finish."""
        if not todo:
            return
        if cluster.inside_worker():  # a campaign inside a run (no nested cluster): in this process
            for i in todo:
                yield i, execute(fn, i, items[i], shared)
            return
        from distributed import as_completed

        client = cluster.client(self.scheduler, self.workers)
        extra = ()
        if not (isinstance(shared, str) and shared == _NO_SHARED):
            # a task, not scattered data: the scheduler can compute it again if its worker dies
            extra = (client.submit(_identity, shared, pure=False),)
        futures = {
            client.submit(execute, fn, i, items[i], *extra, pure=False, key=f"run-{i}-{_token()}"): i for i in todo
        }
        try:
            for fut in as_completed(futures):
                i = futures[fut]
                try:
                    text = fut.result()
                except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: recorded against the run
                    text = records.dumps(
                        {
                            "index": i,
                            "ok": False,
                            "error": f"{type(exc).__name__}: {exc}",
                            "message": str(exc),
                            "traceback": "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)),
                            "worker": None,
                            "elapsed_s": None,
                        }
                    )
                    if type(exc).__name__ == "CancelledError":
                        raise
                fut.release()
                yield i, text
        finally:
            pending = [f for f in futures if not f.done()]
            if pending:
                client.cancel(pending)
            if extra:
                client.cancel(list(extra))


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return socket.gethostname()


def _token() -> str:
    import uuid

    return uuid.uuid4().hex[:12]


def results(recs: list) -> list:
    """The results of the runs that finished (None for failed or missing)."""
    return [r["result"] if r is not None and r.get("ok") else None for r in recs]


def failures(recs: list) -> list:
    """[{run, seed, error}] of the failed runs."""
    return [
        {"run": r["index"], "seed": r.get("seed"), "error": r.get("error")}
        for r in recs
        if r is not None and not r.get("ok")
    ]


def all_failed(recs: list) -> None:
    """Raises ValueError with the first failure's message when no run finished
    (a campaign whose every run fails says why, as one run would)."""
    done = [r for r in recs if r is not None]
    if done and not any(r.get("ok") for r in done):
        raise ValueError(done[0].get("message") or done[0].get("error"))


def missing(recs: list) -> list:
    return [i for i, r in enumerate(recs) if r is None]


def new_campaign(campaign, workers, progress):
    """``campaign``, or one on a local cluster of ``workers`` keeping nothing."""
    return campaign if campaign is not None else Campaign(workers=workers, progress=progress)
