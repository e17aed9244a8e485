"""Progress of long commands (training, evaluation, the benchmark, time-to-beat): a
tqdm bar on a terminal, one flushed line per stage when the output is not a terminal
(a log file, a pipe, CI) or the terminal reports zero columns.

    from coopnav_env.progress import Progress
    with Progress(total=200, unit="episode", desc="evaluating") as bar:
        bar.stage("fim_a")        # a new stage: the bar's description, or one line
        bar.update(1.5)           # fractions are fine; the bar never passes its total

The estimate is tqdm's, from the work completed so far. In line mode a stage line says
what is done, the elapsed time and the estimate left; a line is also printed when
``every_s`` seconds pass without one, so a log shows the run is alive.
"""

from __future__ import annotations

import os
import sys
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    import threading

__all__ = ["Progress", "announce_after", "format_seconds", "is_interactive", "say", "stage"]


def is_interactive(stream: TextIO | None = None) -> bool:
    """Whether ``stream`` (default stderr) is a terminal that reports a width: a bar can
    be drawn there. ``COOPNAV_PROGRESS=lines`` forces lines, ``=bar`` a bar."""
    forced = os.environ.get("COOPNAV_PROGRESS", "").strip().lower()
    if forced in ("bar", "lines", "off"):
        return forced == "bar"
    stream = sys.stderr if stream is None else stream
    try:
        if not stream.isatty():
            return False
        return os.get_terminal_size(stream.fileno()).columns > 0
    except (AttributeError, OSError, ValueError):
        return False


def format_seconds(seconds: float) -> str:
    """``75`` -> ``1 min 15 s``; ``3700`` -> ``1 h 01 min``."""
    seconds = max(float(seconds), 0.0)
    if seconds < 60:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"


def say(text: str, stream: TextIO | None = None) -> None:
    """One flushed line (a stage of a command), on stderr by default."""
    stream = sys.stderr if stream is None else stream
    print(text, file=stream, flush=True)


_PENDING: list[announce_after] = []  # the active announce_after (a stage line ends it)


def stage(text: str, stream: TextIO | None = None) -> None:
    """A stage of a command (``say``), unless ``COOPNAV_PROGRESS=off``; it ends an
    ``announce_after`` still waiting (or erases its transient status)."""
    while _PENDING:
        _PENDING.pop().finish()
    if os.environ.get("COOPNAV_PROGRESS", "").strip().lower() != "off":
        say(text, stream)


