"""The workflow's compile_kernel stage: one process compiles a task's kernel into numba's
cache, and every cell of the task in a later process (every tier, method and forcing) loads it
instead of compiling again."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from oneocean.io import write_npz_atomic
from oneocean.testing import make_test_grid


@pytest.mark.slow
def test_compile_kernel_covers_every_cell_of_the_task(tmp_path):
    grid = tmp_path / "grid.npz"
    write_npz_atomic(grid, make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}   # cold cache
    compile_code = textwrap.dedent(f"""
        from oneocean.kernels import g2g
        from oneocean.tasks import compile_kernel
        compile_kernel({str(grid)!r}, {str(tmp_path / "G2G.json")!r}, "G2G", [1, 2, 3], "6dof")
        print(sum(g2g._kernel.stats.cache_misses.values()))
    """)
    out = subprocess.run([sys.executable, "-c", compile_code], capture_output=True, text=True,
                         env=env, check=True).stdout.split()
    assert int(out[-1]) >= 1                      # it compiled (the cache was empty)
    rec = json.loads((tmp_path / "G2G.json").read_text())
    assert rec["task"] == "G2G" and rec["tiers"] == [1, 2, 3] and rec["not_applicable"] == {}
    assert "time" not in json.dumps(rec)          # no timings: the record's bytes are stable

    cells_code = textwrap.dedent(f"""
        from oneocean.engine import load_grid
        from oneocean.kernels import g2g
        from oneocean.tasks import run_cell
        g = load_grid({str(grid)!r})
        for tier in (1, 2, 3):
            for method in ("heuristic", "oracle"):
                run_cell(g, "G2G", tier, method, episodes=2, seed=1000)
            run_cell(g, "G2G", tier, "heuristic", episodes=2, seed=1000, currents=False)
            run_cell(g, "G2G", tier, "heuristic", episodes=2, seed=1000, current_gain=2.0,
                     tide={{"amplitude_ms": 0.3, "period_s": 44712.0}})
        print(sum(g2g._kernel.stats.cache_hits.values()),
              sum(g2g._kernel.stats.cache_misses.values()))
    """)
    hits, misses = map(int, subprocess.run([sys.executable, "-c", cells_code],
                                           capture_output=True, text=True, env=env,
                                           check=True).stdout.split()[-2:])
    assert hits >= 1 and misses == 0, (hits, misses)
