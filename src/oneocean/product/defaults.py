"""The default grid: a working grid export without running the workflow.

:func:`default_grid_path` returns the grid export (``grid.npz``, contracts §3) of the embedded
default region, the synthetic coast (``oneocean/data/regions/synthetic_coast.yaml``; offline,
no credentials). The first call builds it with the workflow's own library functions --
:func:`oneocean.sources.fetch_currents`, :func:`~oneocean.sources.fetch_bathymetry`,
:func:`oneocean.product.build.build_product`, :func:`oneocean.product.exports.export_grid` -- on the same
configuration sections, so the file is the workflow's
``results/exports/synthetic_coast/<variant>/grid.npz`` byte for byte; later calls return the
cached file.

Cache
    ``$ONEOCEAN_CACHE_DIR`` if set, else ``~/.cache/oneocean``; a grid lives in
    ``grids/<region>/<variant>/<key>/`` with ``grid.npz`` and ``grid.json`` (its sha256 and
    size, the key, the configuration it was built from and how it was built). ``key`` hashes
    the region's configuration (the sections its product depends on, defaults filled), the
    variant, the package version and the source of the code that builds it, and the size and
    modification time of any local input file, so a change to any of them builds a new
    entry. A build runs in a temporary folder beside the entry (the intermediate source and
    product files are deleted with it) under an exclusive lock file (``<key>.lock``,
    ``fcntl.flock``), and the finished folder is renamed into place: concurrent first uses
    build once, and a reader never sees a partial file.

:func:`resolve_grid` turns what an env or :func:`oneocean.evaluate.evaluate` is given into a
:class:`~oneocean.engine.grid.Grid`: None (the default grid), a Grid, a grid export path, or
a region config YAML (built like the default when its sources are synthetic or local files).
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import logging
import os
import platform
import re
import shutil
import tempfile
import time
import zipfile
from importlib import resources
from pathlib import Path

from .. import __version__
from ..errors import ConfigError, DataError

__all__ = ["default_grid_path", "region_grid_path", "resolve_grid", "region_config",
           "cache_dir", "grid_key", "DEFAULT_CONFIG", "DEFAULT_VARIANT", "CACHE_ENV"]

log = logging.getLogger(__name__)

#: The environment variable naming the cache folder (default ``~/.cache/oneocean``).
CACHE_ENV = "ONEOCEAN_CACHE_DIR"
#: The embedded default region's configuration (package data).
DEFAULT_CONFIG = Path(str(resources.files("oneocean") / "data" / "regions"
                          / "synthetic_coast.yaml"))
#: The variant whose grid the envs use by default (the workflow's ``rollouts.variant``).
DEFAULT_VARIANT = "scene"
_VARIANTS = ("tiny", "scene", "public")      # oneocean.vocab.VARIANTS (not imported: cheap path)
#: The configuration sections a product depends on (:data:`oneocean.config.DATA_SECTIONS`).
_SECTIONS = ("region", "sources", "synthetic", "cmems", "gebco", "etopo", "files", "variants")
#: What each workflow step is given (``config_section`` in workflow/rules/{fetch,product}.smk).
_FETCH_CURRENTS = ("region", "sources", "synthetic", "cmems", "files")
_FETCH_BATHYMETRY = ("region", "sources", "synthetic", "gebco", "etopo", "files")
#: The code that builds a grid (package-relative files and folders), hashed into the key.
_CODE = ("sources", "product", "io.py", "vocab.py", "engine/grid.py")
_STEPS = ("oneocean.sources.fetch_currents", "oneocean.sources.fetch_bathymetry",
          "oneocean.product.build.build_product", "oneocean.product.exports.export_grid")
_FORMAT = "oneocean.grid-cache/1"
_NAME = re.compile(r"^[A-Za-z0-9_-]+$")
_PKG = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------ configuration

def cache_dir() -> Path:
    """The cache folder.

    Returns
    -------
    pathlib.Path
        ``$ONEOCEAN_CACHE_DIR`` (``~`` expanded) if set and not empty, else
        ``~/.cache/oneocean``; not created here.
    """
    env = os.environ.get(CACHE_ENV, "").strip()
    return Path(env).expanduser() if env else Path.home() / ".cache" / "oneocean"


def _load_yaml(path: Path, what: str) -> dict:
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        doc = yaml.load(path.read_text(), Loader=loader)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: the {what}'s top level must be a mapping")
    return doc


_schema_cache: dict = {}


def _schema() -> dict:
    if "schema" not in _schema_cache:
        _schema_cache["schema"] = _load_yaml(_PKG / "data" / "config.schema.yaml",
                                             "config schema")
    return _schema_cache["schema"]


def _fill(props: dict, doc: dict) -> dict:
    """``doc`` with the schema's defaults filled in where a key is missing, recursively (what
    :func:`oneocean.config.validate_config` fills, without validating)."""
    for key, sub in props.items():
        if key not in doc and "default" in sub:
            doc[key] = copy.deepcopy(sub["default"])
        if isinstance(doc.get(key), dict) and "properties" in sub:
            _fill(sub["properties"], doc[key])
    return doc


def _merge(base: dict, new: dict) -> dict:
    for k, v in new.items():
        if isinstance(v, dict) and isinstance(base.get(k), dict):
            _merge(base[k], v)
        else:
            base[k] = copy.deepcopy(v)
    return base


def region_config(path: str | os.PathLike | None = None) -> dict:
    """The sections of a region's configuration its product depends on, defaults filled in.

    The sections are ``region``, ``sources``, ``synthetic``, ``cmems``, ``gebco``, ``etopo``,
    ``files`` and ``variants``. Not validated: :func:`oneocean.config.validate_data_config`
    does that before a build.

    Parameters
    ----------
    path : str or os.PathLike, optional
        None: the embedded default region (:data:`DEFAULT_CONFIG`). Otherwise a YAML file
        merged over it, as the workflow merges ``--configfile config/regions/<region>.yaml``
        over ``config/config.yaml`` (a full config file works too; its other sections are
        ignored here).

    Returns
    -------
    dict
        The sections, the schema's defaults filled in where a key is missing.

    Raises
    ------
    ConfigError
        The file is unreadable, not valid YAML, not a mapping, or has a top-level key the
        config schema does not know.
    """
    doc = copy.deepcopy(_load_yaml(DEFAULT_CONFIG, "region config"))
    props = _schema()["properties"]
    if path is not None:
        user = _load_yaml(Path(os.fspath(path)), "region config")
        unknown = sorted(set(user) - set(props))
        if unknown:
            raise ConfigError(f"{path}: unknown key '{unknown[0]}' (known keys here: "
                              f"{', '.join(sorted(props))})")
        _merge(doc, {k: v for k, v in user.items() if k in _SECTIONS})
    return _fill({k: props[k] for k in _SECTIONS}, {k: doc[k] for k in _SECTIONS if k in doc})


def _snapshot(cfg: dict, variant: str) -> dict:
    """What the product of ``variant`` depends on (:func:`oneocean.product.build.product_config`)."""
    snap = {k: cfg[k] for k in _SECTIONS[:-1] if k in cfg}
    snap["variant"] = {"name": variant, **cfg["variants"][variant]}
    return snap


def _local_inputs(cfg: dict) -> list[tuple[str, str]]:
    """(config key, path) of every local input file the region's sources read."""
    src, out = cfg["sources"], []
    if src["currents"] == "files":
        out.append(("files.currents", cfg["files"]["currents"]))
        if src["tides"] and cfg["files"].get("tides"):
            out.append(("files.tides", cfg["files"]["tides"]))
    if src["bathymetry"] == "files":
        out.append(("files.bathymetry", cfg["files"]["bathymetry"]))
    elif src["bathymetry"] == "etopo":
        out.append(("etopo.path", cfg["etopo"]["path"]))
    elif src["bathymetry"] == "gebco" and cfg["gebco"].get("path"):
        out.append(("gebco.path", cfg["gebco"]["path"]))
    return [(k, str(p)) for k, p in out if p]


