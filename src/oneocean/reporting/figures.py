"""The paper's result figures, in one style.

- Fig. 3 :func:`plot_current_field`: the current field over bathymetry (3-D view + plan view).
- Fig. 4 :func:`plot_pollution_species`: a multi-species reacting pollution field
  (:mod:`oneocean.models.pollution`) at a few times.
- Fig. 6 :func:`plot_ladder`: the task ladder, success rate per tier and the drops between
  tiers.
- Fig. 7 :func:`plot_team_sweep`: the SPC team-size sweep.
- :func:`plot_rl_curves`: the PPO baseline's learning curves (the optional ``rl_baselines``
  target).

Every figure is drawn on matplotlib's Agg canvas (no pyplot state) inside :func:`paper_style`
(fonts, sizes and palette shared by all figures) and written by :func:`save_figure`: PNG and
PDF side by side, each written atomically, with fixed metadata (no software, producer or date),
so the same inputs give the same bytes. The functions are pure: inputs (paths, arrays, a seed)
in, the figure files out; each returns the numbers it plotted.
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataError
from ..io import atomic_path
from ..engine import libm

__all__ = ["paper_style", "style_rc", "new_figure", "save_figure", "palette",
           "plot_current_field", "plot_pollution_species", "plot_ladder", "ladder_numbers",
           "plot_team_sweep", "team_sweep_numbers", "plot_rl_curves", "rl_curve_numbers"]

# ------------------------------------------------------------------------------------------
# the shared style
# ------------------------------------------------------------------------------------------

#: PNG resolution (dots per inch); also the resolution of rasterised layers in the PDF.
DPI = 200
#: Widths (inches) of a single- and a double-column figure.
COLUMN_IN = 3.5
PAGE_IN = 7.2
#: Colour of land in map panels.
LAND_RGBA = (0.80, 0.75, 0.66, 1.0)
#: Colour of water without data (no current defined) in map panels.
NODATA_RGBA = (0.88, 0.88, 0.88, 1.0)
#: Colour map of current speed (Fig. 3).
SPEED_CMAP = "viridis"

_PNG_META = {"Software": None}
_PDF_META = {"Creator": None, "Producer": None, "CreationDate": None}


def palette(n: int | None = None) -> list[tuple[float, float, float]]:
    """The figures' qualitative colours (seaborn ``colorblind``).

    Parameters
    ----------
    n : int, optional
        How many (default: the palette's 10; more repeat it).

    Returns
    -------
    list of tuple of float
        RGB triples in [0, 1].
    """
    import seaborn as sns

    return list(sns.color_palette("colorblind", n))


def style_rc() -> dict:
    """The rcParams every figure is drawn with.

    Seaborn's ``ticks`` style at ``paper`` scale, DejaVu Sans (shipped with matplotlib, so the
    same glyphs everywhere), 8 pt text, the :func:`palette` as colour cycle, TrueType fonts in
    the PDF.

    Returns
    -------
    dict
        The rcParams, for :func:`matplotlib.rc_context`.
    """
    import seaborn as sns
    from cycler import cycler

    rc = {}
    rc.update(sns.axes_style("ticks"))
    rc.update(sns.plotting_context("paper"))
    rc.update({
        "font.family": "sans-serif", "font.sans-serif": ["DejaVu Sans"],
        "font.size": 8.0, "axes.titlesize": 8.5, "axes.labelsize": 8.0,
        "xtick.labelsize": 7.0, "ytick.labelsize": 7.0, "legend.fontsize": 7.0,
        "legend.title_fontsize": 7.0, "figure.titlesize": 9.0,
        "axes.linewidth": 0.6, "xtick.major.width": 0.6, "ytick.major.width": 0.6,
        "xtick.major.size": 3.0, "ytick.major.size": 3.0, "lines.linewidth": 1.2,
        "lines.markersize": 4.0, "errorbar.capsize": 2.0, "patch.linewidth": 0.5,
        "legend.frameon": False, "axes.spines.top": False, "axes.spines.right": False,
        "axes.prop_cycle": cycler(color=palette()), "image.cmap": SPEED_CMAP,
        "figure.dpi": 100, "savefig.dpi": DPI, "pdf.fonttype": 42, "ps.fonttype": 42,
        "svg.hashsalt": "oneocean", "svg.fonttype": "none", "path.simplify": True,
    })
    return rc


@contextlib.contextmanager
def paper_style():
    """Context in which a figure is built and saved (see :func:`style_rc`).

    Yields
    ------
    None
        The body runs with the figures' rcParams.
    """
    import matplotlib

    with matplotlib.rc_context(style_rc()):
        yield


def new_figure(width_in: float, height_in: float, layout: str | None = "constrained"):
    """A matplotlib Figure with its own Agg canvas (no pyplot state).

    Call it inside :func:`paper_style`.

    Parameters
    ----------
    width_in : float
        Width, inches (e.g. :data:`COLUMN_IN`, :data:`PAGE_IN`).
    height_in : float
        Height, inches.
    layout : str or None, default "constrained"
        Matplotlib's layout engine.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(float(width_in), float(height_in)), layout=layout)
    FigureCanvasAgg(fig)
    return fig


def freeze_layout(fig, ndigits: int = 6) -> None:
    """Run the figure's layout engine once, round the positions, and switch the engine off.

    Every axes position (and the figure-level titles) is rounded to ``ndigits`` decimals of
    the figure size. Constrained layout's solver (kiwisolver) orders its variables by memory
    address, so the positions it returns can differ in the last bit from one call to the
    next, depending on what the process allocated before; the PDF writes coordinates with six
    decimals, and a position that falls on a rounding tie then changes the file's bytes.
    Rounded positions take that noise out; the shift is below 1e-6 of the figure size, far
    below a pixel. A figure without a layout engine is left as it is.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    ndigits : int, default 6
        Decimals kept, in figure-size units.
    """
    if fig.get_layout_engine() is None:
        return
    fig.draw_without_rendering()
    for ax in fig.axes:
        ax.set_position([round(v, ndigits) for v in ax.get_position(original=False).bounds],
                        which="both")
    for text in (fig._suptitle, fig._supxlabel, fig._supylabel):
        if text is not None:
            x, y = text.get_position()
            text.set_position((round(x, ndigits), round(y, ndigits)))
    fig.set_layout_engine("none")


def save_figure(fig, out_png) -> tuple[Path, Path]:
    """Write ``fig`` as ``out_png`` and the PDF beside it (same stem).

    Each is written atomically and byte-stable (fixed metadata, frozen layout:
    :func:`freeze_layout`); the PNG at :data:`DPI`.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    out_png : path-like
        The PNG path.

    Returns
    -------
    png, pdf : pathlib.Path
        The two files.
    """
    png = Path(out_png)
    pdf = png.with_suffix(".pdf")
    freeze_layout(fig)
    with atomic_path(png, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=DPI, metadata=_PNG_META)
    with atomic_path(pdf, suffix=".pdf") as tmp:
        fig.savefig(tmp, format="pdf", dpi=DPI, metadata=_PDF_META)
    return png, pdf


def _err(v, lo, hi):
    """Asymmetric error-bar lengths ``[v - lo, hi - v]``, never negative (a Wilson bound at
    0 or 100 % can sit a rounding error past the point)."""
    v, lo, hi = (np.asarray(a, dtype=np.float64) for a in (v, lo, hi))
    return [np.maximum(v - lo, 0.0), np.maximum(hi - v, 0.0)]


def _stride(n: int, target: int) -> int:
    return max(1, int(np.ceil(n / target)))


