"""A progress bar on standard error: runs done of the total, rate, time
elapsed and time left."""

from __future__ import annotations

import sys
import time


def _clock(s: float) -> str:
    s = int(round(s))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


class ProgressBar:
    WIDTH = 24

    def __init__(self, label: str, total: int, stored: int = 0, enabled: bool = True, stream=None):
        self.label, self.total, self.stored = label, int(total), int(stored)
        self.done, self.failed = 0, 0
        self.enabled = enabled and total > 0
        self.stream = stream or sys.stderr
        self.t0 = time.monotonic()
        self._last = 0.0
        self._shown = None
        self._tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.show(force=True)

    def update(self, failed: bool = False) -> None:
        self.done += 1
        self.failed += int(failed)
        self.show(force=self.stored + self.done == self.total)

    def line(self) -> str:
        n = self.stored + self.done
        el = time.monotonic() - self.t0
        rate = self.done / el if el > 0 and self.done else 0.0
        left = (self.total - n) / rate if rate > 0 else None
        fill = int(self.WIDTH * n / self.total) if self.total else self.WIDTH
        return (
            f"  {self.label}: [{'#' * fill}{'.' * (self.WIDTH - fill)}] {n}/{self.total} runs"
            + (f" ({self.stored} stored)" if self.stored else "")
            + (f", {self.failed} failed" if self.failed else "")
            + f", {rate * 60:.1f} runs/min, {_clock(el)} elapsed, "
            + ("time left ?" if left is None else f"~{_clock(left)} left")
        )

    def show(self, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        # On a terminal the bar is redrawn in place; in a file, one line every 30 s.
        if not force and now - self._last < (0.2 if self._tty else 30.0):
            return
        self._last = now
        self._shown = (self.done, self.failed)
        self.stream.write(("\r" if self._tty else "") + self.line() + ("" if self._tty else "\n"))
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            if self._shown != (self.done, self.failed):
                self.show(force=True)
            if self._tty:
                self.stream.write("\n")
            self.stream.flush()
