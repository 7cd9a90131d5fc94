"""A one-line text progress bar on stderr, shown only when stderr is a terminal."""

from __future__ import annotations

import sys
import threading
from typing import TextIO


class Progress:
    """Counts finished items and redraws ``[#####.....] 5/10 tiles``.

    ``enabled=None`` shows the bar only when ``stream`` (stderr by default)
    is a terminal, so logs and pipes stay clean.
    """

    def __init__(
        self,
        total: int,
        label: str,
        enabled: bool | None = None,
        stream: TextIO | None = None,
        width: int = 30,
    ) -> None:
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.total = max(total, 1)
        self.label = label
        self.width = width
        self.done = 0
        self._lock = threading.Lock()
        self._draw()

    def _draw(self) -> None:
        if not self.enabled:
            return
        filled = self.width * self.done // self.total
        bar = "#" * filled + "." * (self.width - filled)
        self.stream.write(f"\r[{bar}] {self.done}/{self.total} {self.label}")
        self.stream.flush()

    def advance(self, count: int = 1) -> None:
        with self._lock:
            self.done += count
            self._draw()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()
