"""Float64 math outside the jitted kernels gives the same bits on every x86-64 CPU.

NumPy picks its float64 ``sin``/``cos``/``exp``/``log``/``tanh`` loops by CPU (AVX2, AVX-512)
and sends ``arctan2``, ``arcsin``, ``power``... to SVML on AVX-512; these disagree in the last
bits, so a synthetic region, an episode's start or a model built with them differed between
machines. :mod:`oneocean.engine.libm` is the C library's scalar function on every element.
These tests check its values, that no module outside the jitted kernels calls NumPy's
versions (nor BLAS: a 1-D ``np.linalg.norm``, ``np.dot``, ``@``), and that the synthetic region
and the episode models give the host's bytes with NumPy restricted to its baseline loops and
OpenBLAS to its generic kernels (what an older CPU runs; on an AVX-512 host this also
switches SVML off).
"""

from __future__ import annotations

import ast
import hashlib
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from oneocean.engine import libm

SRC = Path(__file__).parents[1] / "src" / "oneocean"

#: NumPy's float64 ufuncs whose loops differ between CPUs (NumPy's __cpu_targets_info__ lists
#: an AVX2 or AVX-512 version of each); sqrt, hypot, floor... are exact or not dispatched.
DISPATCHED = {"sin", "cos", "tan", "exp", "exp2", "expm1", "log", "log2", "log10", "log1p",
              "tanh", "sinh", "cosh", "arcsin", "arccos", "arctan", "arctan2", "arcsinh",
              "arccosh", "arctanh", "power", "cbrt"}

#: Calls that reach BLAS (a 1-D ``norm`` is ``dot``), whose kernels differ by CPU (measured:
#: OpenBLAS's generic x86-64 kernels give another ``norm`` of 3-vectors than its AVX ones in
#: 6 % of cases); ``norm`` with ``axis`` is NumPy's own reduction.
BLAS_CALLS = {"np.dot", "np.vdot", "np.inner", "np.matmul", "np.linalg.norm"}

#: Decorators of compiled functions (math.* there already is the C library's).
JIT_DECORATORS = {"njit", "jit", "hot_kernel", "vectorize", "guvectorize", "cfunc"}

UNARY = {"sin": math.sin, "cos": math.cos, "exp": math.exp, "tanh": math.tanh,
         "arctan": math.atan}


def _inputs(n: int = 20000) -> np.ndarray:
    rng = np.random.default_rng(7)
    return np.concatenate([rng.uniform(-60.0, 60.0, n), rng.normal(0.0, 1e-3, n // 4),
                           [0.0, -0.0, 1e-300, -1e-300, 1e6, -1e6, np.pi, -np.pi]])


@pytest.mark.parametrize("name", sorted(UNARY))
def test_unary_functions_are_the_c_librarys_bits(name):
    x = _inputs()
    if name == "exp":
        x = x[np.abs(x) < 700.0]                    # Python's math.exp raises on overflow
    got = getattr(libm, name)(x)
    want = np.array([UNARY[name](v) for v in x])
    assert got.dtype == np.float64 and got.shape == x.shape
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))


def test_log_family_and_arcsin_follow_c_at_the_domain_edges():
    p = np.abs(_inputs()) + 1e-12
    assert np.array_equal(libm.log(p), np.array([math.log(v) for v in p]))
    assert np.array_equal(libm.log1p(p), np.array([math.log1p(v) for v in p]))
    s = np.linspace(-1.0, 1.0, 4001)
    assert np.array_equal(libm.arcsin(s), np.array([math.asin(v) for v in s]))
    with np.errstate(all="ignore"):
        assert libm.log(0.0) == -math.inf
        assert math.isnan(libm.log(-1.0)) and math.isnan(libm.arcsin(1.5))
        assert libm.log1p(-1.0) == -math.inf


def test_binary_functions_broadcast_and_match_the_c_library():
    rng = np.random.default_rng(3)
    y = rng.uniform(-5.0, 5.0, (40, 1))
    x = rng.uniform(-5.0, 5.0, (1, 30))
    got = libm.arctan2(y, x)
    assert got.shape == (40, 30)
    assert got[7, 11] == math.atan2(y[7, 0], x[0, 11])
    assert np.array_equal(got, np.array([[math.atan2(a, b) for b in x[0]] for a in y[:, 0]]))
    assert libm.arctan2(0.0, -1.0) == math.pi and libm.arctan2(-0.0, -1.0) == -math.pi
    u = rng.uniform(0.0, 3.0, 500)
    assert np.array_equal(libm.power(u, 3.0), np.array([math.pow(v, 3.0) for v in u]))


def test_scalars_give_floats_and_arrays_keep_their_shape():
    assert type(libm.sin(0.5)) is float and libm.sin(0.5) == math.sin(0.5)
    assert type(libm.arctan2(1.0, 2.0)) is float
    a = np.arange(12, dtype=np.float32).reshape(3, 4)[:, ::2]        # float32, not contiguous
    out = libm.cos(a)
    assert out.shape == (3, 2) and out.dtype == np.float64
    assert out[2, 1] == math.cos(float(a[2, 1]))
    assert libm.exp(np.empty((0, 3))).shape == (0, 3)
    x = np.array([1.0, 2.0])
    libm.exp(x)
    assert np.array_equal(x, [1.0, 2.0])                                 # input untouched


