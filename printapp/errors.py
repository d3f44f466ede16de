"""The errors printapp reports to its users instead of tracebacks."""


class PrintappError(Exception):
    """A problem the user can fix; the CLI prints the message and exits with ``exit_code``."""

    exit_code = 2


class DesignError(PrintappError):
    """The design file (or another input) is missing, malformed or out of range."""
