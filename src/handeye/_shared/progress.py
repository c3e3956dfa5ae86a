"""Progress of the long jobs (image detection, the simulation study, large calibrations): tqdm's bar
with rate and time left on a terminal; elsewhere (a log, a pipe) one line when the job ends."""

from __future__ import annotations

import sys

from .lazy import lazy_module

# loaded when a bar is drawn (a terminal): a command in a pipe, or with --no-progress, never needs it (~10 ms)
_tqdm = lazy_module("tqdm")


class Progress:
    """A progress bar on stderr over ``total`` steps named ``label``: ``update(n)``, then ``close()``."""

    def __init__(self, total: int, label: str, enabled: bool = True) -> None:
        self.total, self.label, self.done = total, label, 0
        self.enabled = enabled and total > 0
        self.tty = sys.stderr.isatty()
        self._bar = (_tqdm.tqdm(total=total, desc=label, file=sys.stderr, unit="step", dynamic_ncols=True, leave=True)
                     if self.enabled and self.tty else None)

    def update(self, n: int = 1) -> None:
        self.done += n
        if self._bar is not None:
            self._bar.update(n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        elif self.enabled:  # not a terminal: no redrawn bar, one line for the log
            sys.stderr.write(f"{self.label}: {self.done}/{self.total}\n")
            sys.stderr.flush()
