"""Merge canonical currents, tides and bathymetry onto one regular grid per dataset variant.

The product (contracts §2) is a CF-1.11 NetCDF file (or, with ``product.format: zarr``, a zarr
store with the same variables and attributes; :mod:`oneocean.product.zarrio`) with ``u, v`` (time,
depth, latitude, longitude), optional ``u_tide, v_tide`` (time, latitude, longitude),
``elevation``, ``land_mask``, ``current_mask`` and ``valid_mask``, written atomically, chunk by
chunk (one time step at a time), with no write-time attributes so two runs give byte-identical
files.
The computation runs on dask's threads scheduler, or on a ``dask.distributed`` cluster given by
``product.scheduler`` (its address); both give the same bytes.

Regridding rule (NaN-aware bilinear, "normalised convolution")
-----------------------------------------------------------------
For each target node the four surrounding source nodes get their bilinear weights ``w_k``
(summing to 1). A source node is *valid* when its value is finite at every time step of the
variant window (the all-time mask, so the product's validity does not change with time). The
interpolated value is ``sum(w_k * valid_k * f_k) / sum(w_k * valid_k)`` when the valid weight
``sum(w_k * valid_k) >= 0.5`` and NaN otherwise. Where all four nodes are valid this is exact
bilinear interpolation (it reproduces linear fields); next to land it extends the wet field by at
most half a source cell instead of smearing NaN one cell into the water. Currents are then
masked (NaN) where the product's bathymetry says land (``elevation >= 0``) or the depth level is
deeper than the local water depth, so no current is invented on land or below the seafloor.
Target nodes may lie up to half a source cell outside the outermost source nodes (the area
covered by cell-centred grids); they take the edge values.

Masks: ``land_mask`` comes from the bathymetry only (``elevation >= 0``); ``current_mask``
marks the nodes whose column has a current at one level or more (``any(valid_mask)``). Water
with ``current_mask == 0`` (e.g. outside a CMEMS subset polygon, or shallower than the first
level) is water without currents, not land.
"""

from __future__ import annotations

import contextlib
import json
import warnings
from functools import partial

import dask
import dask.array as da
import numpy as np
import xarray as xr

from .. import __version__
from ..errors import ConfigError, DataError
from ..io import atomic_path, canonical_json, config_hash, dataset_content_hash
from ..io import write_json_atomic
from .ncio import netcdf_chunk_cache, netcdf_encoding, write_netcdf_atomic
from .zarrio import ZARR_SUFFIX, atomic_dir, is_zarr, open_product, sha256_path, write_zarr
from .zarrio import zarr_encoding
from ..sources import open_bathymetry, open_currents
from ..sources.base import validate
from ..vocab import CF

__all__ = ["build_product", "summarise_product", "variant_grid", "bilinear_plan",
           "regrid_bilinear", "bilinear_weight", "netcdf_encoding", "write_netcdf_atomic",
           "product_config", "netcdf_chunk_cache", "product_options", "compute_scheduler",
           "open_product"]

_DIMS4 = ("time", "depth", "latitude", "longitude")
_DIMS3 = ("time", "latitude", "longitude")
_DIMS2 = ("latitude", "longitude")
_MIN_WEIGHT = 0.5
def _axis(lo: float, hi: float, res: float) -> np.ndarray:
    """Regular nodes at spacing ``res`` centred in [lo, hi] (float64, ascending)."""
    n = int(np.floor((hi - lo) / res + 1e-9)) + 1
    start = lo + 0.5 * ((hi - lo) - (n - 1) * res)
    return np.round(start + res * np.arange(n), 10)


def variant_grid(bbox: dict, variant_cfg: dict) -> dict:
    """Extent and grid nodes of a variant.

    Parameters
    ----------
    bbox : dict
        Region ``west, east, south, north`` (degrees, −180..180, west < east).
    variant_cfg : dict
        ``extent_fraction`` (0 < f <= 1, centred) and ``resolution_deg``.

    Returns
    -------
    dict
        ``west, east, south, north`` (float, the kept extent), ``resolution_deg``,
        ``longitude`` (nx,) and ``latitude`` (ny,) float64 ascending nodes, centred in the extent.

    Raises
    ------
    ConfigError
        ``extent_fraction`` outside (0, 1], or ``resolution_deg`` not positive.
    """
    f, res = float(variant_cfg["extent_fraction"]), float(variant_cfg["resolution_deg"])
    if not 0.0 < f <= 1.0:
        raise ConfigError(f"variants.extent_fraction: must be in (0, 1], got {f}")
    if res <= 0.0:
        raise ConfigError(f"variants.resolution_deg: must be > 0, got {res}")
    west, east, south, north = (float(bbox[k]) for k in ("west", "east", "south", "north"))
    cx, cy = 0.5 * (west + east), 0.5 * (south + north)
    hw, hh = 0.5 * f * (east - west), 0.5 * f * (north - south)
    ext = {"west": round(cx - hw, 10), "east": round(cx + hw, 10),
           "south": round(cy - hh, 10), "north": round(cy + hh, 10)}
    return {**ext, "resolution_deg": res,
            "longitude": _axis(ext["west"], ext["east"], res),
            "latitude": _axis(ext["south"], ext["north"], res)}


