"""The one exception type for bad input.

Every check of user input raises :class:`BouncelabError` with the file it concerns and
a short statement of the problem; the command line prints it as a single
``error: <file>: <problem>`` line and exits non-zero, with no traceback.
"""

from __future__ import annotations

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
