"""Shared pytest fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real-data fixtures folder ``../shared/data`` beside the checkout (skip if absent)."""
    path = Path(__file__).parents[1].parent / "shared" / "data"
    if not path.is_dir():
        pytest.skip(f"real-data fixtures not found at {path}")
    return path


@pytest.fixture
def base_config() -> dict:
    """A fresh copy of ``config/config.yaml`` (every key present), for tests to modify."""
    import yaml

    path = Path(__file__).parents[1] / "config" / "config.yaml"
    with open(path) as fh:
        return yaml.safe_load(fh)


@pytest.fixture(autouse=True)
def _forget_registered_methods():
    """A config with ``llm.models`` registers ``llm_<name>`` methods in the process
    (:func:`oneocean.config.register_llm_methods`), reading a packaged method's cells
    registers it (``ppo``: :data:`oneocean.registry.PACKAGED_METHODS`) and the tables
    register a user's method from its ``oneocean evaluate`` cells; forget every method a
    test registered after it, so tests that list the registry's methods do not depend on
    which test ran before in the same process."""
    from oneocean import registry

    before = set(registry.method_names())
    yield
    for name in set(registry.method_names()) - before:
        registry.unregister_method(name)


@pytest.fixture(scope="session")
def default_grid():
    """The embedded default region's grid export (what ``run_cell(None, ...)``, the step API
    and ``evaluate`` use without a grid)."""
    from oneocean.product.defaults import resolve_grid

    return resolve_grid(None)


@pytest.fixture(scope="session")
def coast():
    """The analytic coast most engine and task tests run on (:func:`oneocean.testing.make_test_grid`:
    5 hourly time steps, 3 depth levels, 30 x 40 cells; land along the west edge, a seafloor
    sloping down to the east, currents and tides), loaded once per test process."""
    from oneocean.engine import load_grid
    from oneocean.testing import make_test_grid

    return load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