def bilinear_plan(src: np.ndarray, dst: np.ndarray, what: str = "axis") -> tuple:
    """Bracketing indices and weights of ``dst`` nodes on an ascending ``src`` axis.

    Parameters
    ----------
    src : (n,) float64
        Source node coordinates, ascending (e.g. degrees).
    dst : (m,) float64
        Target node coordinates, same units.
    what : str, default "axis"
        Names the file/axis in the error message.

    Returns
    -------
    i0, i1 : (m,) int64
        Left/right source indices (equal when ``n == 1``).
    w : (m,) float64
        Weight of ``i1`` in [0, 1] (``1 - w`` for ``i0``).

    Raises
    ------
    DataError
        If a target lies more than half a source cell outside ``src``.
    """
    src, dst = np.asarray(src, float), np.asarray(dst, float)
    n = src.size
    if n == 1:
        if np.any(np.abs(dst - src[0]) > 1e-9):
            raise DataError(f"{what}: a single source node at {src[0]} cannot cover "
                            f"[{dst.min()}, {dst.max()}]")
        z = np.zeros(dst.size, np.int64)
        return z, z, np.zeros(dst.size)
    lo = src[0] - 0.5 * (src[1] - src[0]) - 1e-9
    hi = src[-1] + 0.5 * (src[-1] - src[-2]) + 1e-9
    if dst.min() < lo or dst.max() > hi:
        raise DataError(f"{what}: requested [{dst.min():.6g}, {dst.max():.6g}] lies outside the "
                        f"data [{src[0]:.6g}, {src[-1]:.6g}]")
    i0 = np.clip(np.searchsorted(src, dst, side="right") - 1, 0, n - 2)
    w = np.clip((dst - src[i0]) / (src[i0 + 1] - src[i0]), 0.0, 1.0)
    return i0.astype(np.int64), (i0 + 1).astype(np.int64), w


def _lerp(a: np.ndarray, plan_y: tuple, plan_x: tuple) -> np.ndarray:
    """Separable bilinear interpolation of the last two axes of ``a`` (no NaN handling)."""
    j0, j1, wy = plan_y
    i0, i1, wx = plan_x
    ax = a[..., i0] * (1.0 - wx) + a[..., i1] * wx
    return ax[..., j0, :] * (1.0 - wy)[:, None] + ax[..., j1, :] * wy[:, None]


def bilinear_weight(valid: np.ndarray, plan_y: tuple, plan_x: tuple) -> np.ndarray:
    """Bilinear weight carried by valid source nodes.

    Parameters
    ----------
    valid : (..., ny_src, nx_src) bool
        Which source nodes are valid.
    plan_y, plan_x : tuple
        :func:`bilinear_plan` results for the latitude and longitude axes.

    Returns
    -------
    (..., ny, nx) float64
        Sum of the bilinear weights of the valid surrounding source nodes, in [0, 1].
    """
    return _lerp(np.asarray(valid, np.float64), plan_y, plan_x)


def regrid_bilinear(field: np.ndarray, valid: np.ndarray, plan_y: tuple, plan_x: tuple,
                    min_weight: float = _MIN_WEIGHT, weight: np.ndarray | None = None
                    ) -> np.ndarray:
    """NaN-aware bilinear regridding of the last two axes (see the module docstring).

    Parameters
    ----------
    field : (..., ny_src, nx_src) float
        Source values; entries where ``valid`` is False are ignored (may be NaN).
    valid : (..., ny_src, nx_src) bool
        Which source nodes are valid; broadcastable to ``field``.
    plan_y, plan_x : tuple
        :func:`bilinear_plan` results for the latitude and longitude axes.
    min_weight : float, default 0.5
        Minimum valid bilinear weight for a defined result.
    weight : (..., ny, nx) float64, optional
        Precomputed :func:`bilinear_weight` of ``valid`` (saves work when ``valid`` is reused).

    Returns
    -------
    (..., ny, nx) float64
        Interpolated values, NaN where the valid weight is below ``min_weight``.
    """
    f = np.where(valid, field, 0.0).astype(np.float64, copy=False)
    num = _lerp(f, plan_y, plan_x)
    den = bilinear_weight(valid, plan_y, plan_x) if weight is None else weight
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den >= min_weight - 1e-12, num / den, np.nan)


