"""A local GGUF model as the planner's backend, through ``llama-cpp-python`` (optional).

:class:`LocalClient` has the endpoint client's interface (``complete(messages) -> Reply``,
the same :class:`~oneocean.methods.llm.cache.ResponseCache` in front:
:class:`~oneocean.methods.llm.client.CachedClient`): ``llama_cpp.Llama(model_path=...,
seed=0, verbose=False)`` loaded once when the client is built, then
``create_chat_completion(messages, temperature=0, max_tokens=...)`` per uncached request, its
``usage`` field giving the token counts. ``llama_cpp`` is imported only here, when a model
path is configured; without it, or with a model file that does not load, building the client
is a one-line :class:`~oneocean.errors.ConfigError`. A failure while answering is an
:class:`~oneocean.methods.llm.client.LLMError` (kind ``bad_response``): the planner falls
back. There is no timeout: generation is bounded by ``max_tokens``.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from oneocean.errors import ConfigError

from .cache import ResponseCache
from .client import CachedClient, LLMError, parse_completion


@dataclass(frozen=True)
class LocalConfig:
    """A local model: its file, the model id naming it in the cache key, the output limit.

    Parameters
    ----------
    model_path : str
        The GGUF model file (``~`` expanded).
    model : str
        Model id in the cache key.
    max_tokens : int, optional
        Output-token limit (default 256).
    temperature : float, optional
        Sampling temperature (default 0).
    """

    model_path: str
    model: str
    max_tokens: int = 256
    temperature: float = 0.0


def import_llama():
    """The ``llama_cpp`` module, imported on demand.

    Returns
    -------
    module
        ``llama_cpp``.

    Raises
    ------
    ConfigError
        One line, if ``llama-cpp-python`` is not installed.
    """
    try:
        return importlib.import_module("llama_cpp")
    except ImportError:
        raise ConfigError("model_cfg.model_path is set but llama_cpp is not installed: "
                          "pip install llama-cpp-python") from None


class LocalClient(CachedClient):
    """Chat completions from a local GGUF model (module doc).

    Parameters
    ----------
    config : LocalConfig
        The model.
    cache : ResponseCache, optional
        The response cache (None: every call runs the model).

    Raises
    ------
    ConfigError
        One line, if the model file is missing, ``llama_cpp`` is not installed, or the model
        does not load.
    """

    def __init__(self, config: LocalConfig, cache: ResponseCache | None = None):
        self.config = config
        self.cache = cache
        path = Path(config.model_path).expanduser()
        if not path.is_file():
            raise ConfigError(f"model_cfg.model_path: no model file at {path}")
        llama_cpp = import_llama()
        try:
            self._llm = llama_cpp.Llama(model_path=str(path), seed=0, verbose=False)
        except Exception as err:  # noqa: BLE001 - any load failure is a configuration error
            raise ConfigError(f"model_cfg.model_path: cannot load {path}: "
                              f"{type(err).__name__} {err}") from None

    def __repr__(self) -> str:
        return (f"LocalClient(model={self.config.model!r}, "
                f"model_path={self.config.model_path!r}, cache={self.cache!r})")

    def fetch(self, messages: Sequence[dict]) -> tuple[str, int | None, int | None]:
        """One chat completion of the local model at the configured temperature (0 by default).

        Parameters
        ----------
        messages : sequence of dict
            Chat messages.

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
        try:
            out = self._llm.create_chat_completion([dict(m) for m in messages],
                                                   temperature=float(cfg.temperature),
                                                   max_tokens=int(cfg.max_tokens))
        except Exception as err:  # noqa: BLE001 - the planner falls back, never crashes
            raise LLMError("bad_response", f"llm: local model failed: {type(err).__name__} "
                                           f"{err}") from None
        return parse_completion(out)
