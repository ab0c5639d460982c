"""OneOcean: a data-grounded simulation suite and benchmark for marine robotics."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("oneocean")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]

# Gymnasium ids OneOcean/<TASK>-T<tier>-v0 (oneocean.registration): string entry points, so
# this imports Gymnasium only, not the envs, numba or any task. Without Gymnasium the package
# still imports.
try:
    import gymnasium as _gymnasium  # noqa: F401
except ImportError:  # pragma: no cover - gymnasium is a dependency
    pass
else:
    from .registration import register_envs as _register_envs

    _register_envs()
    del _register_envs