def _regrid_block(block, *, valid, weight, plan_y, plan_x, keep):
    """dask block: regrid (nt, [nz,] ny_src, nx_src) → float32, NaN where not ``keep``."""
    out = regrid_bilinear(block, valid, plan_y, plan_x, weight=weight)
    return np.where(keep, out, np.nan).astype(np.float32)


# --- NetCDF writing --------------------------------------------------------------------------

def _open_input(path, kind: str) -> xr.Dataset:
    """Open a canonical input lazily, one time step per dask chunk.

    The readers validate the file first (a DataError naming it otherwise). A file already in the
    canonical layout (the fetch stage's output) is then read directly with whole
    (depth, latitude, longitude) chunks, about twice as fast as the readers' per-level chunks;
    anything else goes through the readers' normalisation.
    """
    ds = open_currents(path) if kind == "currents" else open_bathymetry(path)
    whole = {"depth": -1, "latitude": -1, "longitude": -1}
    try:
        with warnings.catch_warnings():   # "chunks separate the stored chunks": intended
            warnings.simplefilter("ignore", UserWarning)
            raw = xr.open_dataset(path, engine="netcdf4", cache=False,
                                  chunks={"time": 1, **whole} if kind == "currents" else {})
        validate(raw, str(path), kind)
    except (DataError, OSError, ValueError):
        return ds
    if any(raw[n].dtype != ds[n].dtype for n in ds.data_vars if n in raw):
        return ds
    raw.attrs = dict(ds.attrs)
    return raw


def _source_files(ds: xr.Dataset, path) -> list:
    raw = ds.attrs.get("source_files", "[]")
    try:
        files = json.loads(raw) if isinstance(raw, str) else list(raw)
    except json.JSONDecodeError:
        raise DataError(f"{path}: attribute source_files is not JSON") from None
    return [{"path": str(f["path"]), "sha256": str(f["sha256"])} for f in files]


def product_config(cfg: dict, variant: str) -> dict:
    """The part of the config a variant's product depends on (hashed into ``config_hash``).

    Parameters
    ----------
    cfg : dict
        The config (or a region's configuration, :func:`oneocean.product.defaults.region_config`).
    variant : str
        A key of ``cfg["variants"]``.

    Returns
    -------
    dict
        ``region``, ``sources``, ``synthetic``, ``cmems``, ``gebco``, ``etopo``, ``files``
        (those present in ``cfg``, not copied) and ``variant``: the variant's block with its
        ``name``.
    """
    keys = ("region", "sources", "synthetic", "cmems", "gebco", "etopo", "files")
    snap = {k: cfg[k] for k in keys if k in cfg}
    snap["variant"] = {"name": variant, **cfg["variants"][variant]}
    return snap


def product_options(cfg: dict) -> dict:
    """The config's ``product`` block with its defaults.

    Parameters
    ----------
    cfg : dict
        The config; a missing or empty ``product`` block gives the defaults.

    Returns
    -------
    dict
        A new dict: ``format`` (``"netcdf"``, the default, or ``"zarr"``) and ``scheduler`` (a
        ``dask.distributed`` scheduler address, or None, also for a blank one, for local
        threads), with any other keys of the block.

    Raises
    ------
    ConfigError
        ``product.format`` is neither ``netcdf`` nor ``zarr``.
    """
    opts = {"format": "netcdf", "scheduler": None, **(cfg.get("product") or {})}
    if opts["format"] not in ("netcdf", "zarr"):
        raise ConfigError(f"product.format: Invalid value {opts['format']!r}. Valid options "
                          "are (netcdf, zarr)")
    if opts["scheduler"] is not None and not str(opts["scheduler"]).strip():
        opts["scheduler"] = None
    return opts


