"""Benchmarks of the product stage (prints figures, asserts nothing).

(a) Wall time of ``snakemake --cores 2 exports`` on the default config, in a scratch copy of the
    repository (goal < 60 s including Snakemake start-up).
(b) Peak RSS of ``build_product`` merging a synthetic currents source of >= 4 GB on disk
    (goal < 1.5 GB): the source is generated lazily, one time step at a time, in a child
    process; the merge runs in another child whose peak RSS comes from ``os.wait4``.
(c) A product several times larger than a dask worker's memory limit (default 7 days: 1.3 GB
    as float32, 3.2 x a 400 MB worker), built on a ``dask.distributed`` LocalCluster
    (``--workers`` processes of one thread, each limited to ``--worker-memory-mb``; config
    ``product.scheduler``) and, as the baseline in the same run, on the local threads
    scheduler; each as a zarr store (``--format``). Prints the product's size next to the
    worker limit, the wall times, the peak RSS of every worker process (``resource.getrusage``
    inside the worker) and of the processes that drive the builds, and whether both schedulers
    wrote the same bytes. A distributed build that has not finished after ``--timeout`` seconds
    is reported as stalled (with each worker's status and memory) and the script exits 1.

Usage::

    python benchmarks/product.py            # all parts, full 4 GB source
    python benchmarks/product.py --quick    # smoke run: ~0.1 GB source
    python benchmarks/product.py --skip-workflow --workdir /big/tmp --keep
    python benchmarks/product.py --only-distributed            # part (c), ~4 min here
    python benchmarks/product.py --only-distributed --worker-memory-mb 500 --days 9
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
from oneocean.product.build import build_product
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


def distributed_config(days: int) -> dict:
    """The default region at 0.001 deg (401 x 301 nodes, 7 levels), hourly over ``days``: each
    time step holds u, v (7 levels) and u_tide, v_tide, 7.7 MB as float32."""
    with open(REPO / "config" / "config.yaml") as fh:
        cfg = yaml.safe_load(fh)
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00",
                             "end": f"2025-01-{1 + days:02d}T00:00:00"}
    cfg["synthetic"]["resolution_deg"] = 0.001
    cfg["variants"]["public"] = {"extent_fraction": 1.0, "resolution_deg": 0.001,
                                 "hours": 24 * days, "max_depth_m": 120.0}
    return cfg


DISTRIBUTED = """
import json, os, resource, sys, threading, time
cfg_path, cur, bat, out, meta, workers, limit_mb, res, timeout = sys.argv[1:10]
cfg = json.load(open(cfg_path))
from distributed import LocalCluster, Client
from oneocean.product.build import build_product

def peak_rss():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024

with LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                  memory_limit=f"{limit_mb}MB", dashboard_address=None,
                  silence_logs=40) as cluster, Client(cluster.scheduler_address) as client:
    cfg["product"] = {"scheduler": cluster.scheduler_address}
    failed = []
    def run():
        try:
            build_product(cur, bat, cfg, "public", out, meta)
        except BaseException as exc:
            failed.append(f"{type(exc).__name__}: {exc}")
    t0 = time.perf_counter()
    job = threading.Thread(target=run, daemon=True)
    job.start()
    job.join(float(timeout))
    wall = time.perf_counter() - t0
    rss = sorted(client.run(peak_rss).values())
    workers = client.scheduler_info()["workers"].values()
    state = [f"{w['status']} at {w['metrics']['memory'] / 1e6:.0f} MB" for w in workers]
    json.dump({"wall": wall, "worker_peak_rss": rss, "client_peak_rss": peak_rss(),
               "stalled": job.is_alive(), "workers": state, "error": failed},
              open(res, "w"))
    if job.is_alive() or failed:
        os._exit(3)       # the build thread cannot be stopped; leave without waiting for it
"""


def _size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) if path.is_dir() \
        else path.stat().st_size


def _child_timeout(code: str, timeout: float, *args: str) -> tuple[float, int | None]:
    """Run ``python -c code args`` with a hard timeout: (wall s, exit status, or None when the
    child and its process group were killed after ``timeout`` s)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code, *args], start_new_session=True)
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.wait()
        return time.perf_counter() - t0, None
    return time.perf_counter() - t0, proc.returncode