def _input_records(cfg: dict, where: str) -> list[dict]:
    """Size and modification time of each local input (a DataError if one is missing)."""
    recs = []
    for key, p in _local_inputs(cfg):
        path = Path(p)
        try:
            st = path.stat()
        except OSError:
            raise DataError(f"{where}: {key} {p}: file not found (relative paths are read "
                            f"from the current directory, {Path.cwd()})") from None
        recs.append({"key": key, "path": str(path.resolve()), "bytes": st.st_size,
                     "mtime_ns": st.st_mtime_ns})
    return recs


def _offline(cfg: dict, where: str) -> None:
    """A one-line ConfigError if a source needs the network."""
    src = cfg["sources"]
    if src["currents"] == "cmems":
        raise ConfigError(f"{where}: sources.currents is 'cmems' (Copernicus Marine: network "
                          "and credentials); only regions whose sources are synthetic or local "
                          "files are built here -- run the workflow for this region "
                          f"(`snakemake --cores 2 exports --configfile {where}`) and pass its "
                          "grid.npz")
    if src["bathymetry"] == "gebco" and not cfg["gebco"].get("path"):
        raise ConfigError(f"{where}: sources.bathymetry is 'gebco' from gebco.url (network); "
                          "set gebco.path to a local GEBCO file, or run the workflow for this "
                          "region and pass its grid.npz")