@contextlib.contextmanager
def compute_scheduler(address: str | None = None):
    """Run dask computations inside the block on local threads or a ``dask.distributed`` cluster.

    The client is closed on exit; the cluster is left running. Its workers must see the
    product's input and output paths (a zarr product's chunks are written by the workers).
    While the client is connected, the workers open NetCDF files with the small HDF5 chunk
    cache of :func:`~oneocean.product.ncio.netcdf_chunk_cache` (a worker plugin, removed on exit), so a
    worker's memory does not grow with the time steps it reads.

    Parameters
    ----------
    address : str, optional
        The scheduler's address (e.g. ``tcp://host:8786``); None or empty: local threads.

    Yields
    ------
    distributed.Client or None
        The connected client (the default client inside the block), or None on threads.

    Raises
    ------
    ConfigError
        ``distributed`` is not installed, or no scheduler answers at ``address``.
    """
    if not address:
        with dask.config.set(scheduler="threads"):
            yield None
        return
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError("product.scheduler: the 'distributed' package is not installed "
                          "(pip install 'oneocean[distributed]')") from None
    try:
        client = Client(address, timeout="20s", set_as_default=True)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise ConfigError(f"product.scheduler: cannot connect to {address} ({reason})") \
            from None
    with client:
        plugin = _worker_chunk_cache_plugin()
        client.register_plugin(plugin, name=plugin.name)
        try:
            yield client
        finally:
            with contextlib.suppress(Exception):     # a cluster gone already: nothing to undo
                client.unregister_worker_plugin(plugin.name)


def _worker_chunk_cache_plugin(size_bytes: int | None = None):
    """A ``distributed`` worker plugin that gives the workers the small HDF5 chunk cache of
    :func:`netcdf_chunk_cache` while the client is connected (restored on teardown).

    The inputs are opened and read inside the workers, where netCDF4's default cache (64 MiB per
    variable and open file) is kept for the worker's lifetime: it grows with every time step
    read until u and v hold ~130 MB more per worker, beyond a small worker's pause threshold
    (80 % of its limit). That memory is unmanaged (dask cannot spill it), so the paused
    workers never resume and the build stalls.
    """
    from distributed import WorkerPlugin

    from .ncio import _CHUNK_CACHE_BYTES

    size = int(_CHUNK_CACHE_BYTES if size_bytes is None else size_bytes)

    class NetCDFChunkCache(WorkerPlugin):
        name = "oneocean-netcdf-chunk-cache"

        def setup(self, worker):
            import netCDF4

            self.old = netCDF4.get_chunk_cache()
            netCDF4.set_chunk_cache(size, self.old[1], self.old[2])

        def teardown(self, worker):
            import netCDF4

            if getattr(self, "old", None):
                netCDF4.set_chunk_cache(*self.old)

    return NetCDFChunkCache()


def _parse_time(value) -> np.datetime64:
    return np.datetime64(str(value).replace("Z", ""), "ns")


def _select(cur: xr.Dataset, cfg: dict, vcfg: dict, path) -> dict:
    """Time steps in [region start, start + hours] and depth levels <= the variant's max depth.

    Returns ``{"time": index array, "depth": index array, "window": (start, end)}``; raises
    DataError if either selection is empty.
    """
    start = _parse_time(cfg["region"]["time"]["start"])
    end = start + np.timedelta64(int(round(float(vcfg["hours"]) * 3600e9)), "ns")
    times = cur["time"].values.astype("datetime64[ns]")
    keep_t = np.flatnonzero((times >= start) & (times <= end))
    if keep_t.size == 0:
        raise DataError(f"{path}: no time step in the variant window [{start}, {end}] "
                        f"(data cover {times.min()} .. {times.max()})")
    max_depth = min(float(vcfg["max_depth_m"]), float(cfg["region"].get("max_depth_m", np.inf)))
    depth = np.asarray(cur["depth"].values, float)
    keep_z = np.flatnonzero(depth <= max_depth + 1e-9)
    if keep_z.size == 0:
        raise DataError(f"{path}: no depth level <= {max_depth} m (levels {depth.tolist()})")
    return {"time": keep_t, "depth": keep_z, "window": (start, end)}


def _crop_slices(plan_y, plan_x):
    """Source index slices covering two plans, and the plans shifted into the crop."""
    ys = slice(int(min(plan_y[0].min(), plan_y[1].min())),
               int(max(plan_y[0].max(), plan_y[1].max())) + 1)
    xs = slice(int(min(plan_x[0].min(), plan_x[1].min())),
               int(max(plan_x[0].max(), plan_x[1].max())) + 1)
    shift = lambda p, o: (p[0] - o, p[1] - o, p[2])   # noqa: E731
    return ys, xs, shift(plan_y, ys.start), shift(plan_x, xs.start)


