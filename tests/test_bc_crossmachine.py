"""BC training and the BC forward pass give the same bytes on other CPUs.

A rerun on the same machine cannot catch a CPU dependence: the same kernels run again. These
tests run the training in subprocesses whose environment makes them behave like other x86-64
machines, each with its own empty numba cache (a compile for one CPU is never reused), and
compare the bytes with the host's:

* ``OPENBLAS_CORETYPE``: the BLAS kernels of another CPU generation (Prescott: SSE3,
  Sandybridge: AVX, Haswell: AVX2 + FMA, SkylakeX: AVX-512), those this CPU can execute;
* ``NUMBA_CPU_NAME=generic``: numba compiles for the baseline x86-64 (SSE2, no FMA);
* ``NPY_DISABLE_CPU_FEATURES``: NumPy's ufuncs run their baseline (no AVX2 / AVX-512) loops;
* the three at once (the oldest machine);
* ``GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA,...``: glibc's libm uses its non-FMA variants
  (``log1p``, ``exp``, ``sin``, ... differ from the FMA ones in the last bit for some inputs;
  the features use :func:`oneocean.tasks.learned.log1p_pos`, plain arithmetic, instead).

Each environment's emulation is checked to be in effect (OpenBLAS reports the core it
loaded, numba the target it compiles for, NumPy its dispatched features, ld.so the CPU
features glibc uses), so a test cannot pass because an override was silently ignored.

``ONEOCEAN_TEST_BC_TRAIN=/path/to/train.py`` runs the training against another
implementation of :func:`oneocean.methods.bc.train.train` (e.g. an older revision's file).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from oneocean.methods.bc.dataset import EXTRA_FIELDS
from oneocean.tasks.common import ACT_FIELDS, OBS_FIELDS

pytestmark = pytest.mark.slow

LD_SO = "/lib64/ld-linux-x86-64.so.2"

#: OpenBLAS cores to emulate and the CPU flags (/proc/cpuinfo) each one's kernels need.
BLAS_CORES = {"Prescott": {"pni"}, "Sandybridge": {"avx"}, "Haswell": {"avx2", "fma"},
              "SkylakeX": {"avx512f", "avx512bw", "avx512dq", "avx512vl"}}

#: The names OpenBLAS reports for a core (an x86-64 build's oldest kernels are "Katmai").
BLAS_NAMES = {"Prescott": {"Prescott", "Katmai", "Coppermine", "Northwood"}}

#: glibc's hardware-capability tunable, in the spelling of glibc >= 2.33 and of older ones
#: (a name a glibc does not know is ignored).
NO_AVX2_FMA = ("glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F,-AVX512DQ,-AVX512BW,-AVX512VL,"
               "-AVX2_Usable,-FMA_Usable,-AVX512F_Usable")

#: NumPy's dispatched CPU features above the x86-64-v2 baseline (names of NumPy >= 2.4 and
#: of older ones; unknown names are ignored with a warning).
NPY_FEATURES = ("X86_V3 X86_V4 AVX512_ICL AVX512_SPR AVX2 FMA3 AVX512F AVX512CD AVX512_SKX "
                "AVX512_CLX AVX512_CNL")

CHILD = r"""
import json, sys, warnings
warnings.simplefilter("ignore")
import numpy as np, pandas as pd

dataset, fixed_weights, out, train_file = sys.argv[1:5]
if train_file:
    import importlib.util
    spec = importlib.util.spec_from_file_location("oneocean.methods.bc._train_under_test",
                                                  train_file)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    train = mod.train
else:
    from oneocean.methods.bc.train import train
from oneocean.io import write_json_atomic, write_npz_atomic
from oneocean.tasks.learned import learned_act, make_net
from oneocean.tasks.common import OBS_FIELDS
from oneocean.methods.bc.dataset import EXTRA_FIELDS

df = pd.read_parquet(dataset)
_, w, report = train(df, hidden=(64, 64), epochs=3, batch_size=64, seed=7)
write_npz_atomic(out + ".npz", w)
write_json_atomic(out + ".json", report)