def _code_hash() -> str:
    from ..pipeline.codeversion import files_hash

    files = []
    for entry in _CODE:
        p = _PKG / entry
        files += sorted(f for pat in ("*.py", "*.yaml") for f in p.rglob(pat)) if p.is_dir() \
            else [p]
    return files_hash(files)


def grid_key(cfg: dict, variant: str, inputs: list[dict] | None = None) -> str:
    """The cache key of a variant of a region's grid.

    Parameters
    ----------
    cfg : dict
        The region's configuration (:func:`region_config`).
    variant : str
        The product variant: ``tiny``, ``scene`` or ``public`` (a key of ``cfg["variants"]``).
    inputs : list of dict, optional
        Records of the local input files (config key, resolved path, size in bytes,
        modification time in ns); default none.

    Returns
    -------
    str
        Hex sha256 of the product's configuration, the package version, the hash of the code
        that builds the grid and ``inputs``.
    """
    doc = {"format": _FORMAT, "config": _snapshot(cfg, variant), "oneocean_version": __version__,
           "code_sha256": _code_hash(), "inputs": inputs or []}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def _variant(variant: str) -> str:
    if variant not in _VARIANTS:
        raise ConfigError(f"variant: invalid value {variant!r}; valid variants are "
                          f"{', '.join(_VARIANTS)}")
    return variant


# ------------------------------------------------------------------------------ the cache

def default_grid_path(variant: str = DEFAULT_VARIANT) -> Path:
    """The grid export of the embedded default region (the synthetic coast).

    Built on first use into the cache, then returned from it. Byte-identical to the
    workflow's ``results/exports/synthetic_coast/<variant>/grid.npz`` built by the same code
    and libraries.

    Parameters
    ----------
    variant : str, default "scene"
        The product variant: ``tiny``, ``scene`` or ``public``.

    Returns
    -------
    pathlib.Path
        The cached ``grid.npz``.

    Raises
    ------
    ConfigError
        ``variant`` is not a variant.
    DataError
        The cache folder cannot be written (set ``ONEOCEAN_CACHE_DIR``).
    """
    return region_grid_path(None, variant)