def _plans(ds: xr.Dataset, lat: np.ndarray, lon: np.ndarray, path) -> tuple:
    """Crop slices and bilinear plans of the product grid on ``ds`` (DataError if outside)."""
    py = bilinear_plan(ds["latitude"].values, lat, f"{path}: latitude")
    px = bilinear_plan(ds["longitude"].values, lon, f"{path}: longitude")
    return _crop_slices(py, px)


def _elevation(bat: xr.Dataset, lat: np.ndarray, lon: np.ndarray, path) -> np.ndarray:
    """Bathymetry regridded onto the product grid, (ny, nx) float64 m, positive up."""
    ys, xs, py, px = _plans(bat, lat, lon, path)
    src = np.asarray(bat["elevation"].isel(latitude=ys, longitude=xs).values, float)
    elev = regrid_bilinear(src, np.isfinite(src), py, px)
    if np.isnan(elev).any():
        raise DataError(f"{path}: elevation has no data over part of the variant extent")
    return elev


def _all_time_valid(src: dict, has_tide: bool) -> tuple:
    """Pass 1: source nodes finite at every time, (nz, ny_s, nx_s) and (ny_s, nx_s) bool."""
    ok_uv = da.all(da.isfinite(src["u"]) & da.isfinite(src["v"]), axis=0)
    ok_tide = (da.all(da.isfinite(src["u_tide"]) & da.isfinite(src["v_tide"]), axis=0)
               if has_tide else None)
    return dask.compute(ok_uv, ok_tide)


# --- the product ---------------------------------------------------------------------------

def _var_attrs(name: str) -> dict:
    if name in ("u", "v", "u_tide", "v_tide"):
        what = "eastward" if name.startswith("u") else "northward"
        tide = " due to tides" if name.endswith("_tide") else " (ocean circulation, no tide)"
        return {"standard_name": CF[name], "long_name": f"{what} sea water velocity{tide}",
                "units": "m s-1"}
    if name == "elevation":
        return {"standard_name": CF[name], "long_name": "height above mean sea level "
                "(negative = water depth)", "units": "m", "positive": "up"}
    if name == "land_mask":
        return {"standard_name": CF[name], "long_name": "land from the bathymetry "
                "(elevation >= 0)", "units": "1", "flag_values": np.array([0, 1], np.int8),
                "flag_meanings": "water land"}
    if name == "current_mask":
        return {"standard_name": CF.get(name, "status_flag"),
                "long_name": "water column with currents defined at one depth level or more",
                "units": "1", "flag_values": np.array([0, 1], np.int8),
                "flag_meanings": "no_current current_defined"}
    return {"standard_name": CF[name], "long_name": "water with currents defined at all times",
            "units": "1", "flag_values": np.array([0, 1], np.int8),
            "flag_meanings": "invalid valid"}


_COORD_ATTRS = {
    "time": {"standard_name": "time", "long_name": "time", "axis": "T"},
    "depth": {"standard_name": "depth", "long_name": "depth below sea surface", "units": "m",
              "positive": "down", "axis": "Z"},
    "latitude": {"standard_name": "latitude", "long_name": "latitude",
                 "units": "degrees_north", "axis": "Y"},
    "longitude": {"standard_name": "longitude", "long_name": "longitude",
                  "units": "degrees_east", "axis": "X"},
}


