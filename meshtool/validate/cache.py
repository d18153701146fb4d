"""The result cache of ``meshtool validate``: unchanged assets are not checked again.

An entry is keyed by the asset's path and content hash (SHA-256), the rule-set version, the meshtool version,
the options that change raw findings (the source roots; the asset's own limits, units and up axis, which
per-path settings may give it: :meth:`AssetTask.settings`), the environment (the physics plugin and the
versions of the libraries the rules compute with) and, for a mesh, what the description files under its
consumer index root say about it (:func:`meshtool.validate.snapshot.consumer_state`: every URDF/SDF/MJCF that
uses it, with its SHA-256, taken before the check reads anything). Nothing a report format asks for is part of
the key: one entry serves every format. It holds the raw result (its thumbnail when one was drawn), the
SHA-256 of every file the check read or looked for (MTLs, textures, a pack's sources; ``None`` for absent),
and the digest of everything under the asset's folder (:mod:`meshtool.validate.snapshot`: every name with its
case, kind, permissions and link target), since any of it can change how a reference resolves. The entry is
used only while all of them still match. Entries live in ``CACHE/ab/abcdef....json``: a
:mod:`meshtool.files.cachefile` envelope (the digest of the key it answers and of its content) around the
JSON, written atomically. A damaged entry, one copied from another key or one that does not hold a result is a
miss (described in :attr:`ResultCache.problems`), and the asset is checked again.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import os
from pathlib import Path
from typing import Any

from meshtool import __version__
from meshtool.files import cachefile
from meshtool.files.resolve import file_sha256
from meshtool.findings import Finding, Severity
from meshtool.validate.physics import environment
from meshtool.validate.snapshot import consumer_state, dependency_listings, listing_digest
from meshtool.validate.task import RULESET_VERSION, AssetResult, AssetTask


class ResultCache:
    """Cached :class:`AssetResult` objects in a folder (``None``: no cache, every lookup misses).

    Args:
        folder: The cache folder (created on the first store).
        fingerprint: The options that change raw findings (see :meth:`ValidateConfig.fingerprint`).

    Attributes:
        problems: One line per entry found but not used (damaged, answering another key, not a result).
        hits: Lookups answered from the cache.
        misses: Lookups that found no usable entry (the asset is checked).
    """

    #: Entry kind in the :mod:`meshtool.files.cachefile` envelope.
    KIND = "meshtool-validate-result"

    def __init__(self, folder: Path | None, fingerprint: dict[str, Any]) -> None:
        self.folder = folder
        self.problems: list[str] = []
        self.hits = 0
        self.misses = 0
        self.exclude = Path(os.path.realpath(folder)) if folder is not None else None
        self._consumers: dict[Path, str] = {}  # mesh (resolved) -> consumer_state, taken at lookup
        self._contents: dict[Path, str] = {}  # description file -> sha256, hashed once a run
        self.salt = json.dumps(
            {"meshtool": __version__, "rules": RULESET_VERSION, "options": fingerprint, "environment": environment()},
            sort_keys=True,
        )

    def key(self, task: AssetTask, content_sha256: str) -> str:
        """The entry key of an asset with the given content hash (and, for a mesh, its consumers' state)."""
        settings = json.dumps(task.settings(), sort_keys=True)
        text = f"{self.salt}\n{settings}\n{task.path.resolve()}\n{content_sha256}\n{self.consumers(task)}"
        return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()  # non-UTF-8 names: raw bytes

    def consumers(self, task: AssetTask) -> str:
        """:func:`~meshtool.validate.snapshot.consumer_state` of a mesh, taken once a run (``""`` for a pack).

        Taken at the first lookup, before the check reads: a consumer edited during the check is news next run.
        """
        if task.kind == "mbin":  # a pack's findings do not depend on who uses its sources
            return ""
        path = task.path.resolve()
        state = self._consumers.get(path)
        if state is None:
            state = self._consumers[path] = consumer_state(task.path, self._contents)
        return state

    def lookup(self, task: AssetTask) -> AssetResult | None:
        """The cached result, if every file it depends on is unchanged; counted in :attr:`hits` / :attr:`misses`.

        A result without a thumbnail serves a run that asks for thumbnails too: the runner has the picture
        drawn alone (:attr:`AssetTask.thumbnail_only`) and :meth:`store` keeps it.
        """
        result = self._lookup(task)
        if result is None:
            self.misses += 1
        else:
            self.hits += 1
        return result

    def _lookup(self, task: AssetTask) -> AssetResult | None:
        if self.folder is None:
            return None
        digest = file_sha256(task.path)
        if digest is None:
            return None
        key = self.key(task, digest)
        found = cachefile.read_entry(self._file(key), self.KIND, key)
        if found.problem is not None:
            self.problems.append(cachefile.describe(self._file(key), found.problem))
        if found.payload is None:
            return None
        try:
            entry = json.loads(found.payload)
            own = str(task.path.resolve())  # its hash is part of the key: already checked
            for path, sha in entry["deps"].items():
                if path != own and file_sha256(Path(path)) != sha:
                    return None
            for folder, listing in entry["listings"].items():
                if listing is None or listing_digest(folder, self.exclude) != listing:
                    return None
            result = _from_json(entry["result"])
        except (ValueError, KeyError, TypeError, AttributeError, IndexError, binascii.Error, RecursionError):
            self.problems.append(cachefile.describe(self._file(key), "payload is not a validate result"))
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
            "deps": result.deps,
            "listings": result.listings,
            "result": _to_json(result),
        }
        key = self.key(task, digest)  # a read-only or full cache folder only costs speed: not an error
        cachefile.write_entry(self._file(key), self.KIND, key, json.dumps(entry, sort_keys=True).encode("utf-8"))

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
        "drawable": result.drawable,
        "notes": result.notes,
    }


def _from_json(data: dict[str, Any]) -> AssetResult:
    """The result an entry holds; ``ValueError``/``TypeError`` when it holds something else."""
    findings = []
    for f in data["findings"]:
        code, message, path, line = f["code"], f["message"], f["path"], f["line"]
        if not (isinstance(code, str) and isinstance(message, str) and isinstance(path, str | None)):
            raise TypeError("a finding's code, message or path is not text")
        if line is not None and (isinstance(line, bool) or not isinstance(line, int)):
            raise TypeError("a finding's line is not a number")
        findings.append(Finding(code, Severity(f["severity"]), message, path, line))
    thumbnail = base64.b64decode(data["thumbnail"], validate=True) if data["thumbnail"] else None
    kind, stats, notes, drawable = data["kind"], dict(data["stats"]), list(data["notes"]), data["drawable"]
    if not (
        isinstance(kind, str) and all(isinstance(n, str) for n in notes) and all(isinstance(k, str) for k in stats)
    ):
        raise TypeError("the kind, the notes or the stats are not text")
    if not isinstance(drawable, bool):
        raise TypeError("drawable is not true or false")
    return AssetResult(
        "",
        kind,
        findings,
        dict(data["deps"]),
        dict(data["listings"]),
        stats,
        thumbnail,
        notes,
        drawable=drawable,
    )