def _nice_ref(vmax: float) -> float:
    """A round reference value <= vmax (for a quiver key)."""
    if not vmax > 0:
        return 1.0
    e = 10.0 ** math.floor(math.log10(vmax))
    for m in (5.0, 2.5, 2.0, 1.0):
        if m * e <= vmax:
            return m * e
    return e


# ------------------------------------------------------------------------------------------
# Fig. 3: the current field
# ------------------------------------------------------------------------------------------

_MAX_SURFACE_NODES = 90      # per axis, for plot_surface
_ARROWS_3D = 10              # arrows along the longer side, 3-D panel
_ARROWS_MAP = 17             # arrows along the longer side, plan view
_M_PER_DEG = 111_320.0


def _bilinear(grid: np.ndarray, fy: np.ndarray, fx: np.ndarray) -> np.ndarray:
    """``grid`` (ny, nx) at fractional indices (fy, fx), clamped to the grid."""
    ny, nx = grid.shape
    fy = np.clip(fy, 0.0, ny - 1.0)
    fx = np.clip(fx, 0.0, nx - 1.0)
    j0 = np.minimum(np.floor(fy).astype(int), max(ny - 2, 0))
    i0 = np.minimum(np.floor(fx).astype(int), max(nx - 2, 0))
    j1, i1 = np.minimum(j0 + 1, ny - 1), np.minimum(i0 + 1, nx - 1)
    wy, wx = fy - j0, fx - i0
    return ((1 - wy) * ((1 - wx) * grid[j0, i0] + wx * grid[j0, i1])
            + wy * ((1 - wx) * grid[j1, i0] + wx * grid[j1, i1]))


def _arrow_polygons(x, y, dx, dy, length, head_len, head_half, shaft_half):
    """Arrow outlines (n, 7, 2) centred on (x, y), pointing along the unit vectors (dx, dy)."""
    px, py = -dy, dx
    tail, tip = -0.5 * length, 0.5 * length
    neck = tip - head_len
    along = np.stack([tail, neck, neck, tip, neck, neck, tail], axis=1)
    across = np.stack([shaft_half, shaft_half, head_half, np.zeros_like(length), -head_half,
                       -shaft_half, -shaft_half], axis=1)
    X = x[:, None] + along * dx[:, None] + across * px[:, None]
    Y = y[:, None] + along * dy[:, None] + across * py[:, None]
    return np.stack([X, Y], axis=-1)


def _visible(pts, xn, yn, surf, eye, top, step):
    """Which points (n, 3) see the eye past the terrain, in box coordinates.

    ``surf`` (ny, nx) are the rendered terrain heights at the nodes ``xn`` (nx,) x ``yn``
    (ny,); ``eye`` the (orthographic) direction toward the viewer; ``top`` the box's height.
    A point is hidden when the terrain rises above the ray from it toward the eye anywhere
    inside the box (marched in steps of ``step``)."""
    ok = np.ones(len(pts), dtype=bool)
    if eye[2] <= 0:
        return ok
    t_max = (top - pts[:, 2].min()) / eye[2]
    for t in np.arange(step, t_max + step, step):
        q = pts + t * eye
        inside = ((q[:, 0] >= xn[0]) & (q[:, 0] <= xn[-1])
                  & (q[:, 1] >= yn[0]) & (q[:, 1] <= yn[-1]))
        if not inside.any():
            break
        fy = np.interp(q[:, 1], yn, np.arange(yn.size))
        fx = np.interp(q[:, 0], xn, np.arange(xn.size))
        ok &= ~(inside & (_bilinear(surf, fy, fx) > q[:, 2]))
    return ok