def _provenance(cfg: dict, variant: str, cur: xr.Dataset, bat: xr.Dataset, paths: tuple,
                has_tide: bool) -> dict:
    """Global attributes naming the sources, their files and hashes, config and version."""
    kinds = {"currents": str(cur.attrs.get("source", cfg["sources"]["currents"])),
             "bathymetry": str(bat.attrs.get("source", cfg["sources"]["bathymetry"]))}
    kinds["tides"] = kinds["currents"] if has_tide else "none"
    files, seen = [], set()
    for path, ds in zip(paths, (cur, bat)):
        for f in _source_files(ds, path):
            if f["path"] not in seen:
                seen.add(f["path"])
                files.append(f)
    snap = product_config(cfg, variant)
    synthetic = " (SYNTHETIC data, not real observations)" if "synthetic" in kinds.values() \
        else ""
    attrs = {
        "Conventions": "CF-1.11",
        "title": f"OneOcean environment product, region {cfg['region']['name']}, variant "
                 f"{variant}{synthetic}",
        "institution": "OneOcean",
        "source": kinds["currents"],
        "source_currents": kinds["currents"],
        "source_bathymetry": kinds["bathymetry"],
        "source_tides": kinds["tides"],
        "region": str(cfg["region"]["name"]),
        "variant": variant,
        "oneocean_version": __version__,
        "config_hash": config_hash(snap),
        "config": canonical_json(snap).strip(),
        "source_files": json.dumps(files, sort_keys=True),
        "input_files": json.dumps([str(p) for p in paths]),
        "has_tide": np.int8(1 if has_tide else 0),
        "regridding": "NaN-aware bilinear (normalised by the valid weight, >= 0.5); currents "
                      "masked on land and below the seafloor; land_mask from the bathymetry "
                      "only, current_mask = any(valid_mask)",
    }
    for key in ("model_layout", "model_notes", "tide_in_currents"):
        if key in cur.attrs:  # coastal model output (sources.model): its checked assumptions
            attrs[key] = str(cur.attrs[key])
    for key, ds in (("currents", cur), ("bathymetry", bat)):
        if "request" in ds.attrs:
            attrs[f"request_{key}"] = str(ds.attrs["request"])
        for name in ("synthetic_seed", "synthetic_config_hash"):
            if name in ds.attrs:
                attrs[name] = ds.attrs[name]
    return attrs


def _extent_attrs(grid: dict, times: np.ndarray, depth: np.ndarray, window: tuple) -> dict:
    lat, lon = grid["latitude"], grid["longitude"]
    return {
        "resolution_deg": grid["resolution_deg"],
        "geospatial_lat_min": float(lat[0]), "geospatial_lat_max": float(lat[-1]),
        "geospatial_lon_min": float(lon[0]), "geospatial_lon_max": float(lon[-1]),
        "geospatial_vertical_min": float(depth[0]), "geospatial_vertical_max": float(depth[-1]),
        "geospatial_vertical_positive": "down",
        "time_coverage_start": _iso(times[0]), "time_coverage_end": _iso(times[-1]),
        "time_window_requested": f"{_iso(window[0])}/{_iso(window[1])}",
    }


def build_product(currents_path, bathymetry_path, cfg: dict, variant: str, out_path,
                  metadata_path) -> None:
    """Merge the canonical inputs onto one regular grid for ``variant`` (contracts §2).

    Parameters
    ----------
    currents_path : path
        Canonical currents NetCDF: ``u, v`` (time, depth, latitude, longitude) m s-1, optional
        ``u_tide, v_tide`` (time, latitude, longitude); attrs ``source``, ``source_files``.
    bathymetry_path : path
        Canonical bathymetry NetCDF: ``elevation`` (latitude, longitude), m, positive up.
    cfg : dict
        Validated config: ``region`` (name, bbox, time.start, max_depth_m), ``sources.tides``
        and ``variants[variant]`` (extent_fraction, resolution_deg, hours, max_depth_m).
    variant : str
        A key of ``cfg["variants"]``.
    out_path : path
        The product: a NetCDF file, or a zarr store when it ends in ``.zarr`` (written
        atomically, one time step per chunk; byte-identical reruns).
    metadata_path : path
        Per-variant metadata JSON: settings, grid, realised time coverage, depth levels,
        statistics (:func:`summarise_product`), source kinds and the content hash.

    Raises
    ------
    DataError
        The variant's extent, time window or depth range lies outside the inputs, or no valid
        current remains; no file is written.
    ConfigError
        ``variant`` is not in ``cfg["variants"]``, ``product.format`` is invalid, or
        ``product.scheduler`` is set but ``distributed`` is missing or the scheduler does not
        answer.

    Notes
    -----
    The dask scheduler is ``cfg["product"]["scheduler"]`` (:func:`compute_scheduler`).
    """
    opts = product_options(cfg)
    with netcdf_chunk_cache(), compute_scheduler(opts["scheduler"]):
        _build(currents_path, bathymetry_path, cfg, variant, out_path, metadata_path)


