"""A content-addressed cache of chat-completion replies: one JSON file per request.

The key is the sha256 of a canonical JSON of what determines the answer -- the model id (not
the base URL: the same model behind another server gives the same cached answer), the
messages, the temperature, the output-token limit, the JSON schema the reply was decoded under
(local models only) and :data:`CACHE_SCHEMA` -- so a rerun of
the same prompts makes no HTTP call and reproduces the same plans, and any change of prompt or
setting misses. A record keeps the reply's text, its token usage and the latency measured
when it was fetched, so a rerun from the cache reports the same accounting. Files are written
atomically (temporary file in the same directory, then
``os.replace``), so a crash never leaves a half-written entry under a valid key.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Sequence

from oneocean.errors import ConfigError

#: Bump when the key's contents or the stored record's layout change (old entries then miss).
CACHE_SCHEMA = 1

#: Fields a stored record must have to count as a hit.
RECORD_FIELDS = ("text", "prompt_tokens", "completion_tokens", "latency_s")


def canonical_json(obj) -> str:
    """Compact JSON with sorted keys: equal values give equal strings.

    Parameters
    ----------
    obj : object
        A JSON-able value (no NaN or infinity).

    Returns
    -------
    str
        The JSON text (non-ASCII characters kept).
    """
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=False)


def cache_key(model: str, messages: Sequence[dict], temperature: float, max_tokens: int,
              response_schema: dict | None = None) -> str:
    """The hex sha256 naming the reply to ``messages`` under these settings.

    The hash of the canonical JSON (:func:`canonical_json`) of the settings, the messages and
    :data:`CACHE_SCHEMA` (and the decoding schema, if any: without one the key is unchanged).

    Parameters
    ----------
    model : str
        Model id (not the base URL: the same model behind another server shares entries).
    messages : sequence of dict
        Chat messages.
    temperature : float
        Sampling temperature.
    max_tokens : int
        Output-token limit.
    response_schema : dict, optional
        JSON Schema the reply is decoded under (None: unconstrained).

    Returns
    -------
    str
        64 hex digits.
    """
    payload = {
        "schema": CACHE_SCHEMA,
        "model": str(model),
        "messages": [{str(k): v for k, v in m.items()} for m in messages],
        "temperature": float(temperature),
        "max_tokens": int(max_tokens),
    }
    if response_schema is not None:
        payload["response_schema"] = response_schema
    return hashlib.sha256(canonical_json(payload).encode("utf-8")).hexdigest()


def _is_record(obj) -> bool:
    """True if ``obj`` is a stored reply (text string, token counts int or None, fetch latency
    a finite number >= 0)."""
    if not isinstance(obj, dict) or not all(f in obj for f in RECORD_FIELDS):
        return False
    counts_ok = all(obj[f] is None or (isinstance(obj[f], int) and not isinstance(obj[f], bool))
                    for f in ("prompt_tokens", "completion_tokens"))
    lat = obj["latency_s"]
    latency_ok = (isinstance(lat, (int, float)) and not isinstance(lat, bool)
                  and math.isfinite(lat) and lat >= 0)
    return (isinstance(obj["text"], str) and counts_ok and latency_ok
            and obj.get("schema") == CACHE_SCHEMA)


class ResponseCache:
    """Replies stored as ``<directory>/<key>.json``.

    :meth:`get` returns the stored record or None (an unreadable or foreign file is a miss and
    is overwritten by the next :meth:`put`).

    Parameters
    ----------
    directory : str or os.PathLike
        The cache directory (created by the first :meth:`put`).
    """

    def __init__(self, directory: str | os.PathLike):
        self.directory = Path(directory)

    def __repr__(self) -> str:
        return f"ResponseCache({str(self.directory)!r})"

    def path(self, key: str) -> Path:
        """The file holding ``key``.

        Parameters
        ----------
        key : str
            A cache key (:func:`cache_key`).

        Returns
        -------
        Path
            ``<directory>/<key>.json``.
        """
        return self.directory / f"{key}.json"

    def get(self, key: str) -> dict | None:
        """The record stored under ``key``, or None.

        Parameters
        ----------
        key : str
            A cache key.

        Returns
        -------
        dict or None
            The stored record (``text``, ``prompt_tokens``, ``completion_tokens``, ``latency_s``,
            ...); None if absent, unreadable or not a record of this :data:`CACHE_SCHEMA`.
        """
        try:
            with open(self.path(key), encoding="utf-8") as fh:
                obj = json.load(fh)
        except (OSError, ValueError):
            return None
        return obj if _is_record(obj) else None

    def put(self, key: str, record: dict) -> Path:
        """Store ``record`` (plus the schema version and key) under ``key`` atomically.

        Parameters
        ----------
        key : str
            A cache key.
        record : dict
            The reply's record (:data:`RECORD_FIELDS` and the request's settings).

        Returns
        -------
        Path
            The file written.

        Raises
        ------
        ConfigError
            One line, if the directory or the entry cannot be written.
        """
        obj = {**record, "schema": CACHE_SCHEMA, "key": key}
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.directory, prefix=f".{key[:16]}.", suffix=".tmp")
        except OSError as err:
            raise ConfigError(f"llm cache directory {self.directory} is not writable: {err}") \
                from None
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(json.dumps(obj, sort_keys=True, indent=1, ensure_ascii=False))
                fh.write("\n")
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.path(key))
        except BaseException as err:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            if isinstance(err, OSError):
                raise ConfigError(f"llm cache entry {self.path(key)} could not be written: "
                                  f"{err}") from None
            raise
        return self.path(key)

    def __len__(self) -> int:
        """Number of stored entries."""
        return sum(1 for _ in self.directory.glob("*.json")) if self.directory.is_dir() else 0
