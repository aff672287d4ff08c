"""Progress bars for long stages: tqdm on a terminal, a few plain lines in a log, none with --quiet.

A tqdm bar redraws in place with carriage returns; written to a file (a batch job's log,
``rfsdf demo 2> log``) every redraw stays, and a demo log became mostly bar fragments. So
when the stream is not a terminal a bar waits ``LOG_INTERVAL_S`` before it shows at all
(short stages leave no trace), then writes one plain line at most every ``LOG_INTERVAL_S``.
``rfsdf --quiet`` (``set_quiet``) turns every bar off.
"""

from __future__ import annotations

import sys
from typing import Iterable, TextIO

from tqdm.auto import tqdm

__all__ = ["LOG_INTERVAL_S", "progress_bar", "set_quiet"]

LOG_INTERVAL_S = 30.0  # seconds between progress lines in a log

_quiet = False


def set_quiet(quiet: bool) -> None:
    """Silence (True) or allow (False) every progress bar of this process."""
    global _quiet
    _quiet = quiet


class _Lines:
    """A stream for tqdm that turns each redraw into one plain line (for logs, not terminals)."""

    def __init__(self, stream: TextIO):
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace("\r", "").strip()  # tqdm clears a bar with '\r' and blanks
        if text:
            self.stream.write(text + "\n")

    def flush(self) -> None:
        self.stream.flush()


def progress_bar(iterable: Iterable | None = None, *, desc: str, enabled: bool = True, leave: bool = False,
                 total: int | None = None, initial: int = 0, stream: TextIO | None = None) -> tqdm:
    """A tqdm bar over ``iterable`` (or updated by hand up to ``total``), shown only when
    ``enabled`` and not quiet; plain throttled lines when ``stream`` (default stderr) is no TTY."""
    stream = sys.stderr if stream is None else stream
    options = dict(desc=desc, total=total, initial=initial, leave=leave, disable=_quiet or not enabled)
    if not stream.isatty():
        options.update(file=_Lines(stream), mininterval=LOG_INTERVAL_S, maxinterval=LOG_INTERVAL_S, delay=LOG_INTERVAL_S, ncols=80)
    else:
        options.update(file=stream)
    return tqdm(iterable, **options)
