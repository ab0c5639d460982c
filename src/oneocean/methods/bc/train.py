"""Fit the BC network by MSE on the teacher's actions (:mod:`.fit`: a relu MLP and Adam).

The fit is this package's own, a few hundred lines of ``numba`` loops, not a library's:
the network is a few thousand weights and the training set a few hundred thousand rows, so
it trains in about the time scikit-learn's ``MLPRegressor`` needs (whose semantics it
keeps: initialisation, minibatch order, gradients and Adam steps agree with it to rounding),
and it owns the order of every floating-point sum.

Determinism: the weights file and the training report are a function of the dataset and
``seed`` only, byte for byte, whatever the thread count and whatever BLAS kernels, SIMD
width and FMA support the machine's x86-64 CPU has. The initial weights and every epoch's
shuffle draw from one ``RandomState(seed)``; every reduction (forward pass, gradients,
losses, the features' mean and standard deviation) is a loop in one fixed order (:mod:`.fit`
says how). The features are :func:`oneocean.tasks.learned.features_rows`, the loop's own;
their one transcendental function, ``log1p``, is the C library's, so a libm whose ``log1p``
rounds differently (glibc's variant for CPUs without FMA does, in the last bit, for some
inputs) gives different features in those rows and so different weights.

Protocol: the validation set is whole episodes (the last ``val_fraction`` of each (task,
tier, seed)'s episodes), never rows of a training episode. Training runs ``epochs`` passes,
recording the training and validation MSE after each; the weights of the epoch with the
lowest validation MSE are kept (early stopping without a patience knob). Targets are actions
divided by the vehicle's ``v_max`` (:mod:`oneocean.tasks.learned`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...errors import ConfigError
from ...tasks.common import ACT_FIELDS, OBS_FIELDS
from ...tasks.learned import N_BASE, feature_names, features_rows
from .dataset import EXTRA_FIELDS


def task_order(tasks) -> list[str]:
    """Dataset tasks in the registry's canonical order (the one-hot's order).

    Parameters
    ----------
    tasks : iterable of str
        The dataset's task ids.

    Returns
    -------
    list of str
        The distinct tasks, registered ones in registry order, then unknown ones sorted.
    """
    from ...registry import task_ids

    known = list(task_ids())
    present = set(map(str, tasks))
    return [t for t in known if t in present] + sorted(present - set(known))


def features(df: pd.DataFrame, tasks: list[str]) -> np.ndarray:
    """The features of the dataset rows, as the loop computes them.

    :func:`oneocean.tasks.learned.features_rows`, the loop's own, per task.

    Parameters
    ----------
    df : DataFrame
        Dataset rows with the observation fields and ``task`` (:mod:`.dataset`).
    tasks : list of str
        The one-hot's tasks, in order (:func:`task_order`).

    Returns
    -------
    (R, F) float64
        ``F = N_BASE + len(tasks)`` features per row.
    """
    obs = np.ascontiguousarray(df[list(OBS_FIELDS + EXTRA_FIELDS)].to_numpy(np.float64))
    out = np.zeros((len(df), N_BASE + len(tasks)))
    task_idx = df["task"].map({t: j for j, t in enumerate(tasks)}).to_numpy(np.int64)
    t_lim = df["t_lim_s"].to_numpy(np.float64)
    for j in range(len(tasks)):
        for tl in np.unique(t_lim[task_idx == j]):
            rows = np.flatnonzero((task_idx == j) & (t_lim == tl))
            block = np.zeros((rows.size, out.shape[1]))
            features_rows(np.ascontiguousarray(obs[rows]), float(tl), j, len(tasks), block)
            out[rows] = block
    return out


def targets(df: pd.DataFrame) -> np.ndarray:
    """The teacher's actions in units of the vehicle's speed limit.

    Parameters
    ----------
    df : DataFrame
        Dataset rows with the action fields (m s-1) and ``v_max_ms``.

    Returns
    -------
    (R, 3) float64
        Action / ``v_max`` (world frame, through the water).
    """
    return df[list(ACT_FIELDS)].to_numpy(np.float64) / df["v_max_ms"].to_numpy(np.float64)[:, None]


def validation_mask(df: pd.DataFrame, val_fraction: float) -> np.ndarray:
    """The rows of validation episodes.

    Per (task, tier, seed) the last ``ceil(val_fraction * episodes)`` episodes, keeping at
    least one training episode.

    Parameters
    ----------
    df : DataFrame
        Dataset rows (``task``, ``tier``, ``seed``, ``episode``).
    val_fraction : float
        Share of each group's episodes held out, in (0, 1).

    Returns
    -------
    (R,) bool
        True for rows of validation episodes.
    """
    val = np.zeros(len(df), dtype=bool)
    for _, g in df.groupby(["task", "tier", "seed"], sort=True):
        eps = np.unique(g["episode"].to_numpy())
        n_val = min(int(np.ceil(float(val_fraction) * eps.size)), eps.size - 1)
        if n_val > 0:
            val[g.index[np.isin(g["episode"].to_numpy(), eps[-n_val:])]] = True
    return val


def train(df: pd.DataFrame, *, hidden=(64, 64), epochs: int = 40, batch_size: int = 256,
          learning_rate: float = 1e-3, alpha: float = 1e-5, val_fraction: float = 0.2,
          seed: int = 0):
    """Fit the network on a dataset (:mod:`.dataset`).

    Parameters
    ----------
    df : DataFrame
        The dataset rows.
    hidden : sequence of int, optional
        Hidden layer widths (default ``(64, 64)``).
    epochs : int, optional
        Passes over the training rows (default 40); the best-validation epoch is kept.
    batch_size : int, optional
        Minibatch rows (default 256).
    learning_rate : float, optional
        Adam step size (default 1e-3).
    alpha : float, optional
        L2 penalty (default 1e-5).
    val_fraction : float, optional
        Share of each (task, tier, seed)'s episodes held out for validation, in (0, 1)
        (default 0.2; :func:`validation_mask`).
    seed : int, optional
        Seed of the initial weights and the epochs' shuffles (default 0).

    Returns
    -------
    model : :class:`.fit.MLP`
        The kept (best-validation) network; ``model.predict`` on standardised features is
        what the loop computes (:func:`oneocean.tasks.learned.forward`, the same operations in
        the same order).
    weights : dict of arrays
        :func:`oneocean.tasks.learned.load_weights`'s layout (``mu``, ``sd``, padded ``w``,
        ``b``, ``dims``, ``tasks``, ``features``).
    report : dict
        JSON-able: settings, sizes, per-epoch ``train_mse`` / ``val_mse``, ``best_epoch``,
        per-task validation MSE.

    Raises
    ------
    ConfigError
        An empty dataset, ``val_fraction`` outside (0, 1), or no validation episodes.
    """
    from .fit import Fit, column_stats, mse

    if len(df) == 0:
        raise ConfigError("bc train: the dataset has no rows")
    if not 0 < float(val_fraction) < 1:
        raise ConfigError(f"bc.val_fraction must be in (0, 1), got {val_fraction}")
    df = df.reset_index(drop=True)
    tasks = task_order(df["task"].unique())
    X = features(df, tasks)
    Y = targets(df)
    val = validation_mask(df, val_fraction)
    if not val.any():
        raise ConfigError("bc train: no validation episodes (every cell has one episode); "
                          "raise bc.episodes")
    mu, sd = np.empty(X.shape[1]), np.empty(X.shape[1])
    column_stats(X, np.flatnonzero(~val).astype(np.int64), mu, sd)
    Z = (X - mu) / sd
    Ztr, Ytr, Zva, Yva = Z[~val], Y[~val], Z[val], Y[val]
    fit = Fit(Ztr, Ytr, hidden, batch_size=batch_size, learning_rate=learning_rate,
              alpha=alpha, rng=np.random.RandomState(int(seed)))
    n_y = Y.shape[1]
    train_mse, val_mse = [], []
    best = (np.inf, -1, None)
    for epoch in range(int(epochs)):
        fit.epoch()
        model = fit.model()
        train_mse.append(mse(model.squared_errors(Ztr, Ytr), n_y))
        val_mse.append(mse(model.squared_errors(Zva, Yva), n_y))
        if val_mse[-1] < best[0]:
            best = (val_mse[-1], epoch, model)
    model = best[2]
    sq_va = model.squared_errors(Zva, Yva)
    task_va = df["task"].to_numpy()[val]
    per_task = {t: mse(sq_va[task_va == t], n_y) for t in tasks if (task_va == t).any()}
    weights = export_weights(model, mu, sd, tasks)
    report = {"method": "bc", "library": "oneocean.methods.bc.fit (fixed-order MLP, Adam)",
              "tasks": tasks, "features": list(feature_names(tasks)),
              "hidden": [int(h) for h in hidden], "activation": "relu", "epochs": int(epochs),
              "batch_size": int(batch_size), "learning_rate": float(learning_rate),
              "alpha": float(alpha), "seed": int(seed), "val_fraction": float(val_fraction),
              "n_train": int((~val).sum()), "n_val": int(val.sum()),
              "target": "teacher action / v_max (world frame, through the water)",
              "train_mse": train_mse, "val_mse": val_mse, "best_epoch": int(best[1]) + 1,
              "best_val_mse": float(best[0]), "val_mse_by_task": per_task}
    return model, weights, report


def export_weights(model, mu: np.ndarray, sd: np.ndarray, tasks: list[str]) -> dict:
    """The network as a weights file's arrays, with the features' standardisation and names.

    The layers in :class:`oneocean.tasks.learned.LearnedNet`'s padded layout.

    Parameters
    ----------
    model : MLP
        The network (:class:`.fit.MLP`).
    mu, sd : (F,) float64
        The features' mean and standard deviation over the training rows.
    tasks : list of str
        The one-hot's tasks, in order.

    Returns
    -------
    dict
        ``mu``, ``sd``, ``w``, ``b``, ``dims``, ``tasks``, ``features``
        (:data:`oneocean.tasks.learned.WEIGHT_KEYS`).
    """
    return {"mu": np.asarray(mu, np.float64), "sd": np.asarray(sd, np.float64),
            "w": np.array(model.w, np.float64), "b": np.array(model.b, np.float64),
            "dims": np.asarray(model.dims, np.int64), "tasks": np.asarray(tasks, dtype="U16"),
            "features": np.asarray(feature_names(tasks), dtype="U32")}


def plot_loss(report: dict, out_png) -> None:
    """Plot the training report's loss curves: train and validation MSE per epoch.

    The kept epoch is marked; written as PNG and as PDF beside it, atomically and byte-stable
    (no time or software metadata).

    Parameters
    ----------
    report : dict
        The training report (:func:`train`).
    out_png : path
        The PNG file; the PDF gets the same name with ``.pdf``.
    """
    from pathlib import Path

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ...io import atomic_path

    ep = np.arange(1, len(report["train_mse"]) + 1)
    fig = Figure(figsize=(4.5, 3.0), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.semilogy(ep, report["train_mse"], label="train")
    ax.semilogy(ep, report["val_mse"], label="validation")
    ax.axvline(report["best_epoch"], color="0.5", ls=":", lw=1,
               label=f"kept (epoch {report['best_epoch']})")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE of action / $v_{max}$")
    ax.set_title(f"BC training ({report['n_train']} train / {report['n_val']} val rows)",
                 fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out_png = Path(out_png)
    with atomic_path(out_png, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": None})
    with atomic_path(out_png.with_suffix(".pdf"), suffix=".pdf") as tmp:
        fig.savefig(tmp, format="pdf", metadata={"Creator": None, "Producer": None,
                                                 "CreationDate": None})


def train_to_files(dataset_path, weights_path, report_path, figure_path, **settings) -> dict:
    """Read a dataset file, :func:`train`, write the weights, report and loss figure.

    The weights (``.npz``, byte-stable), the report (JSON) and the figure
    (:func:`plot_loss`) are written atomically.

    Parameters
    ----------
    dataset_path : path
        The dataset's Parquet file (:func:`.dataset.dataset_to_file`).
    weights_path : path
        The weights file to write.
    report_path : path
        The JSON report to write.
    figure_path : path
        The loss figure (PNG; a PDF beside it).
    **settings
        Keyword arguments of :func:`train`.

    Returns
    -------
    dict
        The training report.
    """
    from ...io import write_json_atomic, write_npz_atomic

    df = pd.read_parquet(dataset_path)
    _, weights, report = train(df, **settings)
    write_npz_atomic(weights_path, weights)
    write_json_atomic(report_path, report)
    plot_loss(report, figure_path)
    return report
