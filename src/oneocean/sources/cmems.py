"""Copernicus Marine (GLO12) currents and tides through ``copernicusmarine.subset``.

A request is a plain dict of ``subset`` keywords; its hash names the completed download in
the cache folder, so a rerun with the same request reuses the file and makes no network call.
Downloads go to a temporary name in the cache folder and are renamed once complete.
"""

from __future__ import annotations

import logging
import netrc
import os
from pathlib import Path
from typing import Mapping

import xarray as xr

from ..errors import CredentialsError
from .base import cached_download, file_records, read, to_json

log = logging.getLogger(__name__)

ENV_USERNAME = "COPERNICUSMARINE_SERVICE_USERNAME"
ENV_PASSWORD = "COPERNICUSMARINE_SERVICE_PASSWORD"
ENV_CREDENTIALS_DIRECTORY = "COPERNICUSMARINE_CREDENTIALS_DIRECTORY"
CREDENTIALS_FILENAME = ".copernicusmarine-credentials"
_NETRC_HOSTS = ("auth.marine.copernicus.eu", "my.cmems-du.eu", "nrt.cmems-du.eu")

CURRENT_VARIABLES = ("uo", "vo")
TIDE_VARIABLES = ("utide", "vtide")

NO_CREDENTIALS = (
    "No Copernicus Marine credentials: set COPERNICUSMARINE_SERVICE_USERNAME and "
    "COPERNICUSMARINE_SERVICE_PASSWORD, or run `copernicusmarine login` once (or point "
    "cmems.credentials_file at a credentials file)"
)


def default_credentials_files() -> list[Path]:
    """Credentials files the toolbox looks for, in its order of preference.

    Resolved at call time.

    Returns
    -------
    list of pathlib.Path
        ``$COPERNICUSMARINE_CREDENTIALS_DIRECTORY`` (or ``~/.copernicusmarine``)
        ``/.copernicusmarine-credentials`` (written by ``copernicusmarine login``), then the
        legacy ``~/motuclient/motuclient-python.ini`` and ``~/.netrc``; they need not exist.
    """
    home = Path.home()
    base = Path(os.environ.get(ENV_CREDENTIALS_DIRECTORY) or home / ".copernicusmarine")
    return [base / CREDENTIALS_FILENAME, home / "motuclient" / "motuclient-python.ini",
            home / ".netrc"]


def find_credentials(cmems_cfg: Mapping) -> Path | None:
    """Locate credentials without any network call or prompt.

    Parameters
    ----------
    cmems_cfg : Mapping
        The ``cmems`` config section (``credentials_file`` may be null).

    Returns
    -------
    pathlib.Path or None
        None when both environment variables are set, else the credentials file to pass to
        ``copernicusmarine.subset``: ``credentials_file`` if set, else the first of
        :func:`default_credentials_files` that exists (a ``.netrc`` only with a Copernicus
        Marine host).

    Raises
    ------
    CredentialsError
        Neither the environment variables nor a credentials file are available.
    """
    if os.environ.get(ENV_USERNAME) and os.environ.get(ENV_PASSWORD):
        return None
    explicit = cmems_cfg.get("credentials_file")
    if explicit:
        path = Path(explicit).expanduser()
        if path.is_file():
            return path
        raise CredentialsError(f"cmems.credentials_file {path}: file not found; "
                               f"{NO_CREDENTIALS[0].lower()}{NO_CREDENTIALS[1:]}")
    for path in default_credentials_files():
        if path.is_file() and (path.name not in (".netrc", "_netrc") or _netrc_has_host(path)):
            return path
    raise CredentialsError(NO_CREDENTIALS)


def _netrc_has_host(path: Path) -> bool:
    try:
        auth = netrc.netrc(path)
    except (netrc.NetrcParseError, OSError):
        return False
    return any(auth.authenticators(host) for host in _NETRC_HOSTS)


def build_request(cfg: Mapping, dataset_id: str, dataset_version: str | None,
                  variables: tuple[str, ...], with_depth: bool) -> dict:
    """The ``copernicusmarine.subset`` keywords that define the data of one download.

    ``coordinates_selection_method="outside"`` makes the service return the grid points that
    enclose the bbox, time window and depth range, i.e. one source cell of margin, the times
    bracketing the window and the first level deeper than ``region.max_depth_m``.

    Parameters
    ----------
    cfg : Mapping
        The validated config (its ``region`` section is used).
    dataset_id : str
        The Copernicus Marine dataset id.
    dataset_version : str or None
        Its version; None: the service's default.
    variables : tuple of str
        Provider variable names, e.g. ``("uo", "vo")``.
    with_depth : bool
        Add ``minimum_depth=0`` and ``maximum_depth=region.max_depth_m`` (m).

    Returns
    -------
    dict
        The keywords: dataset, variables, the bbox as minimum/maximum longitude and latitude
        (degrees), ``start_datetime``/``end_datetime`` (``region.time``) and the selection
        method; its hash names the cached download.
    """
    region = cfg["region"]
    bbox, window = region["bbox"], region["time"]
    request = {
        "dataset_id": dataset_id,
        "dataset_version": dataset_version,
        "variables": list(variables),
        "minimum_longitude": float(bbox["west"]),
        "maximum_longitude": float(bbox["east"]),
        "minimum_latitude": float(bbox["south"]),
        "maximum_latitude": float(bbox["north"]),
        "start_datetime": str(window["start"]),
        "end_datetime": str(window["end"]),
        "coordinates_selection_method": "outside",
    }
    if with_depth:
        request["minimum_depth"] = 0.0
        request["maximum_depth"] = float(region["max_depth_m"])
    return request


