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

from ..io import canonical_json, config_hash, write_json_atomic
from ..product.zarrio import is_zarr, path_bytes, sha256_path


def _is_store(path) -> bool:
    """A zarr store (a ``.zarr`` directory), hashed like a file."""
    return is_zarr(path) and Path(path).is_dir()

#: Packages whose versions are recorded with every artifact.
TRACKED_PACKAGES = ("oneocean", "numpy", "xarray", "netCDF4", "dask", "numba", "pandas",
                    "pyarrow", "scipy", "matplotlib", "snakemake", "copernicusmarine")

#: File suffixes whose container format may embed write-time metadata: for these the manifest
#: also stores a hash of the decoded content, which ``verify`` accepts when bytes differ.
#: A zarr store (a ``.zarr`` directory) is hashed over its files (:func:`oneocean.product.zarrio.
#: store_sha256`) and gets a content hash too.
CONTENT_HASHED = (".nc", ".nc4", ".zarr")


@functools.lru_cache(maxsize=1)
def package_versions() -> dict:
    """The installed versions of :data:`TRACKED_PACKAGES` (cached for the process).

    Returns
    -------
    dict
        ``{package: version}``; None for a package that is not installed.
    """
    out = {}
    for name in TRACKED_PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


@functools.lru_cache(maxsize=1)
def git_commit(cwd: str | None = None) -> str:
    """The checked-out git commit (cached for the process).

    Parameters
    ----------
    cwd : str, optional
        A folder inside the repository (default: the current directory).

    Returns
    -------
    str
        The commit hash, with ``+dirty`` if tracked files changed, or ``"unknown"`` outside
        a repository or without git.
    """
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True,
                             text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def content_hash(path: str | os.PathLike) -> str | None:
    """Hash of the decoded variables of a NetCDF file or zarr store.

    Parameters
    ----------
    path : path-like
        A product (``.nc``, ``.nc4``, ``.zarr``) or the arrays store of a zarr export.

    Returns
    -------
    str or None
        The content hash; None for a path without a :data:`CONTENT_HASHED` suffix.
    """
    if not str(path).rstrip("/").endswith(CONTENT_HASHED):
        return None
    from ..io import dataset_content_hash
    from ..product.zarrio import arrays_content_hash, is_arrays_store, open_product

    if is_arrays_store(path):                 # a zarr export: named arrays, no dimensions
        return arrays_content_hash(path)
    with open_product(path, decode_times=False, mask_and_scale=False) as ds:
        return dataset_content_hash(ds)


def file_record(path: str | os.PathLike) -> dict:
    """The manifest record of one file or zarr store.

    Parameters
    ----------
    path : path-like
        The artifact.

    Returns
    -------
    dict
        ``{"path", "sha256", "bytes"}``, plus ``"content_sha256"`` (:func:`content_hash`) for
        NetCDF files and zarr stores.
    """
    p = Path(path)
    rec = {"path": p.as_posix(), "sha256": sha256_path(p), "bytes": path_bytes(p)}
    ch = content_hash(p)
    if ch is not None:
        rec["content_sha256"] = ch
    return rec


def job_provenance(rule: str, wildcards: dict, outputs: list, inputs: list, params: dict) -> dict:
    """Provenance of one job: its outputs (hashed), inputs (hashed), params and environment.

    Parameters
    ----------
    rule : str
        The Snakemake rule.
    wildcards : dict
        The job's wildcards (stored sorted by key).
    outputs : list of path-like
        The job's outputs; each is hashed (:func:`file_record`).
    inputs : list of path-like
        The job's inputs; those that are files or zarr stores are hashed, others skipped.
    params : dict
        The job's JSON-able parameters (stored, and hashed as ``params_sha256``).

    Returns
    -------
    dict
        ``{rule, wildcards, outputs, inputs, params, params_sha256, packages, git_commit}``.
    """
    return {
        "rule": rule,
        "wildcards": dict(sorted(wildcards.items())),
        "outputs": [file_record(o) for o in outputs],
        "inputs": [file_record(i) for i in inputs if Path(i).is_file() or _is_store(i)],
        "params": params,
        "params_sha256": config_hash(params),
        "packages": package_versions(),
        "git_commit": git_commit(),
    }


