"""Figures of the product. Fig. 3: the current field over bathymetry.

Rendered with matplotlib's Agg canvas (no pyplot state) and written as PNG with fixed metadata,
so the same product gives the same bytes.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .errors import DataError
from .io import atomic_path

__all__ = ["plot_current_field"]

_MAX_SURFACE_NODES = 90      # per axis, for plot_surface
_ARROWS_PER_AXIS = 14
_LAND_RGBA = (0.62, 0.55, 0.45, 1.0)


def _stride(n: int, target: int) -> int:
    return max(1, int(np.ceil(n / target)))


def plot_current_field(product_path, out_png, pitch_deg: float = 25.0,
                       azimuth_deg: float = 45.0, depth_m: float = 0.0) -> None:
    """Draw the paper's Fig. 3 for a product: terrain coloured by current speed, with arrows.

    The terrain (``elevation``, m) is a 3-D surface whose water facets are coloured by the ocean
    current speed ``hypot(u, v)`` (m s-1, no tide) at the depth level nearest ``depth_m`` and the
    first time step; land facets are drawn in a terrain colour. Arrows (subsampled) show the
    current direction at that level, drawn just above the terrain.

    Parameters
    ----------
    product_path : path
        A product NetCDF (contracts §2).
    out_png : path
        Output PNG (written atomically; byte-stable: no software/time metadata).
    pitch_deg, azimuth_deg : float
        View elevation and azimuth (degrees) for ``view_init``.
    depth_m : float
        Depth (m, positive down); the nearest product level is shown.
    """
    import matplotlib
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    import seaborn as sns

    with xr.open_dataset(product_path) as ds:
        depths = ds["depth"].values.astype(float)
        k = int(np.argmin(np.abs(depths - float(depth_m))))
        lat, lon = ds["latitude"].values, ds["longitude"].values
        elev = ds["elevation"].values.astype(float)
        u = ds["u"][0, k].values.astype(float)
        v = ds["v"][0, k].values.astype(float)
        t0 = str(np.datetime_as_string(ds["time"].values[0].astype("datetime64[s]"), unit="s"))
        region, variant = ds.attrs.get("region", ""), ds.attrs.get("variant", "")
        source = ds.attrs.get("source", "")
    speed = np.hypot(u, v)
    if not np.isfinite(speed).any():
        raise DataError(f"{product_path}: no current defined at {depths[k]} m")
    vmax = float(np.nanmax(speed)) or 1.0

    sy, sx = _stride(lat.size, _MAX_SURFACE_NODES), _stride(lon.size, _MAX_SURFACE_NODES)
    LON, LAT = np.meshgrid(lon[::sx], lat[::sy])
    Z = elev[::sy, ::sx]
    sp = speed[::sy, ::sx]
    cmap, norm = colormaps["viridis"], Normalize(0.0, vmax)
    colors = cmap(norm(np.nan_to_num(sp)))
    colors[~np.isfinite(sp)] = _LAND_RGBA

    rc = {"pdf.fonttype": 42, "svg.hashsalt": "oneocean", "figure.dpi": 100}
    with matplotlib.rc_context(rc), sns.plotting_context("paper"):
        fig = Figure(figsize=(7.0, 5.2), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(projection="3d", computed_zorder=False)
        ax.plot_surface(LON, LAT, Z, facecolors=colors, rstride=1, cstride=1, linewidth=0,
                        antialiased=False, shade=False, zorder=1)
        kx = np.cos(np.deg2rad(0.5 * (lat[0] + lat[-1])))
        wx, wy = max(np.ptp(lon) * kx, 1e-9), max(np.ptp(lat), 1e-9)
        ax.set_box_aspect((wx, wy, 0.45 * max(wx, wy)))
        ay, axs = _stride(lat.size, _ARROWS_PER_AXIS), _stride(lon.size, _ARROWS_PER_AXIS)
        qlat, qlon = lat[ay // 2::ay], lon[axs // 2::axs]
        QLON, QLAT = np.meshgrid(qlon, qlat)
        qu, qv = u[ay // 2::ay, axs // 2::axs], v[ay // 2::ay, axs // 2::axs]
        ok = np.isfinite(qu) & np.isfinite(qv)
        if ok.any():
            step = min(axs * (lon[1] - lon[0]) if lon.size > 1 else 1.0,
                       ay * (lat[1] - lat[0]) if lat.size > 1 else 1.0)
            scale = 1.3 * step / vmax
            zq = elev[ay // 2::ay, axs // 2::axs] + 0.02 * (np.ptp(elev) or 1.0)
            ax.quiver(QLON[ok], QLAT[ok], zq[ok], qu[ok] * scale, qv[ok] * scale,
                      np.zeros(ok.sum()), color="white", linewidth=1.2,
                      arrow_length_ratio=0.35, normalize=False, zorder=3)
        ax.view_init(elev=float(pitch_deg), azim=float(azimuth_deg))
        ax.set_xlabel("Longitude (°E)")
        ax.set_ylabel("Latitude (°N)")
        ax.set_zlabel("Elevation (m)")
        ax.set_title(f"{region} / {variant} ({source}): currents at {depths[k]:g} m, {t0} UTC",
                     fontsize="small")
        mappable = ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(mappable, ax=ax, shrink=0.6, pad=0.08, label="Current speed (m s$^{-1}$)")
        with atomic_path(out_png, suffix=".png") as tmp:
            fig.savefig(tmp, format="png", dpi=150, metadata={"Software": None})