class Progress:
    """A bar (terminal) or stage lines (elsewhere) over ``total`` units of work.

    ``mode``: "bar", "lines", "off" or None (a bar if ``is_interactive(stream)``, else
    lines; ``COOPNAV_PROGRESS`` overrides). ``every_s``: in line mode, the longest
    silence between lines. Updates past ``total`` are clipped: the bar ends at its total."""

    def __init__(
        self,
        total: float,
        unit: str = "it",
        desc: str = "",
        stream: TextIO | None = None,
        mode: str | None = None,
        every_s: float = 30.0,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        forced = os.environ.get("COOPNAV_PROGRESS", "").strip().lower()
        if forced == "off":
            mode = "off"
        if mode is None:
            mode = forced if forced in ("bar", "lines", "off") else ("bar" if is_interactive(self.stream) else "lines")
        self.mode, self.total, self.unit, self.desc = mode, float(total), unit, desc
        self.n, self.every_s = 0.0, every_s
        self.t0 = self._last_line = time.perf_counter()
        self._bar, self._closed = None, False
        if mode == "bar":
            from tqdm import tqdm

            whole = float(total).is_integer()
            fmt = "{l_bar}{bar}| {n:.0f}/{total_fmt} {unit} [{elapsed}<{remaining}]" if whole else None
            self._bar = tqdm(
                total=int(total) if whole else total,
                unit=unit,
                desc=desc,
                file=self.stream,
                dynamic_ncols=True,
                bar_format=fmt,
                smoothing=0.1,
            )

    # --------------------------------------------------------------------------------
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close(stopped=exc[0] is not None)

    def update(self, n: float = 1.0) -> None:
        """``n`` more units done (clipped at the total)."""
        n = min(float(n), self.total - self.n)
        if n <= 0:
            return
        if self.total - (self.n + n) < 1e-9 * max(self.total, 1.0):  # fractions that add up to the total: exactly it
            n = self.total - self.n
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
        elif self.mode == "lines" and not self._closed and time.perf_counter() - self._last_line >= self.every_s:
            self._line(self.desc)

    def set(self, n: float) -> None:
        """Set the units done to ``n`` (clipped at the total; never backwards)."""
        self.update(n - self.n)

    def stage(self, text: str) -> None:
        """A new stage: the bar's description, or a line with the work done and the estimate
        (nothing once closed)."""
        if self._closed:
            return
        self.desc = text
        if self._bar is not None:
            self._bar.set_description(text[:48], refresh=True)
        elif self.mode == "lines":
            self._line(text)

    def write(self, text: str, stream: TextIO | None = None) -> None:
        """A message (on ``stream``, default the bar's) that does not break the bar; printed
        even with ``mode="off"`` when ``stream`` is given (it is output, not progress)."""
        if self._bar is not None:
            self._bar.write(text, file=stream or self.stream)
        elif stream is not None or self.mode != "off":
            say(text, stream or self.stream)

    def eta_s(self) -> float | None:
        """Seconds left, from the rate of the work done so far (None before 2 % of it: the
        first steps include compiling)."""
        elapsed = time.perf_counter() - self.t0
        if self.n < 0.02 * self.total or elapsed <= 0:
            return None
        return (self.total - self.n) * elapsed / self.n

    def _line(self, text: str):
        elapsed = time.perf_counter() - self.t0
        eta = self.eta_s()
        left = "" if eta is None else f", about {format_seconds(eta)} left"
        n = f"{self.n:.0f}" if self.total.is_integer() else f"{self.n:.1f}"
        say(f"[{n}/{self.total:.0f} {self.unit}, {format_seconds(elapsed)}{left}] {text}", self.stream)
        self._last_line = time.perf_counter()

    def close(self, stopped: bool = False) -> None:
        """End the bar; in line mode a last line: "stopped" when ``stopped`` (the ``with``
        block raised, e.g. Ctrl-C) before the total was reached, else "done"."""
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        elif self.mode == "lines":
            elapsed = time.perf_counter() - self.t0
            n = f"{self.n:.0f}"
            word = "stopped" if stopped and self.n < self.total else "done"
            say(f"[{n}/{self.total:.0f} {self.unit}, {format_seconds(elapsed)}] {word}", self.stream)


class announce_after:
    """A context manager that says ``text`` if its block runs longer than ``seconds``:
    the checks before a command's first stage stay silent when they are quick (a bad
    input is still one line) and say what is happening when they are not (compiling the
    simulator on first use). On a terminal the line is a transient status, erased when
    the block ends; elsewhere one flushed line. Nothing with ``COOPNAV_PROGRESS=off``."""

    def __init__(self, text: str, seconds: float = 2.0, stream: TextIO | None = None) -> None:
        self.text, self.seconds = text, seconds
        self.stream = sys.stderr if stream is None else stream
        self._timer: threading.Timer | None = None
        self._shown, self._transient = False, False

    def _show(self):
        self._shown = True
        if self._transient:
            self.stream.write(self.text + " ...")
            self.stream.flush()
        else:
            say(self.text, self.stream)

    def __enter__(self):
        import threading

        mode = os.environ.get("COOPNAV_PROGRESS", "").strip().lower()
        if mode != "off":
            self._transient = mode != "lines" and is_interactive(self.stream)
            self._timer = threading.Timer(self.seconds, self._show)
            self._timer.daemon = True
            self._timer.start()
            _PENDING.append(self)
        return self

    def __exit__(self, *exc):
        if self in _PENDING:
            _PENDING.remove(self)
        self.finish()

    def finish(self) -> None:
        """Stop waiting; erase the transient status if it was shown."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer.join()
        if self._shown and self._transient:  # erase the status line
            self.stream.write("\r\033[K")
            self.stream.flush()
        self._timer, self._shown = None, False