def download(request: Mapping, credentials_file: Path | None, part: Path) -> None:
    """Run ``copernicusmarine.subset`` for ``request``, writing exactly the file ``part``.

    ``overwrite=True`` replaces a stale temporary file instead of the toolbox's default of
    writing ``name_(1).nc`` beside it; credentials were checked beforehand, so the toolbox
    never prompts.

    Parameters
    ----------
    request : Mapping
        The ``subset`` keywords (:func:`build_request`).
    credentials_file : pathlib.Path or None
        The credentials file (:func:`find_credentials`); None: the environment variables.
    part : pathlib.Path
        The file to write.

    Raises
    ------
    CredentialsError
        The service rejected the credentials.
    """
    import copernicusmarine

    kwargs = dict(request, output_directory=str(part.parent), output_filename=part.name,
                  overwrite=True, disable_progress_bar=True)
    if credentials_file is not None:
        kwargs["credentials_file"] = str(credentials_file)
    try:
        copernicusmarine.subset(**kwargs)
    except copernicusmarine.InvalidUsernameOrPassword as err:
        raise CredentialsError(f"Copernicus Marine rejected the credentials "
                               f"({credentials_file or 'environment variables'}): "
                               f"{NO_CREDENTIALS}") from err


def fetch(cfg: Mapping, request: Mapping, cache_dir: str | os.PathLike) -> Path:
    """Path of the completed download for ``request`` in ``cache_dir`` (downloading if needed).

    Credentials are looked up only when a download is needed, so a rerun from the cache
    works offline.

    Parameters
    ----------
    cfg : Mapping
        The validated config (its ``cmems`` section: credentials, ``retries``,
        ``retry_wait_s``).
    request : Mapping
        The ``subset`` keywords (:func:`build_request`).
    cache_dir : str or os.PathLike
        Folder of completed downloads.

    Returns
    -------
    pathlib.Path
        The cached NetCDF, ``cmems-<dataset_id>-<key>.nc`` in ``cache_dir``.

    Raises
    ------
    CredentialsError
        A download is needed and no credentials are found, or they are rejected.
    DataError
        Every download attempt failed.
    """
    cmems_cfg = cfg["cmems"]
    found: dict[str, Path | None] = {}

    def check_credentials() -> None:
        found["file"] = find_credentials(cmems_cfg)

    return cached_download(
        cache_dir, f"cmems-{request['dataset_id']}", request,
        lambda part: download(request, found.get("file"), part),
        retries=int(cmems_cfg.get("retries", 3)),
        retry_wait_s=float(cmems_cfg.get("retry_wait_s", 5.0)),
        label=f"copernicusmarine.subset {request['dataset_id']}",
        before_download=check_credentials,
    )


def currents(cfg: Mapping, cache_dir: str | os.PathLike) -> xr.Dataset:
    """Canonical currents (and, if ``sources.tides``, tides) for the configured region.

    Parameters
    ----------
    cfg : Mapping
        The validated config (``cmems``, ``region``, ``sources.tides``).
    cache_dir : str or os.PathLike
        Folder of completed downloads; reruns reuse its files.

    Returns
    -------
    xarray.Dataset
        ``u``, ``v`` (m s-1) and optionally ``u_tide``, ``v_tide``; attrs ``source="cmems"``,
        ``source_files``, ``request`` (JSON), ``dataset_id``, ``dataset_version``,
        ``toolbox_version`` (and ``tide_request``, ``tide_dataset_id``,
        ``tide_dataset_version``).

    Raises
    ------
    CredentialsError
        A download is needed and no credentials are found, or they are rejected.
    DataError
        A download failed, or the data do not cover the region.
    """
    import copernicusmarine

    from .files import attach_tides

    c = cfg["cmems"]
    region = cfg["region"]
    request = build_request(cfg, c["dataset_id"], c.get("dataset_version"),
                            CURRENT_VARIABLES, with_depth=True)
    path = fetch(cfg, request, cache_dir)
    ds = read(path, "currents", ("u", "v"), bbox=region["bbox"], time=region["time"],
              max_depth=region["max_depth_m"])
    paths = [path]
    attrs = {
        "request": to_json(request),
        "dataset_id": c["dataset_id"],
        "dataset_version": c.get("dataset_version") or "default",
        "toolbox_version": copernicusmarine.__version__,
    }
    if cfg["sources"]["tides"]:
        tide_request = build_request(cfg, c["tide_dataset_id"], c.get("tide_dataset_version"),
                                     TIDE_VARIABLES, with_depth=False)
        tide_path = fetch(cfg, tide_request, cache_dir)
        tides = read(tide_path, "currents", ("u_tide", "v_tide"), bbox=region["bbox"],
                     time=region["time"])
        ds = attach_tides(ds, tides, str(tide_path))
        paths.append(tide_path)
        attrs.update({
            "tide_request": to_json(tide_request),
            "tide_dataset_id": c["tide_dataset_id"],
            "tide_dataset_version": c.get("tide_dataset_version") or "default",
        })
    ds.attrs = {**{k: v for k, v in ds.attrs.items() if k != "source_files"},
                "source": "cmems", "source_files": to_json(file_records(paths)), **attrs}
    return ds