def _build(currents_path, bathymetry_path, cfg, variant, out_path, metadata_path) -> None:
    if variant not in cfg.get("variants", {}):
        raise ConfigError(f"variants.{variant}: not defined in the config")
    vcfg = cfg["variants"][variant]
    grid = variant_grid(cfg["region"]["bbox"], vcfg)
    lat, lon = grid["latitude"], grid["longitude"]
    cur = _open_input(currents_path, "currents")
    bat = _open_input(bathymetry_path, "bathymetry")
    sel = _select(cur, cfg, vcfg, currents_path)
    ys, xs, py, px = _plans(cur, lat, lon, currents_path)
    elev = _elevation(bat, lat, lon, bathymetry_path)

    has_tide = (bool(cfg.get("sources", {}).get("tides", True))
                and "u_tide" in cur.data_vars and "v_tide" in cur.data_vars)
    names = ["u", "v"] + (["u_tide", "v_tide"] if has_tide else [])
    sub = cur[names].isel(time=sel["time"], depth=sel["depth"], latitude=ys, longitude=xs)
    times = sub["time"].values.astype("datetime64[ns]")
    depth = np.asarray(sub["depth"].values, float)
    src = {n: sub[n].chunk({d: (1 if d == "time" else -1) for d in sub[n].dims}).data
           for n in names}

    ok_uv, ok_tide = _all_time_valid(src, has_tide)
    w_uv = bilinear_weight(ok_uv, py, px)
    valid = ((w_uv >= _MIN_WEIGHT - 1e-12) & (elev < 0.0)[None]
             & (depth[:, None, None] <= -elev[None] + 1e-9))
    if not valid.any():
        raise DataError(f"{currents_path}: no valid (finite, wet) current in the variant "
                        "extent and window")
    land = elev >= 0.0
    current = valid.any(axis=0)

    # the per-node arrays every block needs are graph keys of their own (delayed), so a
    # distributed scheduler ships them to each worker once, not with every task
    shared = {"uv": dict(valid=ok_uv, weight=w_uv, keep=valid)}
    if has_tide:
        shared["tide"] = dict(valid=ok_tide, weight=bilinear_weight(ok_tide, py, px), keep=~land)
    shared = {k: {n: dask.delayed(a, pure=True) for n, a in v.items()} for k, v in shared.items()}
    data = {}
    for n in names:
        uv = n in ("u", "v")
        fn = partial(_regrid_block, plan_y=py, plan_x=px)
        plane = ((depth.size,) if uv else ()) + (lat.size, lon.size)
        chunks = ((1,) * times.size,) + tuple((s,) for s in plane)
        data[n] = (_DIMS4 if uv else _DIMS3,
                   da.map_blocks(fn, src[n], dtype=np.float32, chunks=chunks,
                                 **shared["uv" if uv else "tide"]), _var_attrs(n))
    data["elevation"] = (_DIMS2, elev.astype(np.float32), _var_attrs("elevation"))
    data["land_mask"] = (_DIMS2, land.astype(np.int8), _var_attrs("land_mask"))
    data["current_mask"] = (_DIMS2, current.astype(np.int8), _var_attrs("current_mask"))
    data["valid_mask"] = (("depth",) + _DIMS2, valid.astype(np.int8), _var_attrs("valid_mask"))
    coords = {"time": times, "depth": depth, "latitude": lat, "longitude": lon}
    attrs = {**_provenance(cfg, variant, cur, bat, (currents_path, bathymetry_path), has_tide),
             **_extent_attrs(grid, times, depth, sel["window"])}
    product = xr.Dataset(data, coords={k: (k, v, _COORD_ATTRS[k]) for k, v in coords.items()},
                         attrs=attrs)

    zarr = is_zarr(out_path)
    with (atomic_dir(out_path, suffix=ZARR_SUFFIX) if zarr
          else atomic_path(out_path, suffix=".nc")) as tmp:
        if zarr:
            write_zarr(product, tmp, zarr_encoding(product, netcdf_encoding(product)))
        else:
            write_netcdf_atomic(product, tmp, netcdf_encoding(product))
        with open_product(tmp) as written:
            content = dataset_content_hash(written)
        meta = {
            "region": attrs["region"], "variant": variant,
            "product": {"path": str(out_path), "sha256": sha256_path(tmp),
                        "content_hash": content},
            "settings": {"variant": dict(vcfg), "region": cfg["region"],
                         "sources": cfg.get("sources", {})},
            "config_hash": attrs["config_hash"],
            "grid": {"nt": int(times.size), "nz": int(depth.size), "ny": int(lat.size),
                     "nx": int(lon.size), "resolution_deg": grid["resolution_deg"],
                     "extent": {k: grid[k] for k in ("west", "east", "south", "north")}},
            "time_coverage": {"start": _iso(times[0]), "end": _iso(times[-1]),
                              "count": int(times.size),
                              "requested": [_iso(t) for t in sel["window"]]},
            "depth_levels_m": depth.tolist(),
            "source_kinds": {"currents": attrs["source_currents"],
                             "bathymetry": attrs["source_bathymetry"],
                             "tides": attrs["source_tides"]},
            "source_files": json.loads(attrs["source_files"]),
            "oneocean_version": __version__,
            "summary": summarise_product(tmp),
        }
        write_json_atomic(metadata_path, meta)


