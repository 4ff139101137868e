"""Errors a user can act on. The CLI prints them without a traceback."""


class StudyError(Exception):
    """Bad input: names the file, the key path and what is wrong (exit status 2)."""

    def __init__(self, message: str, *, file: str | None = None, path: str | None = None):
        self.file = file
        self.path = path
        self.fault = message
        where = ": ".join(p for p in (file, path) if p)
        super().__init__(f"{where}: {message}" if where else message)


class SolveError(Exception):
    """A forward solve that cannot be carried out for a data set (e.g. solvability)."""

    def __init__(self, message: str, status: int):
        self.status = status
        super().__init__(message)
