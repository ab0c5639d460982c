"""Provenance records for every workflow output, the collected manifest, and ``verify``.

Each Snakemake job writes one provenance JSON (``results/provenance/<rule>/<wildcards>.json``)
describing its outputs; the ``manifest`` rule collects a region's into
``results/manifest/<region>.json``.
``oneocean verify`` recomputes every hash and names artifacts whose bytes or inputs changed.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from .io import canonical_json, config_hash, sha256_file, write_json_atomic

#: Packages whose versions are recorded with every artifact.
TRACKED_PACKAGES = ("oneocean", "numpy", "xarray", "netCDF4", "dask", "numba", "pandas",
                    "pyarrow", "scipy", "matplotlib", "snakemake", "copernicusmarine")

#: File suffixes whose container format may embed write-time metadata: for these the manifest
#: also stores a hash of the decoded content, which ``verify`` accepts when bytes differ.
CONTENT_HASHED = (".nc", ".nc4")


@functools.lru_cache(maxsize=1)
def package_versions() -> dict:
    out = {}
    for name in TRACKED_PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


@functools.lru_cache(maxsize=1)
def git_commit(cwd: str | None = None) -> str:
    """The checked-out commit (with ``+dirty`` if tracked files changed), or ``unknown``."""
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True,
                             text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def content_hash(path: str | os.PathLike) -> str | None:
    """Hash of the decoded variables for NetCDF files, ``None`` for other formats."""
    if not str(path).endswith(CONTENT_HASHED):
        return None
    import xarray as xr

    from .io import dataset_content_hash

    with xr.open_dataset(path, decode_times=False, mask_and_scale=False) as ds:
        return dataset_content_hash(ds)


def file_record(path: str | os.PathLike) -> dict:
    p = Path(path)
    rec = {"path": p.as_posix(), "sha256": sha256_file(p), "bytes": p.stat().st_size}
    ch = content_hash(p)
    if ch is not None:
        rec["content_sha256"] = ch
    return rec


def job_provenance(rule: str, wildcards: dict, outputs: list, inputs: list, params: dict) -> dict:
    """Provenance of one job: its outputs (hashed), inputs (hashed), params and environment."""
    return {
        "rule": rule,
        "wildcards": dict(sorted(wildcards.items())),
        "outputs": [file_record(o) for o in outputs],
        "inputs": [file_record(i) for i in inputs if Path(i).is_file()],
        "params": params,
        "params_sha256": config_hash(params),
        "packages": package_versions(),
        "git_commit": git_commit(),
    }


def write_job_provenance(path, rule, wildcards, outputs, inputs, params) -> dict:
    prov = job_provenance(rule, wildcards, outputs, inputs, params)
    write_json_atomic(path, prov)
    return prov


def collect_manifest(provenance_files, out_path) -> dict:
    """Merge job provenance files into one manifest keyed by artifact path."""
    artifacts = {}
    for pf in sorted(map(str, provenance_files)):
        with open(pf) as fh:
            job = json.load(fh)
        for out in job["outputs"]:
            artifacts[out["path"]] = {
                **out,
                "rule": job["rule"],
                "wildcards": job["wildcards"],
                "inputs": job["inputs"],
                "params": job["params"],
                "packages": job["packages"],
                "git_commit": job["git_commit"],
                "provenance": Path(pf).as_posix(),
            }
    manifest = {"schema": "oneocean-manifest/1", "artifacts": dict(sorted(artifacts.items()))}
    write_json_atomic(out_path, manifest)
    return manifest


def verify(manifest_path: str | os.PathLike,
           root: str | os.PathLike = ".") -> list[str]:
    """Recompute every hash in the manifest; return one problem line per mismatching artifact.

    An artifact is bad when it is missing, when its bytes changed (for NetCDF: when both its
    bytes and its decoded content changed), or when any input it was made from changed.
    """
    root = Path(root)
    with open(manifest_path) as fh:
        manifest = json.load(fh)
    problems = []
    for path, rec in manifest["artifacts"].items():
        p = root / path
        if not p.is_file():
            problems.append(f"{path}: missing")
            continue
        if sha256_file(p) != rec["sha256"]:
            if not (rec.get("content_sha256") and content_hash(p) == rec["content_sha256"]):
                problems.append(f"{path}: bytes changed since rule '{rec['rule']}' wrote it")
                continue
        for inp in rec["inputs"]:
            ip = root / inp["path"]
            if not ip.is_file():
                problems.append(f"{path}: input {inp['path']} is missing")
                break
            if sha256_file(ip) != inp["sha256"] and not (
                    inp.get("content_sha256") and content_hash(ip) == inp["content_sha256"]):
                problems.append(f"{path}: input {inp['path']} changed since it was made")
                break
    return problems


__all__ = ["collect_manifest", "verify", "write_job_provenance", "job_provenance",
           "file_record", "package_versions", "git_commit", "canonical_json"]
