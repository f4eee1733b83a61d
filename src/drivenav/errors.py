"""Errors for bad user input: each names the file, the field, and what was expected."""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad input from a user-supplied file or option.

    The command line prints ``str(error)`` on one line and exits with status 2, without a traceback.
    """

    def __init__(self, source: str | Path, field: str, expected: str, got: object = None) -> None:
        self.source = str(source)
        self.field = field
        self.expected = expected
        self.got = got
        message = f"{self.source}: field '{field}': expected {expected}"
        if got is not None:
            message += f", got {_short(got)}"
        super().__init__(message)

    def __reduce__(self) -> tuple[type[InputError], tuple[str, str, str, object]]:
        """Rebuild as a plain :class:`InputError` (subclasses differ in their constructors) across processes."""
        return InputError, (self.source, self.field, self.expected, self.got)


def one_line(error: BaseException, limit: int = 200) -> str:
    """``Type: first line of the message`` (at most ``limit`` characters of it): an exception for a log line or a
    reply."""
    lines = str(error).splitlines()
    return f"{type(error).__name__}: {lines[0][:limit]}" if lines else type(error).__name__


def _short(value: object, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class WorkerDiedError(Exception):
    """A worker process died mid-run (killed, out of memory): the run stops; a rerun resumes it.

    The command line prints the message on one line and exits with status 1.
    """

    def __init__(self, episodes: list[str], exit_codes: list[str]) -> None:
        self.episodes = episodes
        codes = f" (exit code {', '.join(exit_codes)})" if exit_codes else ""
        super().__init__(
            f"the worker running episode {', '.join(episodes) or '(unknown)'} died{codes}; "
            "finished episodes are saved, rerun the same command to resume"
        )


class RunStoppedError(Exception):
    """A run that cannot go on: its world or agent cannot start, or its first episodes all failed alike.

    The command line prints the message on one line and exits with status 1; finished episodes stay saved.
    """
