"""Errors a user can act on. The CLI prints them without a traceback."""


class StudyError(Exception):
    """Bad input: names the file, the key path and what is wrong (exit status 2)."""

    def __init__(self, message: str, *, file: str | None = None, path: str | None = None):
        self.file = file
        self.path = path
        self.fault = message
        where = ": ".join(p for p in (file, path) if p)
        super().__init__(f"{where}: {message}" if where else message)

    def in_file(self, file) -> "StudyError":
        """This error, naming `file` if it names none yet (mesh-stage faults know only the key path)."""
        return self if self.file is not None else StudyError(self.fault, file=str(file), path=self.path)


class SolveError(Exception):
    """A forward solve that cannot be carried out for a data set (e.g. solvability)."""

    def __init__(self, message: str, status: int):
        self.status = status
        super().__init__(message)