# the loop's BC forward pass (features, standardisation, network, times v_max) on every
# row, with fixed weights (the parent's), so that only the forward pass can differ
from oneocean.tasks.learned import load_weights
fixed = load_weights(fixed_weights)
obs = df[list(OBS_FIELDS + EXTRA_FIELDS)].to_numpy(np.float64)
t_lim = df["t_lim_s"].to_numpy(np.float64)
act = np.zeros((len(df), 3))
for task in [str(t) for t in fixed["tasks"]]:
    net = make_net(fixed, task, 1, 1)
    for r in np.flatnonzero(df["task"].to_numpy() == task):
        act[r] = learned_act(net, t_lim[r], obs[r][None, None], 0, 0, 1.5)
np.save(out + "_act.npy", act)

facts = {}
try:
    from threadpoolctl import threadpool_info
    facts["openblas"] = sorted(str(i.get("architecture")) for i in threadpool_info()
                               if i.get("internal_api") == "openblas")
except ImportError:
    facts["openblas"] = None
try:                                    # numba internals: what it compiles for
    from numba.core.registry import cpu_target
    cg = cpu_target.target_context.codegen()
    facts["numba_cpu"] = cg._get_host_cpu_name()
    facts["numba_features"] = cg._tm_features
except Exception:
    import numba
    facts["numba_cpu"] = numba.config.CPU_NAME
    facts["numba_features"] = numba.config.CPU_FEATURES
try:
    from numpy._core._multiarray_umath import __cpu_features__ as npf
except ImportError:                     # NumPy < 2
    from numpy.core._multiarray_umath import __cpu_features__ as npf
facts["numpy_avx2"] = bool(npf["X86_V3"] if "X86_V3" in npf else npf.get("AVX2"))
with open(out + "_facts.json", "w") as fh:
    json.dump(facts, fh)
