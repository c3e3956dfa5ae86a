"""A one-line progress bar on stderr, for the long jobs (image detection, the simulation study)."""

from __future__ import annotations

import sys


class Progress:
    """A one-line progress bar on stderr (redrawn in place on a terminal, else one final line)."""

    def __init__(self, total: int, label: str, enabled: bool = True) -> None:
        self.total, self.label, self.done = total, label, 0
        self.enabled = enabled and total > 0
        self.tty = sys.stderr.isatty()

    def update(self, n: int = 1) -> None:
        self.done += n
        if self.enabled and self.tty:
            width = 30
            filled = int(width * self.done / self.total)
            sys.stderr.write(f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total}")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write(("\n" if self.tty else f"{self.label}: {self.done}/{self.total}\n"))
            sys.stderr.flush()