def test_numba_does_not_use_svml():
    # with Intel's SVML numba vectorises math.sin & co. in every kernel, CPU-dependently
    import numba
    assert not numba.config.USING_SVML


def _is_jitted(node: ast.FunctionDef) -> bool:
    for d in node.decorator_list:
        f = d.func if isinstance(d, ast.Call) else d
        name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
        if name in JIT_DECORATORS:
            return True
    return False


def _numpy_calls_outside_jit(tree: ast.AST) -> list[tuple[int, str]]:
    found = []

    def visit(node, jitted):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            jitted = jitted or _is_jitted(node)
        if not jitted and isinstance(node, ast.Call):
            name = ast.unparse(node.func)
            if name.startswith("np.") and name[3:] in DISPATCHED:
                found.append((node.lineno, name))
            elif name in BLAS_CALLS and not any(k.arg == "axis" for k in node.keywords):
                found.append((node.lineno, name))
        if not jitted and isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            found.append((node.lineno, "@"))
        for child in ast.iter_child_nodes(node):
            visit(child, jitted)

    visit(tree, False)
    return found


def test_the_scanner_finds_a_numpy_call_and_spares_jitted_code():
    tree = ast.parse("import numpy as np\n"
                     "def f(x):\n    return np.sin(x)\n"
                     "@hot_kernel(inline='always')\ndef g(x):\n    return np.arctan2(x, 1.0)\n"
                     "@njit\ndef h(x):\n    return np.exp(x)\n"
                     "y = np.power(2.0, 0.3)\n"
                     "z = np.linalg.norm(v) + np.linalg.norm(w, axis=1) + a @ b\n")
    assert sorted(_numpy_calls_outside_jit(tree)) == [(3, "np.sin"), (10, "np.power"),
                                                      (11, "@"), (11, "np.linalg.norm")]


def test_no_module_calls_numpys_cpu_dispatched_math_outside_jitted_kernels():
    # test-only modules: oneocean.testing builds fixtures, engine.reference is the plain-NumPy
    # twin the kernels are checked against; their values never reach an artifact
    test_only = {SRC / "testing.py", SRC / "engine" / "reference.py"}
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        if path in test_only:
            continue
        for line, call in _numpy_calls_outside_jit(ast.parse(path.read_text(), str(path))):
            offenders.append(f"{path.relative_to(SRC.parent)}:{line} {call}")
    assert not offenders, "use oneocean.engine.libm instead:\n" + "\n".join(offenders)


CHILD = r"""
import hashlib, json, sys, warnings
warnings.simplefilter("ignore")
import numpy as np
from numpy._core._multiarray_umath import __cpu_targets_info__ as info
sys.path.insert(0, sys.argv[1])
from test_synthetic import small_config
from oneocean.sources.synthetic import make_bathymetry, make_currents
from oneocean.models.fish import init_school
from oneocean.models.pollution import make_spill
from oneocean.tasks.routing import power_model

def h(*arrays):
    d = hashlib.sha256()
    for a in arrays:
        d.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return d.hexdigest()

cfg = small_config()
bat, cur = make_bathymetry(cfg).compute(), make_currents(cfg).compute()
out = {"loops": {k: info[k]["dd"]["current"] for k in ("sin", "tanh", "exp")},
       "bathymetry": h(*(bat[v].values for v in sorted(bat.data_vars))),
       "currents": h(*(cur[v].values for v in sorted(cur.data_vars))),
       "school": h(*init_school(400, (120.0, -35.0), 80.0, [4, 2, 9])),
       "spill": h(make_spill(60, 50, 10.0, (300.0, 240.0), 90.0, 5.0,
                             rng=np.random.default_rng(5))),
       "power": h(power_model("remus100").power(np.linspace(0.0, 2.5, 301)))}
print(json.dumps(out))
"""


def _child(env_extra: dict, tmp_path: Path, name: str) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / f"numba-{name}"), **env_extra}
    res = subprocess.run([sys.executable, "-c", CHILD, str(Path(__file__).parent)], env=env,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_region_and_episode_models_give_the_host_bytes_on_numpys_baseline_loops(tmp_path):
    from test_bc_crossmachine import NPY_FEATURES
    host = _child({}, tmp_path, "host")
    base = _child({"NPY_DISABLE_CPU_FEATURES": NPY_FEATURES, "OPENBLAS_CORETYPE": "Prescott"},
                  tmp_path, "baseline")
    assert set(base["loops"].values()) == {"baseline(X86_V2)"}, base["loops"]   # in effect
    for key in ("bathymetry", "currents", "school", "spill", "power"):
        assert base[key] == host[key], key
