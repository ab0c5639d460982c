"""OneOcean: a data-grounded simulation suite and benchmark for marine robotics."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("oneocean")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