def region_grid_path(config: str | os.PathLike | None = None,
                     variant: str = DEFAULT_VARIANT) -> Path:
    """The cached grid export of a variant of a region, built on first use.

    Only regions whose sources are synthetic or local files are built (no network).

    Parameters
    ----------
    config : str or os.PathLike, optional
        A region config YAML file merged over the default region (see
        :func:`region_config`); None: the default region.
    variant : str, default "scene"
        The product variant: ``tiny``, ``scene`` or ``public``.

    Returns
    -------
    pathlib.Path
        The cached ``grid.npz``, ``<cache>/grids/<region>/<variant>/<key>/grid.npz`` (the
        key's first 16 hex digits, :func:`grid_key`).

    Raises
    ------
    ConfigError
        A bad or unknown key, or a source that needs the network (one line naming the file).
    DataError
        A local input file is missing, the build fails, or the cache cannot be written.
    """
    variant = _variant(variant)
    where = "the default region" if config is None else str(config)
    cfg = region_config(config)
    if config is not None:                    # a user's file: checked before anything else
        from ..config import validate_data_config

        validate_data_config(copy.deepcopy(cfg), where)
    name = str(cfg.get("region", {}).get("name", ""))
    if not _NAME.match(name):
        raise ConfigError(f"{where}: config key 'region.name': {name!r} must be letters, "
                          "digits, '_' or '-'")
    _offline(cfg, where)
    inputs = _input_records(cfg, where)
    key = grid_key(cfg, variant, inputs)
    folder = cache_dir() / "grids" / name / variant
    entry = folder / key[:16]
    if _valid(entry, key):
        return entry / "grid.npz"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with _lock(folder / f"{key[:16]}.lock") as locked:
            if _valid(entry, key):            # another process built it meanwhile
                return entry / "grid.npz"
            _build(cfg, variant, key, inputs, entry, locked,
                   "oneocean/data/regions/synthetic_coast.yaml (embedded default)"
                   if config is None else str(Path(config).resolve()),
                   where)
    except OSError as exc:
        raise DataError(f"{exc.filename or folder}: cannot build the grid in the cache "
                        f"({exc.strerror or exc}); set {CACHE_ENV} to a writable folder") \
            from None
    return entry / "grid.npz"


