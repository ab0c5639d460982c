"""Benchmarks of the product stage (issue 2 targets; prints figures, asserts nothing).

(a) Wall time of ``snakemake --cores 2 exports`` on the default config, in a scratch copy of the
    repository (goal < 60 s including Snakemake start-up).
(b) Peak RSS of ``build_product`` merging a synthetic currents source of >= 4 GB on disk
    (goal < 1.5 GB): the source is generated lazily, one time step at a time, in a child
    process; the merge runs in another child whose peak RSS comes from ``os.wait4``.

Usage::

    python benchmarks/product.py            # both parts, full 4 GB source
    python benchmarks/product.py --quick    # smoke run: ~0.1 GB source
    python benchmarks/product.py --skip-workflow --workdir /big/tmp --keep
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
GOAL_WORKFLOW_S = 60.0
GOAL_RSS_GB = 1.5
GB = 1024 ** 3


def bench_workflow(workdir: Path) -> None:
    """(a) ``snakemake --cores 2 exports`` in a scratch copy of the repository."""
    if not (REPO / "Snakefile").is_file() or not (REPO / "workflow" / "Snakefile").is_file():
        print("(a) workflow: SKIPPED (no Snakefile in the repository yet)")
        return
    if shutil.which("snakemake") is None:
        print("(a) workflow: SKIPPED (snakemake not on PATH)")
        return
    copy = workdir / "repo"
    shutil.copytree(REPO, copy, ignore=shutil.ignore_patterns(
        ".git", "results", ".snakemake", "logs", "__pycache__", "*.egg-info", ".pytest_cache"))
    cmd = ["snakemake", "--cores", "2", "exports", "--directory", str(copy)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=copy, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        print(f"(a) workflow: FAILED after {wall:.1f} s (exit {proc.returncode}); last lines:")
        print("\n".join(proc.stderr.strip().splitlines()[-15:]))
        return
    verdict = "OK" if wall < GOAL_WORKFLOW_S else "ABOVE GOAL"
    print(f"(a) snakemake --cores 2 exports (default config, fresh copy): {wall:.1f} s "
          f"(goal < {GOAL_WORKFLOW_S:.0f} s) {verdict}")


def big_config(quick: bool) -> dict:
    """The default config with a source big enough for (b).

    Full: 801 x 601 nodes (0.0005 deg), 7 levels, hourly over 6 days (145 steps): u, v, u_tide,
    v_tide float32 uncompressed = 4.5 GB. Quick: 0.002 deg over 2 days (~0.1 GB).
    """
    with open(REPO / "config" / "config.yaml") as fh:
        cfg = yaml.safe_load(fh)
    days = 2 if quick else 6
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00",
                             "end": f"2025-01-{1 + days:02d}T00:00:00"}
    cfg["synthetic"]["resolution_deg"] = 0.002 if quick else 0.0005
    cfg["variants"]["public"] = {"extent_fraction": 1.0,
                                 "resolution_deg": 0.004 if quick else 0.001,
                                 "hours": 24 * days, "max_depth_m": 120.0}
    return cfg


def _child(code: str, *args: str) -> tuple[float, float, int]:
    """Run ``python -c code args`` and return (wall s, peak RSS bytes, exit status)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code, *args])
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return time.perf_counter() - t0, usage.ru_maxrss * 1024.0, proc.returncode


GENERATE = """
import json, sys
from oneocean.sources.synthetic import write_synthetic
cfg = json.load(open(sys.argv[1]))
write_synthetic(cfg, sys.argv[2], sys.argv[3], zlib=False)
"""

MERGE = """
import json, sys
from oneocean.product import build_product
cfg = json.load(open(sys.argv[1]))
build_product(sys.argv[2], sys.argv[3], cfg, "public", sys.argv[4], sys.argv[5])
"""


def bench_rss(workdir: Path, quick: bool) -> None:
    """(b) Peak RSS of build_product on a >= 4 GB synthetic source."""
    cfg = big_config(quick)
    cfg_path = workdir / "config.json"
    cfg_path.write_text(json.dumps(cfg))
    cur, bat = workdir / "currents.nc", workdir / "bathymetry.nc"
    wall, rss, rc = _child(GENERATE, str(cfg_path), str(cur), str(bat))
    if rc != 0:
        print(f"(b) generating the synthetic source FAILED (exit {rc})")
        return
    size = cur.stat().st_size
    print(f"(b) synthetic source: {size / GB:.2f} GB on disk ({cur.name}), generated in "
          f"{wall:.1f} s, generator peak RSS {rss / GB:.2f} GB")
    if not quick and size < 4 * GB:
        print("    WARNING: source smaller than 4 GB")
    out, meta = workdir / "product.nc", workdir / "metadata.json"
    wall, rss, rc = _child(MERGE, str(cfg_path), str(cur), str(bat), str(out), str(meta))
    if rc != 0:
        print(f"(b) build_product FAILED (exit {rc})")
        return
    grid = json.loads(meta.read_text())["grid"]
    verdict = "OK" if rss < GOAL_RSS_GB * GB else "ABOVE GOAL"
    print(f"(b) build_product: product {grid['nt']} x {grid['nz']} x {grid['ny']} x "
          f"{grid['nx']} ({out.stat().st_size / GB:.2f} GB) in {wall:.1f} s; "
          f"peak RSS {rss / GB:.2f} GB (goal < {GOAL_RSS_GB} GB) {verdict}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small source (smoke run)")
    ap.add_argument("--skip-workflow", action="store_true", help="only part (b)")
    ap.add_argument("--skip-rss", action="store_true", help="only part (a)")
    ap.add_argument("--workdir", type=Path, default=None, help="scratch folder (default: tmp)")
    ap.add_argument("--keep", action="store_true", help="keep the scratch folder")
    args = ap.parse_args(argv)
    workdir = Path(tempfile.mkdtemp(prefix="oneocean-bench-", dir=args.workdir))
    print(f"scratch: {workdir}  cpus: {os.cpu_count()}  python: {sys.version.split()[0]}")
    try:
        if not args.skip_workflow:
            (workdir / "a").mkdir()
            bench_workflow(workdir / "a")
        if not args.skip_rss:
            (workdir / "b").mkdir()
            bench_rss(workdir / "b", args.quick)
    finally:
        if args.keep:
            print(f"kept {workdir}")
        else:
            shutil.rmtree(workdir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
