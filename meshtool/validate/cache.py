"""The result cache of ``meshtool validate``: unchanged assets are not checked again.

An entry is keyed by the asset's path and content hash (SHA-256), the rule-set version, the meshtool version,
the options that change raw findings (the limits, the source roots) and the environment (the physics
plugin and the versions of the libraries the rules compute with). It holds the raw result, the SHA-256 of
every file the check read or looked for (MTLs, textures, a pack's sources; ``None`` for absent), and the
digest of everything under the asset's folder (:mod:`meshtool.validate.snapshot`: every name with its
case, kind, permissions and link target), since any of it can change how a reference resolves. The entry
is used only while all of them still match. Entries live in
``CACHE/ab/abcdef....json`` (written atomically); a damaged entry counts as a miss.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import json
import os
from pathlib import Path
from typing import Any

from meshtool import __version__
from meshtool.errors import OutputError
from meshtool.findings import Finding, Severity
from meshtool.outdir import write_file
from meshtool.resolve import file_sha256, read_cache
from meshtool.validate.plugins import environment
from meshtool.validate.snapshot import dependency_listings, listing_digest
from meshtool.validate.task import RULESET_VERSION, AssetResult, AssetTask


class ResultCache:
    """Cached :class:`AssetResult` objects in a folder (``None``: no cache, every lookup misses).

    Args:
        folder: The cache folder (created on the first store).
        fingerprint: The options that change raw findings (see :meth:`ValidateConfig.fingerprint`).
    """

    def __init__(self, folder: Path | None, fingerprint: dict[str, Any]) -> None:
        self.folder = folder
        self.exclude = Path(os.path.realpath(folder)) if folder is not None else None
        self.salt = json.dumps(
            {"meshtool": __version__, "rules": RULESET_VERSION, "options": fingerprint, "environment": environment()},
            sort_keys=True,
        )

    def key(self, task: AssetTask, content_sha256: str) -> str:
        """The entry key of an asset with the given content hash."""
        text = f"{self.salt}\n{task.path.resolve()}\n{content_sha256}"
        return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()  # non-UTF-8 names: raw bytes

    def lookup(self, task: AssetTask) -> AssetResult | None:
        """The cached result, if every file it depends on is unchanged (and it has a thumbnail if asked)."""
        if self.folder is None:
            return None
        digest = file_sha256(task.path)
        if digest is None:
            return None
        data = read_cache(self._file(self.key(task, digest)))
        if data is None:
            return None
        try:
            entry = json.loads(data)
            if task.thumbnails and not entry["thumbnails"]:
                return None
            own = str(task.path.resolve())  # its hash is part of the key: already checked
            for path, sha in entry["deps"].items():
                if path != own and file_sha256(Path(path)) != sha:
                    return None
            for key, listing in entry["listings"].items():
                if listing is None or listing_digest(key, self.exclude) != listing:
                    return None
            result = _from_json(entry["result"])
        except (ValueError, KeyError, TypeError):
            return None
        result.path = task.display
        result.cached = True
        return result

    def listings(self, task: AssetTask) -> dict[str, str | None]:
        """The listings a fresh result of ``task`` will be stored with (taken before the check reads anything)."""
        if self.folder is None or task.kind == "mbin":  # a pack's sources are looked up by exact path (deps)
            return {}
        return dependency_listings(task.path, self.exclude)

    def store(self, task: AssetTask, result: AssetResult) -> None:
        """Remember a fresh result (results with an internal error or a timeout are not cached)."""
        if self.folder is None or any(f.code in ("X001", "X002") for f in result.findings):
            return
        if any(listing is None for listing in result.listings.values()):  # a folder too big to list
            return
        digest = result.deps.get(str(task.path.resolve()))
        if digest is None:
            return
        entry = {
            "thumbnails": task.thumbnails,
            "deps": result.deps,
            "listings": result.listings,
            "result": _to_json(result),
        }
        with contextlib.suppress(OutputError):  # a read-only or full cache folder only costs speed
            write_file(self._file(self.key(task, digest)), json.dumps(entry, sort_keys=True).encode("utf-8"))

    def _file(self, key: str) -> Path:
        assert self.folder is not None
        return self.folder / key[:2] / f"{key}.json"


def _to_json(result: AssetResult) -> dict[str, Any]:
    return {
        "kind": result.kind,
        "findings": [f.to_dict() for f in result.findings],
        "deps": result.deps,
        "listings": result.listings,
        "stats": result.stats,
        "thumbnail": base64.b64encode(result.thumbnail).decode("ascii") if result.thumbnail else None,
        "notes": result.notes,
    }


def _from_json(data: dict[str, Any]) -> AssetResult:
    findings = [
        Finding(f["code"], Severity(f["severity"]), f["message"], f["path"], f["line"]) for f in data["findings"]
    ]
    thumbnail = base64.b64decode(data["thumbnail"]) if data["thumbnail"] else None
    return AssetResult(
        "",
        data["kind"],
        findings,
        dict(data["deps"]),
        dict(data["listings"]),
        dict(data["stats"]),
        thumbnail,
        list(data["notes"]),
    )