def bench_distributed(workdir: Path, days: int, workers: int, limit_mb: int, fmt: str,
                      timeout: float) -> bool:
    """(c) A product several times a worker's memory limit: distributed vs local threads.

    Returns False when a build failed or did not finish within ``timeout`` s (a stall)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        print("(c) distributed: SKIPPED (pip install 'oneocean[distributed]')")
        return True
    cfg = distributed_config(days)
    cfg_path = workdir / "config.json"
    cfg_path.write_text(json.dumps(cfg))
    cur, bat = workdir / "currents.nc", workdir / "bathymetry.nc"
    wall, rss, rc = _child(GENERATE, str(cfg_path), str(cur), str(bat))
    if rc != 0:
        print(f"(c) generating the synthetic source FAILED (exit {rc})")
        return False
    print(f"(c) synthetic source: {cur.stat().st_size / 1e9:.2f} GB on disk, generated in "
          f"{wall:.1f} s")
    name = "product.zarr" if fmt == "zarr" else "product.nc"
    rows = []
    out, meta = workdir / "threads" / name, workdir / "threads" / "metadata.json"
    wall, rss, rc = _child(MERGE, str(cfg_path), str(cur), str(bat), str(out), str(meta))
    if rc != 0:
        print(f"(c) build_product on local threads FAILED (exit {rc})")
        return False
    grid = json.loads(meta.read_text())["grid"]
    nbytes = 4 * grid["nt"] * grid["ny"] * grid["nx"] * (2 * grid["nz"] + 2)
    limit = limit_mb * 1e6                    # dask reads "400MB" as 400e6 bytes
    print(f"(c) product {grid['nt']} x {grid['nz']} x {grid['ny']} x {grid['nx']}, "
          f"{nbytes / 1e6:.0f} MB as float32 in memory, worker limit {limit_mb} MB "
          f"(product = {nbytes / limit:.1f} x the worker limit), format {fmt}")
    rows.append(("local threads (1 process)", wall, f"process {rss / 1e6:.0f}", _size(out)))
    dout, dmeta = workdir / "distributed" / name, workdir / "distributed" / "metadata.json"
    res = workdir / "distributed.json"
    wall, rc = _child_timeout(DISTRIBUTED, timeout + 60.0, str(cfg_path), str(cur),
                                 str(bat), str(dout), str(dmeta), str(workers), str(limit_mb),
                                 str(res), str(timeout))
    r = json.loads(res.read_text()) if rc is not None and res.is_file() else None
    if r is None or r["stalled"] or r["error"]:
        if r is None:
            why = f"killed after {wall:.0f} s (exit {rc})"
        elif r["stalled"]:
            why = (f"did not finish within {timeout:.0f} s: STALLED, workers "
                   f"{'; '.join(r['workers'])} (dask pauses a worker at 80% of its limit)")
        else:
            why = f"FAILED: {r['error'][0]}"
        print(f"(c) build_product on the distributed cluster {why}")
        return False
    workers_mb = ", ".join(f"{b / 1e6:.0f}" for b in r["worker_peak_rss"])
    rows.append((f"distributed {workers} x 1 thread, limit {limit_mb} MB", r["wall"],
                 f"workers {workers_mb}; driver {r['client_peak_rss'] / 1e6:.0f}",
                 _size(dout)))
    same = (json.loads(meta.read_text())["product"]["sha256"]
            == json.loads(dmeta.read_text())["product"]["sha256"])
    print(f"    {'scheduler':<42} {'wall s':>7}  {'on disk MB':>10}  peak RSS MB")
    for label, w, peak, size in rows:
        print(f"    {label:<42} {w:>7.1f}  {size / 1e6:>10.0f}  {peak}")
    print(f"    same bytes on both schedulers: {'yes' if same else 'NO'}")
    return same


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small source (smoke run)")
    ap.add_argument("--skip-workflow", action="store_true", help="only part (b)")
    ap.add_argument("--skip-rss", action="store_true", help="skip part (b)")
    ap.add_argument("--only-distributed", action="store_true", help="only part (c)")
    ap.add_argument("--skip-distributed", action="store_true", help="skip part (c)")
    ap.add_argument("--days", type=int, default=7,
                    help="(c) days of hourly data (default 7: a 1.3 GB product, 3.2 x the "
                         "default worker limit; ~4 min here with both builds)")
    ap.add_argument("--workers", type=int, default=2, help="(c) worker processes (default 2)")
    ap.add_argument("--worker-memory-mb", type=int, default=400,
                    help="(c) memory limit of each worker (default 400; a worker's Python, "
                         "numpy, dask and zarr take ~200 MB, and dask pauses a worker at 80%% "
                         "of its limit, so much less stalls the build)")
    ap.add_argument("--format", choices=("zarr", "netcdf"), default="zarr",
                    help="(c) product format (default zarr)")
    ap.add_argument("--timeout", type=float, default=300.0,
                    help="(c) seconds the distributed build may take before it is reported as "
                         "stalled (default 300)")
    ap.add_argument("--workdir", type=Path, default=None, help="scratch folder (default: tmp)")
    ap.add_argument("--keep", action="store_true", help="keep the scratch folder")
    args = ap.parse_args(argv)
    workdir = Path(tempfile.mkdtemp(prefix="oneocean-bench-", dir=args.workdir))
    print(f"scratch: {workdir}  cpus: {os.cpu_count()}  python: {sys.version.split()[0]}")
    ok = True
    try:
        if not (args.skip_workflow or args.only_distributed):
            (workdir / "a").mkdir()
            bench_workflow(workdir / "a")
        if not (args.skip_rss or args.only_distributed):
            (workdir / "b").mkdir()
            bench_rss(workdir / "b", args.quick)
        if not args.skip_distributed:
            (workdir / "c").mkdir()
            ok = bench_distributed(workdir / "c", 1 if args.quick else args.days,
                                   args.workers, args.worker_memory_mb, args.format,
                                   args.timeout) and ok
    finally:
        if args.keep:
            print(f"kept {workdir}")
        else:
            shutil.rmtree(workdir, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
