"""The one exception type for bad input, and the collection of warnings about it.

Every check of user input raises :class:`BouncelabError` with the file it concerns and
a short statement of the problem; the command line prints it as a single
``error: <file>: <problem>`` line and exits non-zero, with no traceback. Input that is
usable but suspect is warned about through :mod:`logging` (one line naming the file);
:func:`collected_warnings` keeps those lines for an output that should carry them.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


class BouncelabError(Exception):
    """Bad input: names the file and the problem in one line.

    Parameters
    ----------
    path : str or Path or None
        The file (or folder) the problem is in; ``None`` for problems with no file
        (a bad command-line value, say).
    problem : str
        What is wrong, one sentence, no trailing period needed.
    """

    def __init__(self, path: str | Path | None, problem: str):
        self.path = Path(path) if path is not None else None
        self.problem = " ".join(str(problem).split())  # always one line
        super().__init__(str(self))

    def __reduce__(self):
        # rebuilt from both arguments: an error raised in a worker process (the
        # diagnosis's evaluation pool) must reach the caller as itself, not break the pool
        return type(self), (self.path, self.problem)

    def __str__(self) -> str:
        return f"{self.path}: {self.problem}" if self.path is not None else self.problem


class _Collector(logging.Handler):
    """Appends each record's message to ``messages`` (see :func:`collected_warnings`)."""

    def __init__(self, messages: list[str]):
        super().__init__(level=logging.WARNING)
        self.messages = messages

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())
        # logging prints to stderr by itself only where no handler is found: collectors
        # must not silence that; with nested blocks, the first collector prints, once
        if logging.lastResort is not None and _first_collector(record.name) is self:
            if record.levelno >= logging.lastResort.level:
                logging.lastResort.handle(record)


@contextmanager
def collected_warnings() -> Iterator[list[str]]:
    """Collect the warnings bouncelab's modules log inside the ``with`` block.

    Yields the list the messages (``str``, in the order logged) are appended to. The
    records still reach every other handler (the command line's stderr, a workflow
    rule's log), and are printed once where no other handler takes them; blocks may
    nest (the diagnosis command around the extraction). Why: a warning about the input
    (a dirty contact, a drive channel at another frequency, a time column printed with
    too few digits) matters to whoever reads the outputs, and a log is read less often
    than the report that shows them.
    """
    messages: list[str] = []
    handler = _Collector(messages)
    logger = logging.getLogger("bouncelab")
    logger.addHandler(handler)
    try:
        yield messages
    finally:
        logger.removeHandler(handler)


def _first_collector(name: str) -> _Collector | None:
    """The first :class:`_Collector` a record of logger ``name`` reaches, or None where
    it reaches another handler too (that one shows it)."""
    logger: logging.Logger | None = logging.getLogger(name)
    first = None
    while logger is not None:
        for h in logger.handlers:
            if not isinstance(h, _Collector):
                return None
            first = first or h
        logger = logger.parent if logger.propagate else None
    return first
