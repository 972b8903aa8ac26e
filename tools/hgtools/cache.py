"""The one cache of settled states (a scene's grains poured and settled, about half of a run's
cost), shared by all clones on a machine:

    ${HYBRID_CACHE:-~/.cache/hybrid-granular}/<kind>/<label>_<params key>_<sources key>/<file>

with one keying rule: the params key is the SHA-1 of the parameters as sorted JSON, the sources key
the SHA-1 of the files that make the state (the deck, and the driver when it writes the initial
grains), 10 hex digits each. A source may be a (file, marker) pair: only the part of the file before
the first line holding the marker makes the state (a deck whose later stages run from the cached
state), so editing those stages keeps the cache. Next to the state file, `prep.json` may hold what the preparation
measured.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path


def root(override: str | Path | None = None) -> Path:
    """The cache directory: `override` (a driver's --cache-dir), else $HYBRID_CACHE, else
    ~/.cache/hybrid-granular."""
    if override is not None:
        return Path(override)
    return Path(os.environ.get("HYBRID_CACHE", str(Path.home() / ".cache" / "hybrid-granular")))


def digest(data: bytes) -> str:
    return hashlib.sha1(data).hexdigest()[:10]


def source_bytes(source) -> bytes:
    """The bytes of a source that make a cached state: a file, or a (file, marker) pair for the
    part of the file before the first line holding the marker (a marker it lacks is an error)."""
    if isinstance(source, tuple):
        path, marker = source
        text = Path(path).read_bytes()
        at = text.find(marker.encode())
        if at < 0:
            raise ValueError(f"{path} has no line holding {marker!r}: the cache key cannot tell its stages apart")
        return text[:text.rfind(b"\n", 0, at) + 1]
    return Path(source).read_bytes()


@dataclass(frozen=True)
class Settled:
    """One entry: the state file and its preparation record."""
    path: Path

    @classmethod
    def entry(cls, kind: str, label: str, params: dict, sources: tuple, file: str,
              override: str | Path | None = None) -> "Settled":
        key = digest(json.dumps(params, sort_keys=True).encode())
        made = digest(b"".join(source_bytes(p) for p in sources))
        return cls(root(override) / kind / f"{label}_{key}_{made}" / file)

    @property
    def info_path(self) -> Path:
        return self.path.with_name("prep.json")

    def cached(self, with_info: bool = False) -> bool:
        return self.path.exists() and (not with_info or self.info_path.exists())

    def info(self) -> dict:
        return json.loads(self.info_path.read_text())

    def store(self, produced: Path, info: dict | None = None) -> None:
        """Keeps the state a run produced (and its record)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if Path(produced).resolve() != self.path.resolve():
            shutil.copyfile(produced, self.path)
        if info is not None:
            self.info_path.write_text(json.dumps(info, indent=1))
