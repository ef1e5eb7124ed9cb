"""Progress on standard error, drawn by tqdm: done of the total (and how many
were already stored or failed), rate, time elapsed and time left.

Shown only when its stream is a terminal, redrawn in place. PROXOPS_PROGRESS=1
asks for it where the stream is not a terminal too (a log file): a whole line
at most every 30 s, no carriage returns. PROXOPS_PROGRESS=0 turns it off
everywhere."""

from __future__ import annotations

import os
import sys

from tqdm import tqdm

ENV = "PROXOPS_PROGRESS"
LOG_INTERVAL_S = 30.0


class _Lines:
    """The stream tqdm draws into when it is not a terminal: every redraw as
    one whole line, without the carriage return and padding tqdm writes."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace("\r", "").strip()
        if text:
            self.stream.write(text + "\n")

    def flush(self) -> None:
        self.stream.flush()


class ProgressBar:
    """``update()`` after each run (``failed=True`` for a failed one); called
    as ``bar()`` or ``bar(n)`` it serves as a progress callback; ``total`` may
    grow while it runs; ``close()`` at the end."""

    def __init__(self, label: str, total: int, stored: int = 0, enabled: bool = True, stream=None, unit: str = "run"):
        self.label, self.stored = label, int(stored)
        self.done, self.failed = 0, 0
        stream = stream or sys.stderr
        tty = hasattr(stream, "isatty") and stream.isatty()
        asked = os.environ.get(ENV, "").strip()
        self.enabled = enabled and total > 0 and asked != "0" and (tty or asked == "1")
        self._bar = tqdm(
            total=int(total),
            initial=self.stored,
            desc=f"  {label}",
            unit=unit,
            file=stream if tty else _Lines(stream),
            mininterval=0.2 if tty else LOG_INTERVAL_S,
            dynamic_ncols=tty,
            disable=not self.enabled,
            postfix=self._note(),
        )

    @property
    def total(self) -> int:
        return int(self._bar.total)

    @total.setter
    def total(self, value: int) -> None:
        self._bar.total = int(value)
        self._bar.refresh()

    def _note(self) -> str:
        """What the bar says after its rate: runs already stored, runs failed."""
        counts = ((self.stored, "stored"), (self.failed, "failed"))
        return ", ".join(f"{count} {what}" for count, what in counts if count)

    def update(self, failed: bool = False, n: int = 1) -> None:
        self.done += n
        self.failed += int(failed)
        if failed:
            self._bar.set_postfix_str(self._note(), refresh=False)
        self._bar.update(n)

    def __call__(self, n: int = 1) -> None:
        self.update(n=n)

    def close(self) -> None:
        self._bar.close()
