# SPDX-License-Identifier: MIT
"""The shared test vectors (vectors/*.json at the repository root), read for the tests.

A vector file that does not exist gives None, which the tests turn into an error naming it; a file
that exists but is not valid JSON fails loudly.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[3]
VECTORS = REPO / "vectors"


def load(filename: str) -> dict[str, Any] | None:
    """The parsed vector file, or None if it does not exist."""
    path = VECTORS / filename
    if not path.exists():
        return None
    data = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise ValueError(f"{path}: the top level must be an object")
    return data


def section(filename: str, key: str) -> list[dict[str, Any]] | None:
    """The list under `key` in a vector file; None if the file does not exist, [] if it has no such list."""
    data = load(filename)
    if data is None:
        return None
    entries = data.get(key, [])
    if not isinstance(entries, list) or not all(isinstance(entry, dict) for entry in entries):
        raise ValueError(f"{VECTORS / filename}: {key!r} must be a list of objects")
    return entries


def hex_bytes(text: str) -> bytes:
    """Bytes from the vectors' hex text ("10 01 00 11"; spaces optional)."""
    return bytes.fromhex(text)
