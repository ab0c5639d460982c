"""One exception type for bad input: a one-line message naming the file or key and the problem."""

from __future__ import annotations


class OneOceanError(ValueError):
    """Bad input or configuration. ``str(err)`` is a single line meant for the user.

    Parameters
    ----------
    message : str
        What went wrong, naming the file or key; runs of whitespace (newlines included) are
        collapsed to single spaces.
    """

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


class DataError(OneOceanError):
    """A data file is missing, malformed, or does not cover what was asked."""


class ConfigError(OneOceanError):
    """A configuration key is unknown, ill-typed, or out of range."""


class DiskFullError(OneOceanError):
    """The disk (or the user's quota) filled up while an artifact was being written.

    The partial file was removed. The three arguments are kept as attributes of the same names.

    Parameters
    ----------
    path : path-like
        The artifact being written.
    free : int, optional
        Free bytes on its filesystem when the write failed (None if unknown).
    what : str, default "the disk is full"
        The cause, as it appears in the message.
    """

    def __init__(self, path, free: int | None = None, what: str = "the disk is full"):
        self.path, self.free, self.what = path, free, what
        room = "" if free is None else f" ({free} bytes = {free / 1e6:.1f} MB free)"
        super().__init__(f"{path}: cannot write: {what}{room}; no partial file was left")


class CredentialsError(OneOceanError):
    """Credentials for a remote data service are missing."""


class NotApplicable(ConfigError):
    """A region cannot host a task cell.

    E.g. no water deep enough, no site in the tier's current regime. Not a crash: the workflow
    writes the cell as not applicable with this one-line reason and the tables show it so."""
