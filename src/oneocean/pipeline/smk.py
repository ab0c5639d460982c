"""The thin adapter every ``workflow/scripts/*.py`` uses: log, run one function, record
provenance."""

from __future__ import annotations

import contextlib
import logging
import sys
import traceback
from pathlib import Path

from .manifest import write_job_provenance


def _plain(obj):
    """Snakemake Namedlists/params → plain JSON-able values."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return str(obj)


def optional_input(snakemake, name: str):
    """The path of a named input an input function may leave empty (``[]``).

    Parameters
    ----------
    snakemake : snakemake.script.Snakemake
        The job's ``snakemake`` object.
    name : str
        The input's name.

    Returns
    -------
    str or None
        The (first) path, or None when the input is missing or empty.
    """
    value = getattr(snakemake.input, name, None)
    if value is None or isinstance(value, str):
        return value or None
    value = list(value)
    return str(value[0]) if value else None


def _logger(snakemake) -> logging.Logger:
    log_path = snakemake.log[0] if len(snakemake.log) else None
    handlers = [logging.StreamHandler(sys.stderr)]
    if log_path:
        Path(log_path).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_path, mode="w"))
    logging.basicConfig(level=logging.INFO, handlers=handlers, force=True,
                        format="%(levelname)s %(name)s: %(message)s")
    # matplotlib's PDF backend subsets fonts through fontTools, which logs every glyph at INFO
    logging.getLogger("fontTools").setLevel(logging.WARNING)
    return logging.getLogger(f"oneocean.{snakemake.rule}")


def _guarded(snakemake, log, func) -> None:
    from ..errors import OneOceanError

    try:
        from ..config import register_llm_methods
        from ..registry import load_plugins

        # the workflow's plugins (tasks/methods they register) and its LLM planners exist in
        # every job's process too
        cfg = getattr(snakemake, "config", None) or {}
        load_plugins(cfg.get("plugins") or [])
        register_llm_methods(cfg)
        func(snakemake)
    except OneOceanError as err:
        log.error("%s", err)
        sys.exit(1)
    except Exception:
        log.error("%s", traceback.format_exc())
        raise


def run(snakemake, func) -> None:
    """Run ``func(snakemake)`` with logging to the job log, then write the job's provenance.

    The output named ``prov`` receives the provenance of every other output. A
    :class:`~oneocean.errors.OneOceanError` is reported as its one-line message (no traceback)
    and the job fails; Snakemake then removes the job's outputs. Before ``func``, the config's
    ``plugins`` are loaded and its LLM planners registered, as in the workflow's own process.

    Parameters
    ----------
    snakemake : snakemake.script.Snakemake
        The job's ``snakemake`` object; its outputs must include ``prov``.
    func : callable
        ``func(snakemake)``, the job's work.
    """
    log = _logger(snakemake)
    _guarded(snakemake, log, func)
    outputs = dict(snakemake.output.items())
    prov = outputs.pop("prov")
    params = {k: _plain(v) for k, v in snakemake.params.items()}
    files = [str(f) for o in outputs.values()
             for f in (o if isinstance(o, (list, tuple)) else [o])]   # a named list of files
    write_job_provenance(prov, snakemake.rule, _plain(dict(snakemake.wildcards.items())),
                         files,
                         [str(i) for i in snakemake.input], params)
    with contextlib.suppress(Exception):
        log.info("wrote %s", ", ".join(map(str, outputs.values())))


def run_cells(snakemake, func) -> None:
    """A batched job: run ``func(snakemake, cell, path)`` for every cell of the job, in order.

    ``snakemake.params.cells`` lists the cells (each a dict with its own ``wildcards`` and
    ``params``), ``snakemake.output.parquet`` and ``snakemake.output.prov`` their files in the
    same order. Each cell gets its own provenance record, as if it had been a job of its own
    (its wildcards, its output, the job's inputs, its params), so the manifest and
    ``oneocean verify`` see one entry per cell file. Errors are handled as in :func:`run`.

    Parameters
    ----------
    snakemake : snakemake.script.Snakemake
        The job's ``snakemake`` object.
    func : callable
        ``func(snakemake, cell, path)``: runs one cell (a dict of ``params.cells``) into its
        output file ``path``.

    Raises
    ------
    RuntimeError
        The numbers of cells, parquet outputs and provenance outputs differ.
    """
    log = _logger(snakemake)
    cells = list(snakemake.params.cells)
    files, provs = list(snakemake.output.parquet), list(snakemake.output.prov)
    if not len(cells) == len(files) == len(provs):
        raise RuntimeError(f"rule {snakemake.rule}: {len(cells)} cells, {len(files)} outputs, "
                           f"{len(provs)} provenance files")

    def each(s):
        for cell, path in zip(cells, files):
            func(s, cell, path)

    _guarded(snakemake, log, each)
    wildcards = _plain(dict(snakemake.wildcards.items()))
    inputs = [str(i) for i in snakemake.input]
    for cell, path, prov in zip(cells, files, provs):
        write_job_provenance(prov, snakemake.rule, {**wildcards, **_plain(cell["wildcards"])},
                             [str(path)], inputs, _plain(cell["params"]))
    with contextlib.suppress(Exception):
        log.info("wrote %d cells: %s ... %s", len(files), files[0], files[-1])
