"""The results store of a campaign: one JSON file per run, written the
moment the run finishes.

Layout (``root`` is ``--store``, default ``$PROXOPS_CACHE/campaigns`` or
``~/.cache/proxops/campaigns``)::

    root/<name>-<sha12>/campaign.json          the campaign's arguments
    root/<name>-<sha12>/<stage>/run-000017.json one record per run and stage

``sha12`` is the start of the SHA-256 of the arguments, so a campaign
re-run with the same arguments finds its runs. Each record holds the run's
index, the SHA-256 of its input (a stored run is reused only while that
input is unchanged), its seed, whether it finished, its result or its error
and traceback, the worker and the wall time. A record is written to a
temporary file and renamed into place: a campaign stopped at any moment
leaves every record whole or absent.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

from bench.runner import records

FORMAT = 1


def default_root() -> Path:
    return Path(os.environ.get("PROXOPS_CACHE", Path.home() / ".cache" / "proxops")) / "campaigns"


class RunStore:
    """Per-run records of one campaign on disk."""

    def __init__(self, name: str, arguments: dict, root=None):
        self.name = name
        self.arguments = {"format": FORMAT, "campaign": name, **arguments}
        self.sha256 = records.sha256(self.arguments)
        self.path = Path(root if root is not None else default_root()) / f"{name}-{self.sha256[:12]}"

    def exists(self) -> bool:
        return (self.path / "campaign.json").exists()

    def open(self) -> "RunStore":
        """Creates the folder and its campaign.json; drops temporary files a
        stopped campaign left."""
        self.path.mkdir(parents=True, exist_ok=True)
        meta = self.path / "campaign.json"
        if not meta.exists():
            _write_atomically(meta, records.dumps(self.arguments, indent=1) + "\n")
        for tmp in self.path.glob("*/.*.tmp*"):
            tmp.unlink(missing_ok=True)
        return self

    def _file(self, stage: str, index: int) -> Path:
        return self.path / stage / f"run-{index:06d}.json"

    def load(self, stage: str) -> dict:
        """{run index: record} of the runs stored for ``stage``; an unreadable
        or damaged file (``damaged``) counts as not stored, and its name is
        kept in ``self.damaged``."""
        out = {}
        self.damaged = []
        folder = self.path / stage
        if not folder.is_dir():
            return out
        for f in sorted(folder.glob("run-*.json")):
            try:
                rec = records.loads(f.read_text())
            except (ValueError, RecursionError, OSError):
                rec = None
            why = damaged(rec, f.name)
            if why:
                self.damaged.append(f"{f.name}: {why}")
                continue
            out[rec["index"]] = rec
        return out

    def write(self, stage: str, record: dict) -> None:
        f = self._file(stage, int(record["index"]))
        f.parent.mkdir(parents=True, exist_ok=True)
        _write_atomically(f, records.dumps(record) + "\n")


def damaged(rec, name: str | None = None) -> str | None:
    """Why the stored record ``rec`` (from the file ``name``) cannot stand
    for its run, None when it can: a dict whose index is the file's, whose
    ok is true or false, with its input's hash and, when it finished, its
    result, matching the result's hash (a record written before results
    were hashed: a result that is not null or empty). A hand-edited or
    truncated record is then run again, or counted missing, never read as
    a finished run without a result."""
    if not isinstance(rec, dict):
        return "not a run record"
    index = rec.get("index")
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        return f"index {index!r} is not a run number"
    if name is not None and name != f"run-{index:06d}.json":
        return f"index {index} is not the file's"
    if not isinstance(rec.get("ok"), bool):
        return f"ok {rec.get('ok')!r} is not true or false"
    if not isinstance(rec.get("input_sha256"), str):
        return "no input hash"
    if not rec["ok"]:
        return None
    if "result" not in rec:
        return "finished without a result"
    if "result_sha256" in rec:
        try:
            same = rec["result_sha256"] == records.sha256(rec["result"])
        except (TypeError, ValueError):
            same = False
        return None if same else "its result is not the one it was written with (hash differs)"
    result = rec["result"]
    if result is None or (isinstance(result, (dict, list)) and not result):
        return f"finished with an empty result ({records.dumps(result)})"
    return None


class MemoryStore:
    """The same interface, in memory (library calls without a store)."""

    def __init__(self, name: str = "campaign", arguments: dict | None = None):
        self.name, self.arguments, self.path = name, arguments or {}, None
        self._stages: dict = {}
        self.damaged: list = []

    def exists(self) -> bool:
        return bool(self._stages)

    def open(self) -> "MemoryStore":
        return self

    def load(self, stage: str) -> dict:
        return dict(self._stages.get(stage, {}))

    def write(self, stage: str, record: dict) -> None:
        self._stages.setdefault(stage, {})[int(record["index"])] = records.roundtrip(record)


def _write_atomically(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}.{socket.gethostname()}")
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
