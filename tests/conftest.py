"""Shared pytest fixtures, and the session's one compile of every task's loop."""

from __future__ import annotations

import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

_WARM = """
import sys, tempfile
from oneocean.product.defaults import default_grid_path
from oneocean.tasks import compile_kernel
with tempfile.TemporaryDirectory() as d:
    compile_kernel(default_grid_path(), d + "/k.json", sys.argv[1], [1, 2, 3], "6dof")
"""


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    """Compile every registered task's episode loop into numba's on-disk cache once, two
    tasks at a time, before the tests start (and before pytest-xdist starts its workers),
    so that no two test processes compile the same kernel: each test process loads it.

    Only for a run of the whole suite (no file or test named on the command line), not in an
    xdist worker (its controller did it) and not with ``ONEOCEAN_TEST_WARM=0``. A task whose
    compile fails is left to its tests, which then fail with the error.
    """
    cfg = session.config
    if hasattr(cfg, "workerinput") or os.environ.get("ONEOCEAN_TEST_WARM", "1") == "0":
        return
    if cfg.option.collectonly or any(a not in ("tests", "tests/") for a in cfg.args):
        return
    from oneocean.product.defaults import resolve_grid
    from oneocean.registry import task_ids

    resolve_grid(None)       # the default region's grid, built once, before the processes

    def warm(task):
        subprocess.run([sys.executable, "-c", _WARM, task], stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, check=False)

    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(warm, task_ids()))


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