"""


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def _glibc_features(env: dict) -> str | None:
    """The CPU features glibc uses under ``env`` (``ld.so --list-diagnostics``, glibc
    >= 2.33), or None if this ld.so cannot say."""
    try:
        out = subprocess.run([LD_SO, "--list-diagnostics"], env=env, capture_output=True,
                             text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    lines = [ln for ln in out.stdout.splitlines()
             if ln.startswith("x86.cpu_features.features") and ".active[" in ln]
    return "\n".join(lines) if out.returncode == 0 and lines else None


def _environments() -> dict[str, dict]:
    """Name -> environment overrides: the host as it is, then one emulation per kind, then
    the oldest machine."""
    flags = _cpu_flags()
    envs = {"host": {}}
    cores = [c for c, need in BLAS_CORES.items() if need <= flags]
    for core in cores:
        envs[f"openblas={core}"] = {"OPENBLAS_CORETYPE": core}
    envs["numba=generic"] = {"NUMBA_CPU_NAME": "generic"}
    envs["numpy=baseline"] = {"NPY_DISABLE_CPU_FEATURES": NPY_FEATURES}
    envs["oldest"] = {"NUMBA_CPU_NAME": "generic", "NPY_DISABLE_CPU_FEATURES": NPY_FEATURES,
                      **({"OPENBLAS_CORETYPE": cores[0]} if cores else {})}
    if "fma" in flags or "avx2" in flags:
        envs["glibc=no-avx2-fma"] = {"GLIBC_TUNABLES": NO_AVX2_FMA}
    return envs


ENVS = _environments()

def _cases():
    return [n for n in ENVS if n != "host"]


def _dataset(path: Path) -> None:
    """A small teacher-like dataset: two tasks, two seeds, five episodes each, observations
    with the NaNs the loop records (no altitude, no pollution field, missing teammates) and
    a smooth nonlinear action (a speed-limited pursuit of the goal against the current)."""
    rng = np.random.RandomState(11)
    parts = []
    for task, n_mates in (("G2G", 0), ("FT", 2)):
        for seed in (100, 101):
            for episode in range(5):
                n = 120
                o = np.full((n, len(OBS_FIELDS) + len(EXTRA_FIELDS)), np.nan)
                o[:, 0:3] = rng.normal(0.0, 150.0, (n, 3)) * [1.0, 1.0, 0.1]
                o[:, 3:5] = rng.normal(0.0, 0.3, (n, 2))
                o[:, 5] = rng.uniform(0.0, 80.0, n)
                o[:, 6] = np.where(rng.uniform(size=n) < 0.2, np.nan, rng.uniform(1, 40, n))
                if task == "FT":
                    o[:, 7] = rng.exponential(2.0, n)
                for m in range(n_mates):
                    o[:, 8 + 2 * m:10 + 2 * m] = rng.normal(0.0, 20.0, (n, 2))
                o[:, 14:20] = rng.normal(0.0, 1.0, (n, 6))          # position, heading, velocity
                o[:, 20] = np.arange(n, dtype=np.float64)           # time
                o[:, 21] = rng.uniform(0.0, 50.0, n)
                o[:, 22] = 0.0
                if task == "G2G":                                   # its own two fields
                    o[:, 23] = rng.uniform(0.0, 5e4, n)
                    o[:, 24] = o[:, 23] / 6e4
                g = o[:, 0:3]
                dist = np.sqrt((g ** 2).sum(axis=1))[:, None]
                a = 2.0 * g / (dist + 25.0)
                a[:, 0] -= o[:, 3]
                a[:, 1] -= o[:, 4]
                df = pd.DataFrame({"task": task, "tier": np.int64(1), "seed": np.int64(seed),
                                   "episode": np.int64(episode), "step": np.arange(n),
                                   "agent": np.int64(0)})
                for j, name in enumerate(OBS_FIELDS + EXTRA_FIELDS):
                    df[name] = o[:, j]
                for j, name in enumerate(ACT_FIELDS):
                    df[name] = np.clip(a[:, j], -2.0, 2.0)
                df["v_max_ms"] = 2.0
                df["t_lim_s"] = 600.0
                parts.append(df)
    pd.concat(parts, ignore_index=True).to_parquet(path)


def _fixed_weights(dataset: Path, path: Path) -> None:
    """Random weights in the weights file's layout for the dataset's tasks (the forward
    pass's test input, the same for every environment)."""
    from oneocean.io import write_npz_atomic
    from oneocean.tasks.learned import feature_names
    from oneocean.methods.bc.train import features, task_order

    df = pd.read_parquet(dataset)
    tasks = task_order(df["task"].unique())
    X = features(df, tasks)
    dims = [X.shape[1], 64, 64, 3]
    rng = np.random.RandomState(5)
    w = np.zeros((3, 64, 64))
    b = np.zeros((3, 64))
    for k in range(3):
        w[k, :dims[k], :dims[k + 1]] = rng.uniform(-0.4, 0.4, (dims[k], dims[k + 1]))
        b[k, :dims[k + 1]] = rng.uniform(-0.1, 0.1, dims[k + 1])
    write_npz_atomic(path, {"mu": X.mean(axis=0), "sd": X.std(axis=0) + 0.5, "w": w, "b": b,
                            "dims": np.asarray(dims, np.int64),
                            "tasks": np.asarray(tasks, dtype="U16"),
                            "features": np.asarray(feature_names(tasks), dtype="U32")})


def _run(tmp_path: Path, name: str, overrides: dict, dataset: Path, fixed: Path,
         train_file: str) -> dict:
    out = tmp_path / name.replace("=", "_")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(out) + "_numba", "OMP_NUM_THREADS": "1",
           **overrides}
    proc = subprocess.run([sys.executable, "-c", CHILD, str(dataset), str(fixed), str(out),
                           train_file],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"{name}: {proc.stderr[-3000:]}"
    return {"weights": hashlib.sha256(Path(str(out) + ".npz").read_bytes()).hexdigest(),
            "report": json.loads(Path(str(out) + ".json").read_text()),
            "act": np.load(str(out) + "_act.npy"),
            "facts": json.loads(Path(str(out) + "_facts.json").read_text()),
            "glibc": _glibc_features(env)}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Every environment's training run (weights hash, report, forward-pass actions, what
    the emulation reported), one after the other (~4 s each)."""
    tmp = tmp_path_factory.mktemp("bc_crossmachine")
    dataset = tmp / "dataset.parquet"
    _dataset(dataset)
    fixed = tmp / "fixed_weights.npz"
    _fixed_weights(dataset, fixed)
    train_file = os.environ.get("ONEOCEAN_TEST_BC_TRAIN", "")
    return {name: _run(tmp, name, env, dataset, fixed, train_file)
            for name, env in ENVS.items()}


@pytest.mark.parametrize("name", [n for n in ENVS if n != "host"])
def test_the_emulation_is_in_effect(runs, name):
    host, r, env = runs["host"], runs[name], ENVS[name]
    core = env.get("OPENBLAS_CORETYPE")
    if core and r["facts"]["openblas"] is not None:
        assert set(r["facts"]["openblas"]) <= BLAS_NAMES.get(core, {core}), r["facts"]
    if env.get("NUMBA_CPU_NAME") == "generic":
        assert (r["facts"]["numba_cpu"], r["facts"]["numba_features"]) == ("generic", "")
        assert host["facts"]["numba_cpu"] != "generic"
    if "NPY_DISABLE_CPU_FEATURES" in env and host["facts"]["numpy_avx2"]:
        assert not r["facts"]["numpy_avx2"]
    if "GLIBC_TUNABLES" in env and host["glibc"] is not None:
        assert r["glibc"] != host["glibc"], f"glibc ignored {NO_AVX2_FMA}"


@pytest.mark.parametrize("name", _cases())
def test_training_gives_the_host_bytes(runs, name):
    """Same weights file and training report as on the host."""
    host, r = runs["host"], runs[name]
    assert host["report"]["n_val"] > 0 and len(host["report"]["val_mse"]) == 3
    assert r["report"] == host["report"]
    assert r["weights"] == host["weights"]


@pytest.mark.parametrize("name", _cases())
def test_bc_forward_pass_gives_the_host_actions(runs, name):
    """:func:`~oneocean.tasks.learned.learned_act` (features, standardisation, network) on
    every dataset row with the same fixed weights: the same action bits as on the host."""
    host, r = runs["host"], runs[name]
    assert np.isfinite(host["act"]).all() and np.abs(host["act"]).max() > 0
    assert r["act"].tobytes() == host["act"].tobytes()


LOOP_CHILD = r"""
import sys
import numpy as np
import oneocean.engine as E
from oneocean.tasks.learned import load_weights
from oneocean.tasks import Cell
from oneocean.testing import make_test_grid

