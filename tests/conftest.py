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