def _iso(t) -> str:
    return str(np.datetime_as_string(np.datetime64(t, "s"), unit="s"))


def summarise_product(path) -> dict:
    """Headline numbers of a product, streamed one time step at a time.

    Parameters
    ----------
    path : str or os.PathLike
        The product (NetCDF file or zarr store, :func:`open_product`).

    Returns
    -------
    dict
        ``region``, ``variant``, ``source`` (+ ``source_currents``, ``source_bathymetry``),
        ``has_tide``; ``extent`` {west, east, south, north} (outer grid nodes, degrees);
        ``ny, nx, nt, nz``; ``resolution_deg``; ``time_start``, ``time_end`` (ISO, UTC),
        ``n_times``; ``depths_m``, ``n_depths``; at the surface level (depth index 0), over valid
        water and all times: ``mean_speed_ms``, ``max_speed_ms`` (ocean currents, no tide),
        ``max_tide_speed_ms`` and ``max_total_speed_ms`` (currents + tide; equals
        ``max_speed_ms`` without tide); ``ocean_fraction`` (share of nodes with
        ``land_mask == 0``); ``current_fraction`` (share of nodes with currents,
        ``current_mask == 1``; water without currents = ocean - current fraction).
    """
    with netcdf_chunk_cache(), open_product(path) as ds:
        lat, lon = ds["latitude"].values, ds["longitude"].values
        times = ds["time"].values
        has_tide = int(ds.attrs.get("has_tide", 0)) == 1
        ssum, scount, smax, tmax, totmax = 0.0, 0, 0.0, 0.0, 0.0
        for k in range(times.size):
            u = ds["u"][k, 0].values.astype(float)
            v = ds["v"][k, 0].values.astype(float)
            sp = np.hypot(u, v)
            ok = np.isfinite(sp)
            ssum += float(sp[ok].sum())
            scount += int(ok.sum())
            smax = max(smax, float(sp[ok].max(initial=0.0)))
            if has_tide:
                ut = ds["u_tide"][k].values.astype(float)
                vt = ds["v_tide"][k].values.astype(float)
                tmax = max(tmax, float(np.nanmax(np.hypot(ut, vt), initial=0.0)))
                tot = np.hypot(u + ut, v + vt)
                totmax = max(totmax, float(tot[np.isfinite(tot)].max(initial=0.0)))
        if not has_tide:
            totmax = smax
        land = ds["land_mask"].values
        current = (ds["current_mask"].values if "current_mask" in ds
                   else ds["valid_mask"].values.any(axis=0))
        res = float(ds.attrs.get("resolution_deg",
                                 lon[1] - lon[0] if lon.size > 1 else np.nan))
        return {
            "region": str(ds.attrs.get("region", "")), "variant": str(ds.attrs.get("variant", "")),
            "source": str(ds.attrs.get("source", "")),
            "source_currents": str(ds.attrs.get("source_currents", "")),
            "source_bathymetry": str(ds.attrs.get("source_bathymetry", "")),
            "has_tide": has_tide,
            "extent": {"west": float(lon[0]), "east": float(lon[-1]),
                       "south": float(lat[0]), "north": float(lat[-1])},
            "ny": int(lat.size), "nx": int(lon.size), "nt": int(times.size),
            "nz": int(ds.sizes["depth"]), "resolution_deg": res,
            "time_start": _iso(times[0]), "time_end": _iso(times[-1]),
            "n_times": int(times.size),
            "depths_m": [float(d) for d in ds["depth"].values],
            "n_depths": int(ds.sizes["depth"]),
            "mean_speed_ms": ssum / scount if scount else None,
            "max_speed_ms": smax, "max_tide_speed_ms": tmax, "max_total_speed_ms": totmax,
            "ocean_fraction": float(np.mean(land == 0)),
            "current_fraction": float(np.mean(current != 0)),
        }
