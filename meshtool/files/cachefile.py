r"""One envelope for every cache entry meshtool and simrun write: an entry says which key it answers.

The hull cache (:mod:`meshtool.hulls.decompose`), the validate cache (:mod:`meshtool.validate.cache`) and simrun's
compiled-model cache (:mod:`simrun.world.model_cache`) store each entry as (little-endian)::

    offset  size  field
    0       8     magic b"\x89MTCACHE"
    8       4     u32 envelope version (1)
    12      32    SHA-256 of the entry's kind and key: sha256(kind + b"\0" + key), UTF-8 (surrogateescape)
    44      8     u64 payload length
    52      32    SHA-256 of the payload
    84      n     the payload (the cache's own format: an ``.npz``, JSON, a compiled model)

An entry is used only when the magic, the version, the length (no byte missing, none extra) and both
digests match the lookup; anything else is a *miss* with a one-line reason (:class:`Entry`), after which
the caller computes the result afresh and writes the entry again. The *kind* separates caches (and the two
entries the hull cache keeps per key), so an entry of one kind never answers a lookup of another.

Threat model: the payload digest catches damage (a truncated write, a flipped bit, a zero-length file);
the key digest catches an entry copied or renamed from another key (another asset's hulls, another
scene's model) and a payload swapped between entries. Neither is a signature: whoever can write the cache
folder can write a well-formed entry for any key (SHA-256 needs no secret), so the cache folder must be
as trusted as the code that reads it. Entries are written to a temporary file in the same folder and
renamed over the old one (:func:`meshtool.files.outdir.write_file`), so concurrent writers of one key leave one
complete entry, never a mix.
"""

from __future__ import annotations

import hashlib
import os
import struct
from dataclasses import dataclass
from pathlib import Path

from meshtool.errors import OutputError, ResolveError
from meshtool.files.outdir import write_file
from meshtool.files.safeopen import DEFAULT_LIMITS, read_file

MAGIC = b"\x89MTCACHE"
#: Envelope version; bump when the layout above changes.
VERSION = 1
_HEAD = struct.Struct("<8sI32sQ32s")
#: Bytes before the payload.
HEADER_BYTES = _HEAD.size


@dataclass(frozen=True, slots=True)
class Entry:
    """What a lookup found.

    Attributes:
        payload: The payload when the entry is sound and answers the key; ``None`` on a miss.
        problem: Why an existing entry was not used (one line, no path); ``None`` for a hit or an absent entry.
    """

    payload: bytes | None
    problem: str | None = None


def key_digest(kind: str, key: str) -> bytes:
    """SHA-256 of an entry's kind and key (as stored in the envelope)."""
    return hashlib.sha256(f"{kind}\0{key}".encode("utf-8", "surrogateescape")).digest()


def seal(kind: str, key: str, payload: bytes) -> bytes:
    """The envelope of ``payload`` answering ``key`` of ``kind``."""
    head = _HEAD.pack(MAGIC, VERSION, key_digest(kind, key), len(payload), hashlib.sha256(payload).digest())
    return head + payload


def unseal(kind: str, key: str, data: bytes) -> Entry:
    """The payload of an envelope when it is sound and answers ``key`` of ``kind``, else why not."""
    if len(data) < HEADER_BYTES:
        return Entry(None, f"truncated ({len(data)} bytes, shorter than the {HEADER_BYTES}-byte header)")
    magic, version, key_sha, length, payload_sha = _HEAD.unpack_from(data)
    if magic != MAGIC:
        return Entry(None, "not a cache entry (wrong magic)")
    if version != VERSION:
        return Entry(None, f"entry format version {version}, this version reads {VERSION}")
    if key_sha != key_digest(kind, key):
        return Entry(None, "answers another key (copied from another entry?)")
    if len(data) - HEADER_BYTES != length:
        return Entry(None, f"truncated or padded ({len(data) - HEADER_BYTES} payload bytes, {length} recorded)")
    payload = data[HEADER_BYTES:]
    if hashlib.sha256(payload).digest() != payload_sha:
        return Entry(None, "content digest mismatch (damaged)")
    return Entry(payload)


def read_entry(path: Path, kind: str, key: str, limit: int = DEFAULT_LIMITS.other) -> Entry:
    """Look ``key`` up in the entry file ``path``; an absent file is a plain miss (no problem)."""
    try:
        os.stat(path)
    except FileNotFoundError:
        return Entry(None)
    except (OSError, ValueError) as exc:
        return Entry(None, f"cannot be read ({getattr(exc, 'strerror', None) or exc})")
    try:
        data = read_file(path, limit)
    except ResolveError as exc:
        return Entry(None, f"cannot be read ({exc.message})")
    return unseal(kind, key, data)


def write_entry(path: Path, kind: str, key: str, payload: bytes) -> bool:
    """Store ``payload`` for ``key`` of ``kind`` atomically; False when the folder cannot be written.

    A read-only or full cache folder costs the next run time, nothing else, so it is not an error.
    """
    try:
        write_file(path, seal(kind, key, payload))
    except OutputError:
        return False
    return True


def describe(path: Path, problem: str) -> str:
    """The note for a cache entry that was not used: ``cache entry PATH: PROBLEM; recomputed``."""
    return f"cache entry {path}: {problem}; recomputed"


__all__ = ["HEADER_BYTES", "MAGIC", "VERSION", "Entry", "describe", "key_digest", "read_entry", "seal", "unseal"]