def write_job_provenance(path, rule, wildcards, outputs, inputs, params) -> dict:
    """Write one job's provenance (:func:`job_provenance`) as JSON, atomically.

    Parameters
    ----------
    path : path-like
        The provenance file (``results/provenance/<rule>/<wildcards>.json``).
    rule, wildcards, outputs, inputs, params
        As :func:`job_provenance`.

    Returns
    -------
    dict
        The record written.
    """
    prov = job_provenance(rule, wildcards, outputs, inputs, params)
    write_json_atomic(path, prov)
    return prov


def collect_manifest(provenance_files, out_path) -> dict:
    """Merge job provenance files into one manifest keyed by artifact path.

    Parameters
    ----------
    provenance_files : iterable of path-like
        The jobs' provenance JSON files, read in sorted order (a later job's record of the
        same path wins).
    out_path : path-like
        The manifest JSON, written atomically.

    Returns
    -------
    dict
        ``{"schema": "oneocean-manifest/1", "artifacts": {path: record}}``: each output's
        file record with its job's rule, wildcards, inputs, params, packages, git commit
        and provenance file.
    """
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


def _reason(exc: BaseException, path) -> str:
    """A decoder's or the OS's complaint on one line, without the file's own name."""
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    names = (str(path), os.fspath(Path(path).resolve()))
    for name in [repr(n) for n in names] + list(names):
        text = text.replace(f": {name}", "").replace(name, "")
    return " ".join(text.split())[:200] or type(exc).__name__


def _check(p: Path, rec: dict) -> str | None:
    """What is wrong with file ``p`` against its manifest record ``rec`` (which holds
    ``sha256`` and, for NetCDF, ``content_sha256``), or None when it matches."""
    if not (p.is_file() or _is_store(p)):
        return "missing"
    try:
        if sha256_path(p) == rec["sha256"]:
            return None
    except OSError as exc:
        return f"cannot be read ({_reason(exc, p)})"
    if not rec.get("content_sha256"):
        return "sha256 differs from the manifest"
    try:
        content = content_hash(p)
    except Exception as exc:  # noqa: BLE001 (any decoder failure means a corrupt file)
        return f"cannot be decoded ({_reason(exc, p)})"
    if content != rec["content_sha256"]:
        return "content hash differs from the manifest"
    return None


def verify(manifest_path: str | os.PathLike,
           root: str | os.PathLike = ".") -> list[str]:
    """Recompute every hash in the manifest; return one problem line per bad artifact.

    An artifact is bad when it is missing or unreadable, when its bytes changed (for NetCDF:
    when its bytes changed and its decoded content changed or cannot be decoded), or when any
    input it was made from is bad in the same way. Every artifact is checked; a corrupt file
    is a problem line, never an exception.

    Parameters
    ----------
    manifest_path : path-like
        The manifest JSON (:func:`collect_manifest`).
    root : path-like, default "."
        The folder the manifest's artifact paths are relative to.

    Returns
    -------
    list of str
        One line per bad artifact (empty: everything verifies).

    Raises
    ------
    DataError
        The manifest itself cannot be read or is not a manifest (one line naming it).
    """
    from ..errors import DataError

    root = Path(root)
    try:
        with open(manifest_path) as fh:
            manifest = json.load(fh)
        artifacts = manifest["artifacts"]
        items = list(artifacts.items())
    except OSError as exc:
        raise DataError(f"{manifest_path}: cannot read the manifest "
                        f"({exc.strerror or exc})") from None
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise DataError(f"{manifest_path}: not a oneocean manifest "
                        f"({_reason(exc, manifest_path)})") from None
    problems = []
    for path, rec in items:
        try:
            bad = _check(root / path, rec)
            if bad:
                problems.append(f"{path}: {bad}" if bad == "missing" else
                                f"{path}: {bad} (written by rule '{rec['rule']}')")
                continue
            for inp in rec["inputs"]:
                bad = _check(root / inp["path"], inp)
                if bad:
                    problems.append(f"{path}: input {inp['path']} is missing" if bad == "missing"
                                    else f"{path}: input {inp['path']} changed since it was "
                                    f"made: {bad}")
                    break
        except (KeyError, TypeError, AttributeError) as exc:
            problems.append(f"{path}: malformed manifest record ({type(exc).__name__}: {exc})")
    return problems


__all__ = ["collect_manifest", "verify", "write_job_provenance", "job_provenance",
           "file_record", "package_versions", "git_commit", "canonical_json"]