grid = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
_, _, act = Cell(grid, "G2G", 1).run("bc", 2, 1000, "6dof", observations=True,
                                     net=load_weights(sys.argv[1]))
np.save(sys.argv[2], act)
"""


def test_in_loop_learned_actions_are_the_same_for_the_generic_cpu(tmp_path):
    """A small BC rollout (G2G, two episodes, fixed weights) inside the fused loop: the
    recorded actions have the same bits when numba compiles for the baseline x86-64 (a fresh
    cache: the G2G kernel is compiled again, ~20 s) as here."""
    import oneocean.engine as E
    from oneocean.io import write_npz_atomic
    from oneocean.tasks.learned import load_weights
    from oneocean.tasks.learned import feature_names
    from oneocean.tasks import Cell
    from oneocean.testing import make_test_grid

    tasks = ["G2G"]
    dims = [len(feature_names(tasks)), 32, 32, 3]
    rng = np.random.RandomState(8)
    w = np.zeros((3, 32, 32))
    b = np.zeros((3, 32))
    for k in range(3):
        w[k, :dims[k], :dims[k + 1]] = rng.uniform(-0.5, 0.5, (dims[k], dims[k + 1]))
        b[k, :dims[k + 1]] = rng.uniform(-0.1, 0.1, dims[k + 1])
    path = tmp_path / "w.npz"
    write_npz_atomic(path, {"mu": np.zeros(dims[0]), "sd": np.full(dims[0], 3.0), "w": w,
                            "b": b, "dims": np.asarray(dims, np.int64),
                            "tasks": np.asarray(tasks, dtype="U16"),
                            "features": np.asarray(feature_names(tasks), dtype="U32")})
    grid = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    _, _, act = Cell(grid, "G2G", 1).run("bc", 2, 1000, "6dof", observations=True,
                                         net=load_weights(path))
    env = {**os.environ, "NUMBA_CPU_NAME": "generic",
           "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    proc = subprocess.run([sys.executable, "-c", LOOP_CHILD, str(path),
                           str(tmp_path / "act.npy")], env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    generic = np.load(tmp_path / "act.npy")
    assert np.isfinite(act).sum() > 100
    assert generic.tobytes() == act.tobytes()