def _valid(entry: Path, key: str) -> bool:
    """The entry holds a finished grid of ``key`` (its record and a file of the recorded
    size)."""
    try:
        rec = json.loads((entry / "grid.json").read_text())
        return rec.get("key") == key and (entry / "grid.npz").stat().st_size == rec["bytes"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


@contextlib.contextmanager
def _lock(path: Path):
    """An exclusive ``flock`` on ``path`` (created if missing) for the block; yields whether
    it holds one (without ``fcntl``, on Windows, it does not: the atomic rename alone keeps
    the cache consistent, and concurrent first uses may each build)."""
    try:
        import fcntl
    except ImportError:                       # pragma: no cover - not POSIX
        yield False
        return
    with open(path, "a+b") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield True
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


class _BuildPath(os.PathLike):
    """A file of a build folder: opened at its real place (``os.fspath``) and recorded by
    its path relative to the folder (``str``), as the workflow records its files relative to
    its working directory; so the product and the grid export record the workflow's paths."""

    def __init__(self, root: Path, rel: str):
        self.real, self.rel = root / rel, rel

    def __fspath__(self) -> str:
        return str(self.real)

    def __str__(self) -> str:
        return self.rel

    def __repr__(self) -> str:
        return f"_BuildPath({self.rel!r} -> {str(self.real)!r})"


def _workflow_paths(name: str, variant: str) -> dict[str, str]:
    """The workflow's files for the region and variant (``workflow/rules/*.smk``)."""
    return {"currents": f"results/raw/{name}/currents.nc",
            "bathymetry": f"results/raw/{name}/bathymetry.nc",
            "download": f"results/raw/{name}/download",
            "product": f"results/product/{name}/{variant}/product.nc",
            "metadata": f"results/product/{name}/{variant}/metadata.json",
            "grid": f"results/exports/{name}/{variant}/grid.npz"}


def _build(cfg: dict, variant: str, key: str, inputs: list[dict], entry: Path, locked: bool,
           source: str, where: str) -> None:
    """Build the grid into a temporary folder beside ``entry`` and rename it into place
    (called under the entry's lock when ``locked``)."""
    from ..config import validate_data_config
    from .exports import export_grid
    from ..io import sha256_file, write_json_atomic
    from .build import build_product
    from ..sources import fetch_bathymetry, fetch_currents

    checked = validate_data_config(copy.deepcopy(cfg), where)
    if checked != cfg:                        # pragma: no cover - a schema-filling mismatch
        raise RuntimeError(f"{where}: the cache key's configuration differs from the "
                           "validated one")
    name = cfg["region"]["name"]
    folder = entry.parent
    if locked:                                # only a killed build leaves one behind
        for stale in folder.glob(f".{entry.name}.build-*"):
            shutil.rmtree(stale, ignore_errors=True)
    old = entry if entry.exists() else None
    t0 = time.perf_counter()
    log.info("building the %s grid of %s into %s", variant, where, entry)
    stage = Path(tempfile.mkdtemp(prefix=f".{entry.name}.build-", dir=folder))
    try:
        work, out = stage / "work", stage / "out"
        out.mkdir()
        p = {k: _BuildPath(work, v) for k, v in _workflow_paths(name, variant).items()}
        section = lambda *keys: {k: cfg[k] for k in keys}   # noqa: E731
        fetch_currents(section(*_FETCH_CURRENTS), p["currents"], p["download"])
        fetch_bathymetry(section(*_FETCH_BATHYMETRY), p["bathymetry"], p["download"])
        build_product(p["currents"], p["bathymetry"], section(*_SECTIONS), variant,
                      p["product"], p["metadata"])
        export_grid(p["product"], out / "grid.npz", {"region": name, "variant": variant})
        shutil.rmtree(work)
        grid = out / "grid.npz"
        meta = _grid_meta(grid)
        write_json_atomic(out / "grid.json", {
            "format": _FORMAT,
            "grid": "grid.npz",
            "sha256": sha256_file(grid),
            "bytes": grid.stat().st_size,
            "key": key,
            "region": name,
            "variant": variant,
            "config_source": source,
            "config": _snapshot(cfg, variant),
            "config_hash": meta.get("config_hash", ""),
            "inputs": inputs,
            "oneocean_version": __version__,
            "code_sha256": _code_hash(),
            "built": {
                "steps": list(_STEPS),
                "workflow_paths": _workflow_paths(name, variant),
                "seconds": round(time.perf_counter() - t0, 2),
                "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "python": platform.python_version(),
                "packages": _packages(),
            },
        })
        if old is not None:                   # an invalid entry: move it aside first
            with contextlib.suppress(FileNotFoundError):
                os.replace(old, stage / "old")
        try:
            os.replace(out, entry)
        except OSError:
            if not _valid(entry, key):        # (unlocked) another build won: keep it
                raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    log.info("built %s in %.1f s", entry / "grid.npz", time.perf_counter() - t0)


def _grid_meta(path: Path) -> dict:
    import numpy as np

    with np.load(path, allow_pickle=False) as z:
        return json.loads(str(z["meta_json"]))


def _packages() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in ("numpy", "xarray", "dask", "netCDF4", "h5py"):
        with contextlib.suppress(PackageNotFoundError):
            out[name] = version(name)
    return out


# ------------------------------------------------------------------------------ resolve_grid

def _hint(path: Path) -> str:
    """How to build a grid export like ``path`` (a workflow target), or use the default."""
    parts = path.parts
    if (len(parts) >= 5 and parts[-5:-3] == ("results", "exports")
            and parts[-1] in ("grid.npz", "grid.zarr")):
        region, variant = parts[-3], parts[-2]
        extra = ("" if region == "synthetic_coast"
                 else f" --configfile config/regions/{region}.yaml")
        if parts[-1] == "grid.zarr":
            extra += " --config 'exports={\"format\": \"zarr\"}'"
        build = (f"build it in the workflow's checkout with `snakemake --cores 2 "
                 f"results/exports/{region}/{variant}/{parts[-1]}{extra}`")
    else:
        build = ("build one with the workflow (`snakemake --cores 2 exports` writes "
                 "results/exports/<region>/<variant>/grid.npz)")
    return f"{build}, or pass grid=None for the default region"


def resolve_grid(grid=None, *, variant: str = DEFAULT_VARIANT):
    """What an env is given, as a :class:`~oneocean.engine.grid.Grid`.

    ``grid`` is one of

    * None: the default region's grid (:func:`default_grid_path` of ``variant``);
    * a :class:`~oneocean.engine.grid.Grid`: returned as it is;
    * a mapping with the grid export's keys (e.g. :func:`oneocean.testing.make_test_grid`);
    * a path to a grid export ``.npz`` or ``.zarr`` store (contracts §3): loaded;
    * a path to a region config ``.yaml``/``.yml`` (like ``config/regions/<region>.yaml``):
      that region's ``variant`` grid, built into the cache like the default
      (:func:`region_grid_path`; synthetic or local-file sources only).

    Parameters
    ----------
    grid : None, Grid, Mapping, str or os.PathLike, optional
        The grid source, one of the above.
    variant : str, default "scene"
        The product variant (``tiny``, ``scene`` or ``public``) of a grid built from a region
        config (``grid`` None or a ``.yaml`` path).

    Returns
    -------
    Grid
        The loaded grid (:func:`oneocean.engine.grid.load_grid`).

    Raises
    ------
    DataError
        A missing or malformed grid export, a missing input file (one line naming the path,
        the problem and how to build it).
    ConfigError
        A path of another kind, a bad region config, a region that needs the network.
    """
    from collections.abc import Mapping

    from ..engine.grid import Grid, load_grid

    if grid is None:
        return load_grid(default_grid_path(variant))
    if isinstance(grid, Grid):
        return grid
    if isinstance(grid, Mapping):
        return load_grid(grid)
    if not isinstance(grid, (str, os.PathLike)):
        raise ConfigError(f"grid: expected None, a Grid, a grid export (.npz) or a region "
                          f"config (.yaml), got {type(grid).__name__}")
    path = Path(os.fspath(grid)).expanduser()
    suffix = path.suffix.lower()
    kinds = ("a grid export (.npz or .zarr), a region config (.yaml), or None for the "
             "default region")
    if suffix == ".zarr":
        if not path.exists():
            raise DataError(f"{path}: grid export not found; {_hint(path)}")
        try:
            return load_grid(path)
        except DataError as exc:
            raise DataError(f"{exc}; {_hint(path)}") from None
    if path.is_dir():
        raise DataError(f"{path}: is a folder; pass {kinds}")
    if suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise DataError(f"{path}: region config not found; pass a region config such as "
                            "config/regions/synthetic_coast.yaml, or grid=None for the "
                            "default region")
        return load_grid(region_grid_path(path, variant))
    if suffix != ".npz":
        what = f"suffix {path.suffix!r}" if path.suffix else "no suffix"
        raise ConfigError(f"{path}: not a grid source ({what}); pass {kinds}")
    if not path.is_file():
        raise DataError(f"{path}: grid export not found; {_hint(path)}")
    if not zipfile.is_zipfile(path):
        raise DataError(f"{path}: not a grid export (not an .npz archive); {_hint(path)}")
    try:
        return load_grid(path)
    except DataError as exc:
        raise DataError(f"{exc}; {_hint(path)}") from None
