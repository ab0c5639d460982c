"""The ocean-environment product: :mod:`.build` merges bathymetry and currents into one CF
NetCDF (or zarr) per region and variant; :mod:`.exports` writes the core backend's grid and the
scene backend's temporal export; :mod:`.ncio` and :mod:`.zarrio` read and write them;
:mod:`.defaults` builds the embedded default region on first use. The data sources are
:mod:`oneocean.sources`."""
