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
def _forget_llm_methods():
    """A config with ``llm.models`` registers ``llm_<name>`` methods in the process
    (:func:`oneocean.config.register_llm_methods`), and reading a packaged method's cells
    registers it (``ppo``: :data:`oneocean.registry.PACKAGED_METHODS`); forget them after
    each test, so tests that list the registry's methods do not depend on which test ran
    before."""
    from oneocean import registry

    before = set(registry.method_names())
    yield
    for name in set(registry.method_names()) - before:
        if name.startswith("llm_") or name in registry.PACKAGED_METHODS:
            registry.unregister_method(name)