def plot_current_field(product_path, out_png, pitch_deg: float = 25.0,
                       azimuth_deg: float = 45.0, depth_m: float = 0.0) -> dict:
    """Draw the paper's Fig. 3 for a product: the current field over the bathymetry.

    Left, a 3-D view (orthographic): the terrain (``elevation``, m, hill-shaded) with its
    water facets coloured by the ocean current speed ``hypot(u, v)`` (m s-1, no tide) at the
    depth level nearest ``depth_m`` and the first time step, land facets in a land colour, and
    flat arrows draped just above the terrain showing the current direction (length grows with
    the speed, heads always visible). An arrow is drawn only if no terrain lies between it and
    the viewer (ray-marched along the view direction), so the terrain occludes arrows behind
    ridges instead of them showing through. Right, the plan view: speed as an image over
    longitude/latitude (land and water without currents masked), bathymetry contours (m), and
    a quiver (length proportional to speed, with a key), sharing the colour bar (m s-1).

    Parameters
    ----------
    product_path : path
        A product NetCDF (contracts §2).
    out_png : path
        Output PNG; the PDF is written beside it (same stem). Both atomically, byte-stable.
    pitch_deg, azimuth_deg : float
        View elevation and azimuth (degrees) of the 3-D panel.
    depth_m : float
        Depth (m, positive down); the nearest product level is shown.

    Returns
    -------
    dict
        ``depth_m`` (the level shown), ``vmax`` (colour scale top, m s-1), ``arrows_3d``
        (arrows drawn in the 3-D panel), ``arrows_hidden`` (arrows culled as occluded),
        ``arrows_map`` (arrows in the plan view), ``png``, ``pdf``.
    """
    import xarray as xr
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LightSource, ListedColormap, Normalize
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    with xr.open_dataset(product_path) as ds:
        depths = ds["depth"].values.astype(float)
        k = int(np.argmin(np.abs(depths - float(depth_m))))
        lat = ds["latitude"].values.astype(float)
        lon = ds["longitude"].values.astype(float)
        elev = ds["elevation"].values.astype(float)
        u = ds["u"][0, k].values.astype(float)
        v = ds["v"][0, k].values.astype(float)
        t0 = str(np.datetime_as_string(ds["time"].values[0].astype("datetime64[s]"), unit="s"))
        region, variant = ds.attrs.get("region", ""), ds.attrs.get("variant", "")
        source = ds.attrs.get("source", "")
    speed = np.hypot(u, v)
    if not np.isfinite(speed).any():
        raise DataError(f"{product_path}: no current defined at {depths[k]} m")
    if lat.size < 2 or lon.size < 2:
        raise DataError(f"{product_path}: need at least 2 x 2 grid points for Fig. 3")
    vmax = float(np.nanmax(speed)) or 1.0
    elev = np.where(np.isfinite(elev), elev, 0.0)
    zlo, zhi = float(elev.min()), float(elev.max())
    if zhi - zlo < 1e-6:
        zlo, zhi = zlo - 1.0, zhi + 1.0

    kx = float(libm.cos(np.deg2rad(0.5 * (lat[0] + lat[-1]))))
    wx_m = float(np.ptp(lon)) * kx * _M_PER_DEG       # extent, metres
    wy_m = float(np.ptp(lat)) * _M_PER_DEG
    dx_m, dy_m = wx_m / (lon.size - 1), wy_m / (lat.size - 1)
    cmap, norm = colormaps[SPEED_CMAP], Normalize(0.0, vmax)
    land = ~np.isfinite(speed)
    stats = {"depth_m": float(depths[k]), "vmax": vmax}

    # ---- 3-D panel geometry (box coordinates: x, y in proportion to metres)
    sy, sx = _stride(lat.size, _MAX_SURFACE_NODES), _stride(lon.size, _MAX_SURFACE_NODES)
    iy = np.unique(np.r_[np.arange(0, lat.size, sy), lat.size - 1])
    ix = np.unique(np.r_[np.arange(0, lon.size, sx), lon.size - 1])
    LON, LAT = np.meshgrid(lon[ix], lat[iy])
    Z = elev[np.ix_(iy, ix)]
    sp = speed[np.ix_(iy, ix)]
    big = max(wx_m, wy_m)
    # box height: 0.35 of the longer side, less if that would exaggerate the relief > 300 x
    box = (wx_m / big, wy_m / big,
           float(np.clip(300.0 * (zhi - zlo) / big, 0.12, 0.35)))
    rgb = cmap(norm(np.nan_to_num(sp)))
    rgb[~np.isfinite(sp)] = LAND_RGBA
    exag = (box[2] / (zhi - zlo)) / (1.0 / big)        # vertical exaggeration of the box
    ls = LightSource(azdeg=315.0, altdeg=40.0)
    # rows run south -> north (shade_rgb expects north first): flip, shade, flip back
    shaded = ls.shade_rgb(rgb[::-1, :, :3], Z[::-1], fraction=0.6, blend_mode="soft",
                          vert_exag=exag, dx=dx_m * sx, dy=dy_m * sy)[::-1]
    face = np.concatenate([np.clip(shaded, 0, 1), np.ones(Z.shape + (1,))], axis=-1)

    # arrows: a coarse grid of water points, drawn flat just above the terrain
    spacing = big / _ARROWS_3D
    ay, ax_ = max(1, round(spacing / dy_m)), max(1, round(spacing / dx_m))
    qj, qi = np.meshgrid(np.arange(ay // 2, lat.size, ay), np.arange(ax_ // 2, lon.size, ax_),
                         indexing="ij")
    qj, qi = qj.ravel(), qi.ravel()
    qu, qv, qs = u[qj, qi], v[qj, qi], speed[qj, qi]
    ok = np.isfinite(qs) & (qs > 1e-9)
    qj, qi, qu, qv, qs = qj[ok], qi[ok], qu[ok], qv[ok], qs[ok]
    S = spacing / _M_PER_DEG                            # arrow spacing, metric degrees
    length = S * (0.35 + 0.55 * qs / vmax)
    head = np.minimum(0.5 * length, 0.38 * S)
    polys = _arrow_polygons(lon[qi] * kx, lat[qj], qu / qs, qv / qs, length, head,
                            0.55 * head, 0.14 * head)
    plon, plat = polys[..., 0] / kx, polys[..., 1]
    # terrain under every vertex, on the rendered (subsampled) surface, lifted a little
    fy = np.interp(plat, lat[iy], np.arange(iy.size))
    fx = np.interp(plon, lon[ix], np.arange(ix.size))
    lift = 0.015 * (zhi - zlo)
    pz = _bilinear(Z, fy, fx) + lift
    ztop = zhi + 2 * lift
    # occlusion: ray-march every vertex (and the shaft's middle) toward the eye, in box
    # coordinates (x, y in proportion to metres, z to the exaggerated elevation)
    el, az = np.deg2rad(float(pitch_deg)), np.deg2rad(float(azimuth_deg))
    eye = np.array([libm.cos(el) * libm.cos(az), libm.cos(el) * libm.sin(az), libm.sin(el)])
    to_bx = lambda a: (a - lon[0]) / (lon[-1] - lon[0]) * box[0]  # noqa: E731
    to_by = lambda a: (a - lat[0]) / (lat[-1] - lat[0]) * box[1]  # noqa: E731
    to_bz = lambda a: (a - zlo) / (ztop - zlo) * box[2]  # noqa: E731
    pts = np.stack([to_bx(plon), to_by(plat), to_bz(pz)], axis=-1)
    mids = np.stack([0.5 * (pts[:, 0] + pts[:, 1]), 0.5 * (pts[:, 5] + pts[:, 6])], axis=1)
    probe = np.concatenate([pts, mids], axis=1)
    xn, yn = to_bx(lon[ix]), to_by(lat[iy])
    step = 0.5 * min(np.diff(xn).min(), np.diff(yn).min())
    vis = _visible(probe.reshape(-1, 3), xn, yn, to_bz(Z), eye, box[2], step)
    shown = vis.reshape(probe.shape[:2]).all(axis=1)
    stats.update(arrows_3d=int(shown.sum()), arrows_hidden=int((~shown).sum()))

    # ---- plan view
    mspacing = big / _ARROWS_MAP
    my, mx = max(1, round(mspacing / dy_m)), max(1, round(mspacing / dx_m))
    mj = np.arange(my // 2, lat.size, my)
    mi = np.arange(mx // 2, lon.size, mx)
    MU, MV = u[np.ix_(mj, mi)], v[np.ix_(mj, mi)]
    mok = np.isfinite(MU) & np.isfinite(MV)
    stats["arrows_map"] = int(mok.sum())
    plan_ratio = wy_m / max(wx_m, 1e-9)          # height / width of the map
    water_speed = speed[np.isfinite(speed)]
    vref = float(np.quantile(water_speed, 0.95)) or vmax   # arrow of one spacing (x 0.9)

    # layout in inches (manual: mplot3d and aspect-locked maps defeat the layout engines)
    H, W3 = 3.6, 3.75                            # height; width of the 3-D panel
    ml, mb, mt, gap, cbw, cbl = 0.55, 0.45, 0.6, 0.1, 0.12, 0.62
    hp = H - mb - mt
    wp = hp / plan_ratio
    if wp > 3.0:
        wp, hp = 3.0, 3.0 * plan_ratio
    W = W3 + ml + wp + gap + cbw + cbl
    x2 = W3 + ml

    title = (f"{region} / {variant} ({source}): currents at {depths[k]:.3g} m, {t0} UTC")
    with paper_style():
        fig = new_figure(W, H, layout=None)
        ax3 = fig.add_axes((0.2 / W, 0.0, (W3 - 0.2) / W, (H - 0.3) / H), projection="3d",
                           computed_zorder=False)
        ax3.set_proj_type("ortho")
        surf = ax3.plot_surface(LON, LAT, Z, facecolors=face, rstride=1, cstride=1,
                                linewidth=0, antialiased=False, shade=False, zorder=1)
        surf.set_rasterized(True)
        if shown.any():
            verts = [np.column_stack([plon[n], plat[n], pz[n]]) for n in np.flatnonzero(shown)]
            arrows = Poly3DCollection(verts, facecolors="white", edgecolors=(0, 0, 0, 0.85),
                                      linewidths=0.35, zorder=3)
            ax3.add_collection3d(arrows)
        ax3.set_xlim(lon[0], lon[-1])
        ax3.set_ylim(lat[0], lat[-1])
        ax3.set_zlim(zlo, ztop)
        ax3.set_box_aspect(box, zoom=0.92)
        ax3.view_init(elev=float(pitch_deg), azim=float(azimuth_deg))
        for axis, frac in ((ax3.xaxis, box[0]), (ax3.yaxis, box[1]), (ax3.zaxis, 1.0)):
            axis.set_major_locator(MaxNLocator(max(2, int(round(4 * frac)))))
            axis.pane.set_facecolor((0.97, 0.97, 0.97, 1.0))
            axis._axinfo["grid"].update(linewidth=0.4, color=(0.85, 0.85, 0.85, 1.0))
        ax3.tick_params(labelsize=6, pad=0)
        ax3.set_xlabel("Longitude (°E)", labelpad=1, fontsize=7)
        ax3.set_ylabel("Latitude (°N)", labelpad=1, fontsize=7)
        ax3.set_zlabel("Elevation (m)", labelpad=-2, fontsize=7)
        fig.text(0.01, (H - 0.45) / H, "(a) terrain and current direction",
                 fontsize=8.5, va="bottom")

        ax2 = fig.add_axes((x2 / W, mb / H, wp / W, hp / H))
        water = np.ma.masked_invalid(speed)
        ax2.pcolormesh(lon, lat, water, cmap=cmap, norm=norm, shading="nearest",
                       rasterized=True)
        nodata = np.ma.masked_array(np.where(elev >= 0.0, 1.0, 0.0), mask=~land)
        ax2.pcolormesh(lon, lat, nodata, cmap=ListedColormap([NODATA_RGBA, LAND_RGBA]),
                       vmin=0.0, vmax=1.0, shading="nearest", rasterized=True)
        if zlo < 0:
            levels = [lv for lv in MaxNLocator(5).tick_values(zlo, 0.0) if zlo < lv < 0.0]
            if levels:
                cs = ax2.contour(lon, lat, elev, levels=levels, colors="0.1",
                                 linewidths=0.4, alpha=0.6)
                ax2.clabel(cs, fontsize=5, fmt=lambda z: f"{-z:g} m", inline=True)
        if zhi > 0 > zlo:
            ax2.contour(lon, lat, elev, levels=[0.0], colors="0.1", linewidths=0.7)
        MLON, MLAT = np.meshgrid(lon[mi], lat[mj])
        scale = vref / (0.9 * mspacing / _M_PER_DEG)
        q = ax2.quiver(MLON[mok], MLAT[mok], MU[mok] / kx, MV[mok], angles="xy",
                       scale_units="xy", scale=scale, units="inches", width=0.014,
                       headwidth=3.6, headlength=3.6, headaxislength=3.2, minlength=0.6,
                       color="white", edgecolor="k", linewidth=0.35, zorder=3)
        ref = _nice_ref(vref)
        fig.text(x2 / W, (mb + hp + 0.08) / H, "(b) plan view", fontsize=8.5, va="bottom")
        ax2.quiverkey(q, X=(x2 + wp + gap + 0.1) / W, Y=(mb + hp + 0.14) / H, U=ref,
                      label=f"{ref:g} m s$^{{-1}}$", labelpos="E", coordinates="figure",
                      color="k", labelsep=0.04, fontproperties={"size": 6.5})
        ax2.set_xlim(lon[0], lon[-1])
        ax2.set_ylim(lat[0], lat[-1])
        ax2.set_aspect(1.0 / kx)
        ax2.xaxis.set_major_locator(MaxNLocator(max(2, min(4, int(wp / 0.5)))))
        ax2.yaxis.set_major_locator(MaxNLocator(5))
        ax2.set_xlabel("Longitude (°E)")
        ax2.set_ylabel("Latitude (°N)")
        cax = fig.add_axes(((x2 + wp + gap) / W, mb / H, cbw / W, hp / H))
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=cax,
                     label="Current speed (m s$^{-1}$)")
        fig.suptitle(title, y=0.985)
        png, pdf = save_figure(fig, out_png)
    stats.update(png=str(png), pdf=str(pdf))
    return stats


# ------------------------------------------------------------------------------------------
# Fig. 4: a multi-species reacting pollution field
# ------------------------------------------------------------------------------------------

#: Species of Fig. 4 and the reaction between them (rates s-1): fresh oil emulsifies
#: (A -> B) and dissolves (A -> C), the emulsion dissolves (B -> C), the dissolved fraction
#: degrades (C -> sink). ``K`` of ``dC/dt = K C`` is built from these by :func:`_fig4_reaction`.
FIG4_SPECIES = ("fresh oil", "emulsion", "dissolved")
FIG4_RATES = {"emulsify": 1.0 / 900.0, "dissolve": 1.0 / 3600.0,
              "emulsion_dissolve": 1.0 / 5400.0, "degrade": 1.0 / 7200.0}


def _fig4_reaction(rates=FIG4_RATES) -> np.ndarray:
    a, d = rates["emulsify"], rates["dissolve"]
    b, g = rates["emulsion_dissolve"], rates["degrade"]
    return np.array([[-(a + d), 0.0, 0.0],
                     [a, -b, 0.0],
                     [d, b, -g]])


def _fig4_scene(rng, nx, nz, h, current_ms, eddy_ms):
    """Land mask (nz, nx) and cell-centre currents (m s-1) of Fig. 4's small coastal domain:
    a wavy coast along the north side and an islet, a uniform eastward drift plus an eddy."""
    x = h * np.arange(nx)
    z = h * np.arange(nz)
    X, Z = np.meshgrid(x, z)
    Lx, Lz = h * (nx - 1), h * (nz - 1)
    phase = rng.uniform(0.0, 2.0 * np.pi)
    coast = 0.84 * Lz + 0.06 * Lz * libm.sin(2.0 * np.pi * X / Lx * 1.5 + phase)
    land = (Z > coast) | ((X - 0.70 * Lx) ** 2 + (Z - 0.55 * Lz) ** 2 < (0.07 * Lz) ** 2)
    xe, ze, re = 0.48 * Lx, 0.45 * Lz, 0.27 * Lz
    dx, dz = X - xe, Z - ze
    r = np.hypot(dx, dz)
    w = eddy_ms * (r / re) * libm.exp(0.5 * (1.0 - (r / re) ** 2))   # peak eddy_ms at r = re
    with np.errstate(invalid="ignore", divide="ignore"):
        uc = current_ms - np.where(r > 0, w * dz / r, 0.0)
        vc = np.where(r > 0, w * dx / r, 0.0)
    uc[land], vc[land] = 0.0, 0.0
    return land.astype(np.uint8), uc, vc


def plot_pollution_species(out_png, seed: int = 0, *, times_s=(300.0, 1200.0, 2700.0),
                           dt_s: float = 10.0, nx: int = 80, nz: int = 56, h_m: float = 10.0,
                           spill_kg: float = 1000.0, leak_kg_s: float = 0.15,
                           current_ms: float = 0.12, eddy_ms: float = 0.2,
                           kappa_m2s: float = 1.5) -> dict:
    """Draw Fig. 4: a multi-species pollution field of the reaction kind, at a few times.

    A small coastal domain (``nx`` x ``nz`` cells of ``h_m``; a wavy coast along the north
    side and an islet; west, south and east sides open) carries a uniform eastward drift
    ``current_ms`` plus an eddy (peak ``eddy_ms``), put on the faces with
    :func:`~oneocean.models.pollution.faces_from_centers`. A spill of ``spill_kg`` of fresh oil
    (:func:`~oneocean.models.pollution.make_spill`, stretched by the seeded generator) and a
    leak of ``leak_kg_s`` (:func:`~oneocean.models.pollution.emit`, every step) feed species 0;
    the :data:`KIND_REACTION <oneocean.models.pollution.KIND_REACTION>` field turns it into the
    others (:data:`FIG4_SPECIES`, :data:`FIG4_RATES`) while
    :func:`~oneocean.models.pollution.step_field` advects and diffuses all of them. Rows are
    species (one colour scale per species, shared across times; square-root scale), columns
    the times ``times_s``; each panel gives the species' mass on the grid, each column the
    budget (on the grid, escaped through open sides, degraded). Deterministic for a seed.

    Parameters
    ----------
    out_png : path-like
        The PNG (the PDF goes beside it: :func:`save_figure`).
    seed : int, default 0
        Seed of the coast's phase and the spill's placement and shape.
    times_s : sequence of float, default (300.0, 1200.0, 2700.0)
        Snapshot times, s (>= 0; sorted, rounded to whole steps).
    dt_s : float, default 10.0
        Time step, s (> 0).
    nx, nz : int, default 80, 56
        Cells along x (east) and z (north).
    h_m : float, default 10.0
        Cell size, m.
    spill_kg : float, default 1000.0
        Mass of the initial spill, kg.
    leak_kg_s : float, default 0.15
        Rate of the continuous leak, kg s-1.
    current_ms : float, default 0.12
        Uniform eastward drift, m s-1.
    eddy_ms : float, default 0.2
        Peak speed of the eddy, m s-1.
    kappa_m2s : float, default 1.5
        Diffusivity, m2 s-1.

    Returns
    -------
    dict
        ``times_s`` (nt,), ``species``, ``mass_kg`` (n_species, nt) on the grid,
        ``initial_kg`` (the spill's mass on the grid), ``emitted_kg`` / ``escaped_kg`` /
        ``degraded_kg`` (nt,) cumulative, ``fields`` (nt, n_species, nz, nx) kg m-2,
        ``land`` (nz, nx) uint8, ``png``, ``pdf``.

    Raises
    ------
    ValueError
        If ``times_s`` is empty or negative, or ``dt_s`` is not positive.
    """
    from matplotlib.colors import ListedColormap, PowerNorm

    from ..models import pollution as pol

    times = np.asarray(sorted(float(t) for t in times_s), dtype=float)
    if times.size == 0 or times[0] < 0 or not dt_s > 0:
        raise ValueError("plot_pollution_species: need times_s >= 0 and dt_s > 0")
    steps = np.rint(times / dt_s).astype(int)
    rng = np.random.default_rng(seed)
    land, uc, vc = _fig4_scene(rng, nx, nz, h_m, current_ms, eddy_ms)
    uf, vf = pol.faces_from_centers(uc, vc)
    ns = len(FIG4_SPECIES)
    Lx, Lz = h_m * (nx - 1), h_m * (nz - 1)
    spill_xz = (Lx * (0.22 + 0.04 * rng.uniform(-1, 1)), Lz * (0.45 + 0.04 * rng.uniform(-1, 1)))
    leak_xz = (0.15 * Lx, 0.15 * Lz)
    C = pol.make_spill(nx, nz, h_m, spill_xz, 0.08 * Lx, spill_kg, rng, n_species=ns,
                       species=0, land=land)
    kind, params = pol.field_params("reaction", ns, reaction=_fig4_reaction())
    work = pol.make_work(C)
    open_bc = pol.OPEN_WEST | pol.OPEN_EAST | pol.OPEN_SOUTH
    initial = float(pol.total_mass(C, h_m))
    emitted = escaped = 0.0
    snaps, mass, em, es = [], [], [], []
    for k in range(int(steps[-1]) + 1):
        while len(snaps) < steps.size and steps[len(snaps)] == k:
            snaps.append(C.copy())
            mass.append([pol.species_mass(C, s, h_m) for s in range(ns)])
            em.append(emitted)
            es.append(escaped)
        if k == steps[-1]:
            break
        emitted += pol.emit(C, 0, leak_xz[0], leak_xz[1], leak_kg_s, dt_s, 0.0, 0.0, h_m)
        escaped += pol.step_field(C, kind, params, uf, vf, land, h_m, dt_s, kappa_m2s,
                                  open_bc, work)
    mass = np.asarray(mass, dtype=float).T                     # (ns, nt)
    em, es = np.asarray(em), np.asarray(es)
    degraded = initial + em - es - mass.sum(axis=0)
    fields = np.stack(snaps)
    t_real = steps * dt_s

    cols = palette(10)
    species_colors = [cols[3], cols[0], cols[2]]
    extent = (-0.5 * h_m, (nx - 0.5) * h_m, -0.5 * h_m, (nz - 0.5) * h_m)
    land_img = np.ma.masked_array(np.ones(land.shape), mask=land == 0)
    qs = 7
    qx, qz = np.meshgrid(h_m * np.arange(qs // 2, nx, qs), h_m * np.arange(qs // 2, nz, qs))
    qu, qv = uc[qs // 2::qs, qs // 2::qs], vc[qs // 2::qs, qs // 2::qs]
    qok = land[qs // 2::qs, qs // 2::qs] == 0
    nt = t_real.size
    with paper_style():
        import seaborn as sns

        panel_w = (PAGE_IN - 1.3) / nt
        fig = new_figure(PAGE_IN, ns * panel_w * (nz / nx) + 1.0)
        axes = fig.subplots(ns, nt, sharex=True, sharey=True, squeeze=False)
        for s in range(ns):
            cmap = sns.light_palette(species_colors[s], as_cmap=True)
            vmax = float(fields[:, s].max()) * 1e3 or 1.0               # g m-2
            norm = PowerNorm(0.5, vmin=0.0, vmax=vmax)
            for c in range(nt):
                ax = axes[s, c]
                img = np.ma.masked_array(fields[c, s] * 1e3, mask=land != 0)
                im = ax.imshow(img, origin="lower", extent=extent, cmap=cmap, norm=norm,
                               interpolation="nearest")
                ax.imshow(land_img, origin="lower", extent=extent,
                          cmap=ListedColormap([LAND_RGBA]), vmin=0, vmax=1,
                          interpolation="nearest")
                ax.quiver(qx[qok], qz[qok], qu[qok], qv[qok], color="0.45", alpha=0.6,
                          angles="xy", scale_units="xy", scale=0.2 / (0.8 * qs * h_m),
                          width=0.004, headwidth=4, headlength=4, headaxislength=3.5)
                if s == 0:
                    ax.plot(*leak_xz, marker="v", ms=4, mfc="k", mec="white", mew=0.5,
                            ls="none")
                ax.text(0.97, 0.05, f"{mass[s, c]:.0f} kg", transform=ax.transAxes,
                        ha="right", va="bottom", fontsize=6.5,
                        bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none",
                              "alpha": 0.8})
                ax.set_aspect("equal")
                ax.tick_params(labelsize=6)
                if s == 0:
                    ax.set_title(f"t = {t_real[c] / 60:.3g} min: {mass[:, c].sum():.0f} kg on "
                                 f"grid\nescaped {es[c]:.0f} kg, degraded {degraded[c]:.0f} kg",
                                 fontsize=7)
                if c == 0:
                    ax.set_ylabel(f"{FIG4_SPECIES[s]}\nz (m)")
                if s == ns - 1:
                    ax.set_xlabel("x (m)")
            fig.colorbar(im, ax=list(axes[s, :]), shrink=0.9, pad=0.01, aspect=12,
                         label="g m$^{-2}$")
        r = FIG4_RATES
        fig.suptitle(f"Reacting pollution field (seed {seed}): spill {spill_kg:g} kg + leak "
                     f"{leak_kg_s:g} kg s$^{{-1}}$ (▼); emulsify {1 / r['emulsify'] / 60:g} min, "
                     f"dissolve {1 / r['dissolve'] / 60:g} / {1 / r['emulsion_dissolve'] / 60:g}"
                     f" min, degrade {1 / r['degrade'] / 60:g} min (e-folding)", fontsize=7.5)
        png, pdf = save_figure(fig, out_png)
    return {"times_s": t_real, "species": list(FIG4_SPECIES), "mass_kg": mass,
            "emitted_kg": em, "escaped_kg": es, "degraded_kg": degraded, "initial_kg": initial,
            "fields": fields, "land": land, "png": str(png), "pdf": str(pdf)}


# ------------------------------------------------------------------------------------------
# Fig. 6: the ladder
# ------------------------------------------------------------------------------------------

def _task_order(present, tasks=None) -> list[str]:
    if tasks is not None:
        return [str(t) for t in tasks]
    from .. import registry

    known = [t for t in registry.task_ids() if t in present]
    return known + sorted(set(present) - set(known))


def ladder_numbers(cell_files, tasks=None, method: str = "heuristic"):
    """The numbers Fig. 6 plots, from cell files (:func:`oneocean.reporting.cells.load_cells`).

    Only ``method``'s cells with currents on; not-applicable cells are left out.

    Parameters
    ----------
    cell_files : iterable of path-like
        Rollout cell files.
    tasks : sequence of str, optional
        The tasks, in order (default: every task present, in registry order).
    method : str, default "heuristic"
        The method.

    Returns
    -------
    rates : DataFrame
        One row per (task, tier) cell: ``task, tier, k, n, sr, lo, hi`` (SR and its Wilson
        95 % interval in %).
    drops : DataFrame
        One row per task: ``task`` and, per consecutive tier pair ``(a, b)`` among the tiers
        present, a column ``"T{a}-T{b}"`` = SR(a) - SR(b) in points (NaN if either is missing).
        ``attrs["tiers"]`` lists the tiers.

    Raises
    ------
    DataError
        No cell files, or more than one cell of ``method`` per (task, tier).
    """
    from .cells import load_cells
    from .stats import wilson

    cells = load_cells(list(cell_files))
    if cells.empty:
        raise DataError("plot_ladder: no cell files")
    sel = cells[(cells["method"] == method) & cells["currents"] & cells["applicable"]
                & (cells["n"] > 0)]
    dup = sel.duplicated(["task", "tier"], keep=False)
    if dup.any():
        d = sel[dup].iloc[0]
        raise DataError(f"plot_ladder: more than one {method} cell for {d['task']} "
                        f"tier {d['tier']} (currents on)")
    order = _task_order(set(sel["task"]), tasks)
    rows = []
    for c in sel.itertuples():
        if c.task not in order:
            continue
        lo, hi = wilson(int(c.k), int(c.n))
        rows.append({"task": c.task, "tier": int(c.tier), "k": int(c.k), "n": int(c.n),
                     "sr": 100.0 * c.k / c.n, "lo": 100.0 * lo, "hi": 100.0 * hi})
    rates = pd.DataFrame(rows, columns=["task", "tier", "k", "n", "sr", "lo", "hi"])
    rates["_o"] = rates["task"].map({t: i for i, t in enumerate(order)})
    rates = rates.sort_values(["_o", "tier"], kind="stable").drop(columns="_o")
    rates = rates.reset_index(drop=True)
    tiers = sorted(set(cells.loc[cells["method"] == method, "tier"]))
    drops = pd.DataFrame({"task": order})
    for a, b in zip(tiers[:-1], tiers[1:]):
        sa = rates[rates["tier"] == a].set_index("task")["sr"]
        sb = rates[rates["tier"] == b].set_index("task")["sr"]
        drops[f"T{a}-T{b}"] = [float(sa.get(t, np.nan) - sb.get(t, np.nan)) for t in order]
    drops.attrs["tiers"] = tiers
    return rates, drops


def plot_ladder(cell_files, out_png, tasks=None, method: str = "heuristic") -> dict:
    """Draw Fig. 6: the difficulty ladder of one method, two panels.

    Left, the success rate (%) per task at every tier (grouped bars) with Wilson 95 % error
    bars; right, the drops between consecutive tiers (T1->T2, T2->T3; percentage points, a
    positive drop = harder tier, lower SR). From the cell files
    (:func:`oneocean.reporting.cells.load_cells`), only ``method``'s cells with currents on;
    not-applicable (or missing) cells are marked n/a. ``tasks`` selects and orders the tasks
    (default: every task present, in registry order).

    Parameters
    ----------
    cell_files : iterable of path-like
        Rollout cell files.
    out_png : path-like
        The PNG (the PDF goes beside it: :func:`save_figure`).
    tasks : sequence of str, optional
        The tasks, in order.
    method : str, default "heuristic"
        The method.

    Returns
    -------
    dict
        ``rates`` and ``drops`` (:func:`ladder_numbers`, exactly what is plotted), ``png``,
        ``pdf``.

    Raises
    ------
    DataError
        As :func:`ladder_numbers`.
    """
    import seaborn as sns

    rates, drops = ladder_numbers(cell_files, tasks, method)
    tiers = drops.attrs["tiers"]
    order = list(drops["task"])
    pairs = [c for c in drops.columns if c != "task"]
    x = np.arange(len(order))
    with paper_style():
        tier_cols = sns.color_palette("crest", len(tiers))
        drop_cols = sns.color_palette("flare", max(len(pairs), 1))
        fig = new_figure(PAGE_IN, 2.7)
        gs = fig.add_gridspec(1, 2, width_ratios=[1.65, 1.0])
        ax, axd = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[0, 1])
        w = 0.8 / len(tiers)
        for ti, tier in enumerate(tiers):
            r = rates[rates["tier"] == tier].set_index("task")
            xs = x + (ti - 0.5 * (len(tiers) - 1)) * w
            have = np.array([t in r.index for t in order])
            sr = np.array([r["sr"].get(t, np.nan) for t in order])
            lo = np.array([r["lo"].get(t, np.nan) for t in order])
            hi = np.array([r["hi"].get(t, np.nan) for t in order])
            ax.bar(xs[have], sr[have], w * 0.92, color=tier_cols[ti], label=f"Tier {tier}",
                   zorder=2)
            ax.errorbar(xs[have], sr[have], yerr=_err(sr[have], lo[have], hi[have]),
                        fmt="none", ecolor="0.15", elinewidth=0.6, capsize=1.5, zorder=3)
            for xi in xs[~have]:
                ax.text(xi, 2.0, "n/a", rotation=90, ha="center", va="bottom", fontsize=5.5,
                        color="0.4")
        ax.set_xticks(x, order)
        ax.set_xlim(-0.6, len(order) - 0.4)
        ax.set_ylim(0, 108)
        ax.set_ylabel("Success rate (%)")
        ax.yaxis.grid(True, lw=0.4, color="0.88", zorder=0)
        ax.set_axisbelow(True)
        ax.legend(ncols=len(tiers), loc="lower left", bbox_to_anchor=(0.0, 1.0),
                  handlelength=1.0, columnspacing=1.0, borderaxespad=0.2)
        n_eps = sorted(set(rates["n"]))
        ns = (f"{n_eps[0]}" if len(n_eps) == 1 else f"{n_eps[0]}-{n_eps[-1]}") if n_eps else "0"
        ax.set_title(f"(a) {method}: success rate, Wilson 95 % CI ({ns} episodes per cell)",
                     loc="left", fontsize=7.5, pad=16)
        wd = 0.8 / max(len(pairs), 1)
        for pi, col in enumerate(pairs):
            xs = x + (pi - 0.5 * (len(pairs) - 1)) * wd
            vals = drops[col].to_numpy(dtype=float)
            ok = np.isfinite(vals)
            axd.bar(xs[ok], vals[ok], wd * 0.92, color=drop_cols[pi],
                    label=col.replace("-", "→"), zorder=2)
            for xi in xs[~ok]:
                axd.text(xi, 0.5, "n/a", rotation=90, ha="center", va="bottom", fontsize=5.5,
                         color="0.4")
        axd.axhline(0.0, color="0.2", lw=0.6, zorder=3)
        axd.set_xticks(x, order, rotation=45, ha="right", rotation_mode="anchor")
        axd.set_xlim(-0.6, len(order) - 0.4)
        axd.set_ylabel("SR drop (points)")
        axd.yaxis.grid(True, lw=0.4, color="0.88", zorder=0)
        axd.set_axisbelow(True)
        if pairs:
            axd.legend(ncols=len(pairs), loc="lower left", bbox_to_anchor=(0.0, 1.0),
                       handlelength=1.0, borderaxespad=0.2)
        axd.set_title("(b) drop between tiers (SR points)", loc="left", fontsize=7.5,
                      pad=16)
        png, pdf = save_figure(fig, out_png)
    return {"rates": rates, "drops": drops, "png": str(png), "pdf": str(pdf)}


# ------------------------------------------------------------------------------------------
# Fig. 7: the SPC team-size sweep
# ------------------------------------------------------------------------------------------

def team_sweep_numbers(cell_files) -> pd.DataFrame:
    """The numbers Fig. 7 plots: one row per team size.

    Over the applicable cells with currents on, all of one task, tier and method; the team
    size ``n_agents`` comes from each cell's record, else its column.

    Parameters
    ----------
    cell_files : iterable of path-like
        The sweep's cell files (of a task with a ``cleanup_rate`` metric, i.e. SPC), one per
        team size.

    Returns
    -------
    pandas.DataFrame
        Sorted by team size: ``n_agents, n, k, sr, sr_lo, sr_hi`` (%, Wilson 95 %),
        ``cleanup, cleanup_lo, cleanup_hi`` (mean cleanup rate, %, seeded bootstrap 95 %),
        ``T_s, T_lo, T_hi`` (mean time to success, s, bootstrap; the time limit counts for
        failed episodes), ``coll_pct`` (mean near-collision ratio, %), ``E`` (mean control
        effort, m2 s-1) and ``task, tier, method, target_pct`` (the success target fraction
        of the cells' tier, %, or NaN).

    Raises
    ------
    DataError
        No applicable cell with currents on, cells of more than one (task, tier, method),
        or more than one cell per team size.
    """
    from .cells import read_cell
    from .stats import BOOT_SEED, mean_ci, wilson

    rows = []
    ident = set()
    targets = set()
    for f in cell_files:
        df, c = read_cell(f)
        if not c["applicable"] or not len(df) or not c["currents"]:
            continue
        n_agents = c["n_agents"]
        ident.add((str(c["task"]), c["tier"], str(c["method"])))
        tf = (c["meta"].get("tier_params") or {}).get("target_fraction")
        targets.add(float(tf) if tf is not None else math.nan)
        k, n = int(df["success"].sum()), int(len(df))
        lo, hi = wilson(k, n)
        cr = df["cleanup_rate"].to_numpy(dtype=float)
        ts = df["T_s"].to_numpy(dtype=float)
        _, clo, chi = mean_ci(cr, BOOT_SEED + n_agents)
        _, tlo, thi = mean_ci(ts, BOOT_SEED + 1000 + n_agents)
        rows.append({"n_agents": n_agents, "n": n, "k": k, "sr": 100.0 * k / n,
                     "sr_lo": 100.0 * lo, "sr_hi": 100.0 * hi,
                     "cleanup": 100.0 * float(np.nanmean(cr)), "cleanup_lo": 100.0 * clo,
                     "cleanup_hi": 100.0 * chi, "T_s": float(np.nanmean(ts)), "T_lo": tlo,
                     "T_hi": thi, "coll_pct": 100.0 * float(df["coll_ratio"].mean()),
                     "E": float(df["E"].mean())})
    if not rows:
        raise DataError("plot_team_sweep: no applicable cell with currents on")
    if len(ident) > 1:
        raise DataError(f"plot_team_sweep: cells of more than one (task, tier, method): "
                        f"{sorted(ident)}")
    out = pd.DataFrame(rows)
    if out["n_agents"].duplicated().any():
        raise DataError("plot_team_sweep: more than one cell per team size "
                        f"{sorted(out.loc[out['n_agents'].duplicated(), 'n_agents'])}")
    out = out.sort_values("n_agents", kind="stable").reset_index(drop=True)
    (task, tier, method), = ident
    out["task"], out["tier"], out["method"] = task, tier, method
    out["target_pct"] = 100.0 * targets.pop() if len(targets) == 1 else math.nan
    return out


def plot_team_sweep(cell_files, out_png) -> dict:
    """Draw Fig. 7: the SPC team-size sweep (one cell per team size N, e.g. SPC Tier 2).

    Left: success rate (Wilson 95 % error bars) and mean cleanup rate (seeded bootstrap 95 %
    error bars) vs N, in %, with the tier's cleanup target when the cells record it. Right:
    mean time to success ``T_s`` (s, bootstrap 95 % bars; the time limit counts for failed
    episodes) and the mean near-collision ratio (%, right axis) vs N, each T point annotated
    with the mean control effort E in thousands (m² s⁻¹). Where the region hosts no cell,
    the figure says so instead (an empty ``sweep``).

    Parameters
    ----------
    cell_files : iterable of path-like
        The sweep's cell files, one per team size.
    out_png : path-like
        The PNG (the PDF goes beside it: :func:`save_figure`).

    Returns
    -------
    dict
        ``sweep`` (:func:`team_sweep_numbers`, exactly what is plotted), ``png``, ``pdf``.

    Raises
    ------
    DataError
        As :func:`team_sweep_numbers`, but for no applicable cell.
    """
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    try:
        sw = team_sweep_numbers(list(cell_files))
    except DataError as exc:
        if "no applicable cell" not in str(exc):
            raise
        # the region cannot host the sweep's cells: say so in the figure, never crash
        with paper_style():
            fig = new_figure(PAGE_IN, 1.2)
            ax = fig.add_subplot()
            ax.axis("off")
            ax.text(0.5, 0.5, "Fig. 7: the team-size sweep's cells are not applicable in this "
                    "region (each cell file records why)", ha="center", va="center")
            png, pdf = save_figure(fig, out_png)
        return {"sweep": pd.DataFrame(), "png": str(png), "pdf": str(pdf)}
    N = sw["n_agents"].to_numpy()
    col = palette(10)
    with paper_style():
        fig = new_figure(PAGE_IN, 2.6)
        ax, axt = fig.subplots(1, 2)
        ax.errorbar(N, sw["sr"], yerr=_err(sw["sr"], sw["sr_lo"], sw["sr_hi"]),
                    color=col[0], marker="o", label="SR (Wilson 95 %)")
        ax.errorbar(N + 0.08, sw["cleanup"], yerr=_err(sw["cleanup"], sw["cleanup_lo"],
                                                       sw["cleanup_hi"]),
                    color=col[1], marker="s", ls="--",
                    label="cleanup rate (bootstrap 95 %)")
        tgt = float(sw["target_pct"].iloc[0])
        if np.isfinite(tgt):
            ax.axhline(tgt, color="0.5", lw=0.7, ls=":", zorder=1)
            ax.text(N.min(), tgt + 1.5, f"target {tgt:g} %", fontsize=6, color="0.35",
                    va="bottom")
        ax.set_ylim(0, 108)
        ax.set_xlabel("team size N")
        ax.set_ylabel("rate (%)")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncols=2, borderaxespad=0.2,
                  handlelength=1.6, columnspacing=1.0)
        neps = sorted(set(sw["n"]))
        eps = f"{neps[0]}" if len(neps) == 1 else f"{neps[0]}-{neps[-1]}"
        ax.set_title(f"(a) {sw['task'].iloc[0]} Tier {sw['tier'].iloc[0]}, "
                     f"{sw['method'].iloc[0]} ({eps} episodes per N)", loc="left",
                     fontsize=7.5, pad=16)

        axt.errorbar(N, sw["T_s"], yerr=_err(sw["T_s"], sw["T_lo"], sw["T_hi"]),
                     color=col[2], marker="o")
        for n_, t_, hi_, e_ in zip(N, sw["T_s"], sw["T_hi"], sw["E"]):
            axt.annotate(f"{e_ / 1000:.1f}k", (n_, hi_), xytext=(0, 4.0),
                         textcoords="offset points", ha="center", va="bottom", fontsize=5.5,
                         color="0.25")
        axt.set_xlabel("team size N")
        axt.set_ylabel("mean time to success T (s)", color=col[2])
        axt.tick_params(axis="y", colors=col[2])
        axt.xaxis.set_major_locator(MaxNLocator(integer=True))
        lo_t, hi_t = float(np.nanmin(sw["T_lo"])), float(np.nanmax(sw["T_hi"]))
        pad = 0.12 * max(hi_t - lo_t, 1.0)
        axt.set_ylim(max(0.0, lo_t - pad), hi_t + 2.0 * pad)
        axc = axt.twinx()
        axc.spines["right"].set_visible(True)
        axc.plot(N, sw["coll_pct"], color=col[3], marker="^", ls="--")
        axc.set_ylabel("near-collision ratio (%)", color=col[3])
        axc.tick_params(axis="y", colors=col[3])
        cmax = float(np.nanmax(sw["coll_pct"]))
        axc.set_ylim(0.0, max(1.0, 1.25 * cmax))
        axt.legend(handles=[
            Line2D([], [], color=col[2], marker="o", label="T (bootstrap 95 %)"),
            Line2D([], [], color=col[3], marker="^", ls="--", label="near-collision ratio")],
            loc="lower left", bbox_to_anchor=(0.0, 1.0), ncols=2, borderaxespad=0.2,
            handlelength=1.6, columnspacing=1.0)
        axt.set_title("(b) time to success and near collisions", loc="left", fontsize=7.5,
                      pad=16)
        axt.text(0.02, 0.04, "labels: mean effort E (10$^3$ m$^2$ s$^{-1}$)",
                 transform=axt.transAxes, fontsize=6, color="0.25", va="bottom")
        png, pdf = save_figure(fig, out_png)
    return {"sweep": sw, "png": str(png), "pdf": str(pdf)}


# ------------------------------------------------------------------------------------------
# The PPO baseline's learning curves (the optional rl_baselines target)
# ------------------------------------------------------------------------------------------

#: What :func:`rl_curve_numbers` reads from each row of a training report's curve.
_CURVE_KEYS = frozenset({"rollout", "timesteps", "episodes", "success_rate",
                         "mean_episode_return", "mean_reward"})


def rl_curve_numbers(report_files) -> pd.DataFrame:
    """The numbers the learning-curve figure plots: one row per task and training rollout.

    From each training report (``oneocean.methods.ppo.train.train_to_files``), the curve of
    its kept run (``selected_seed``).

    Parameters
    ----------
    report_files : iterable of path-like
        ``training_report.json`` files, one per task.

    Returns
    -------
    pandas.DataFrame
        In the reports' order, rollouts ascending: ``task, seed, rollout, timesteps,
        mean_reward`` (mean reward per step over the rollout), ``episodes`` (training
        episodes that ended in it), ``successes``, ``success_pct`` and its Wilson 95 %
        interval ``success_lo, success_hi`` (NaN for a rollout in which no episode ended),
        ``mean_episode_return``.

    Raises
    ------
    DataError
        A report that is not valid JSON, lacks a key the figure reads (named), or a task
        given twice.
    """
    import json

    from .stats import wilson

    rows, seen = [], set()
    for f in report_files:
        try:
            rep = json.loads(Path(f).read_text())
            task, seed = str(rep["task"]), int(rep["selected_seed"])
            run = next(r for r in rep["runs"] if int(r["seed"]) == seed)
            curve = run["curve"]
        except json.JSONDecodeError as exc:
            raise DataError(f"{f}: not a training report (invalid JSON: {exc})") from None
        except KeyError as exc:
            raise DataError(f"{f}: training report without {exc.args[0]!r}") from None
        except StopIteration:
            raise DataError(f"{f}: training report without the run of its selected seed "
                            f"{rep['selected_seed']}") from None
        if task in seen:
            raise DataError(f"{f}: a second training report of task {task}")
        seen.add(task)
        for c in curve:
            missing = _CURVE_KEYS - set(c)
            if missing:
                raise DataError(f"{f}: a learning-curve row without {sorted(missing)}")
        for c in sorted(curve, key=lambda c: int(c["rollout"])):
            n = int(c["episodes"])
            k = int(round(float(c["success_rate"]) * n)) if n else 0
            lo, hi = wilson(k, n) if n else (math.nan, math.nan)
            rows.append({"task": task, "seed": seed, "rollout": int(c["rollout"]),
                         "timesteps": int(c["timesteps"]),
                         "mean_reward": float(c["mean_reward"]), "episodes": n,
                         "successes": k, "success_pct": 100.0 * k / n if n else math.nan,
                         "success_lo": 100.0 * lo, "success_hi": 100.0 * hi,
                         "mean_episode_return": (float(c["mean_episode_return"]) if n
                                                 else math.nan)})
    cols = ["task", "seed", "rollout", "timesteps", "mean_reward", "episodes", "successes",
            "success_pct", "success_lo", "success_hi", "mean_episode_return"]
    return pd.DataFrame(rows, columns=cols)


def plot_rl_curves(report_files, out_png) -> dict:
    """Draw the PPO baseline's learning curves, one line per task (its kept training run).

    Left: the mean reward per step of each training rollout (the dense training reward)
    against SB3 timesteps. Right: the success rate of the training episodes that ended in
    each rollout (the training policy's stochastic actions), %, with its Wilson 95 % interval
    (the tasks' points side by side around the rollout); a rollout in which no episode ended
    has no point. Training episodes only: the evaluation seed's scores are in Table V.

    Parameters
    ----------
    report_files : iterable of path-like
        ``training_report.json`` files, one per task.
    out_png : path-like
        The PNG (the PDF goes beside it: :func:`save_figure`).

    Returns
    -------
    dict
        ``curves`` (:func:`rl_curve_numbers`, exactly what is plotted), ``png``, ``pdf``.

    Raises
    ------
    DataError
        As :func:`rl_curve_numbers`, or no report.
    """
    cv = rl_curve_numbers(list(report_files))
    if not len(cv):
        raise DataError("plot_rl_curves: no training report (rl.tasks is empty)")
    tasks = list(dict.fromkeys(cv["task"]))
    col = palette(max(len(tasks), 1))
    with paper_style():
        fig = new_figure(PAGE_IN, 2.4)
        ax, axs = fig.subplots(1, 2)
        for j, t in enumerate(tasks):
            d = cv[cv["task"] == t]
            x = d["timesteps"].to_numpy() / 1e3
            ax.plot(x, d["mean_reward"], color=col[j], marker="o", markersize=2.5,
                    label=f"{t} (seed {int(d['seed'].iloc[0])})")
            m = d["episodes"].to_numpy() > 0
            # tasks side by side around each rollout's x (a fifth of the rollout spacing)
            dx = 0.2 * float(np.median(np.diff(x))) if len(x) > 1 else 0.0
            sp = d[m]
            axs.errorbar(x[m] + dx * (j - 0.5 * (len(tasks) - 1)) / max(len(tasks) - 1, 1),
                         sp["success_pct"], yerr=_err(sp["success_pct"], sp["success_lo"],
                                                      sp["success_hi"]),
                         color=col[j], fmt="o", markersize=2.5, elinewidth=0.7,
                         capsize=1.2, label=t)
        ax.set_xlabel("SB3 timesteps (10$^3$)")
        ax.set_ylabel("mean reward per step")
        ax.set_title("(a) dense training reward", loc="left", fontsize=7.5)
        ax.legend(loc="best")
        axs.set_xlabel("SB3 timesteps (10$^3$)")
        axs.set_ylabel("success (%)")
        axs.set_ylim(-3.0, 103.0)
        axs.set_title("(b) training episodes' success per rollout (Wilson 95 %)", loc="left",
                      fontsize=7.5)
        axs.legend(loc="upper left", ncols=len(tasks))
        png, pdf = save_figure(fig, out_png)
    return {"curves": cv, "png": str(png), "pdf": str(pdf)}
