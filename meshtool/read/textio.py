r"""Decoding of text-based asset files (OBJ, MTL) into normalised Python text.

OBJ and MTL files arrive in whatever encoding the exporter used. This module turns raw bytes into one
canonical form that the parsers can rely on: ``\\n`` line endings only (CRLF and lone CR converted),
backslash line continuations joined (line numbers preserved by leaving the continued lines empty), and
leading whitespace stripped. It never touches the file system.
"""

from __future__ import annotations

import codecs
import re
from dataclasses import dataclass, field

from meshtool.errors import MeshtoolError
from meshtool.findings import Finding, info

_CONTINUATION = re.compile(r"\\\n")
# Control characters that never occur in a text OBJ/MTL (tab, LF, CR, FF, VT are allowed).
_BINARY_BYTES = bytes(b for b in range(32) if b not in (9, 10, 11, 12, 13))
_TEXT_BYTES = bytes(b for b in range(256) if b not in _BINARY_BYTES)
_BINARY_HEAD = 1 << 16  # a bad byte this early means a binary file (reported by byte offset)


@dataclass(slots=True)
class DecodedText:
    """Text ready for a line parser.

    Attributes:
        data: The normalised text encoded as UTF-8: LF line endings, continuations joined, ending with a
            newline unless empty.
        encoding: ``utf-8``, ``utf-8-sig``, ``utf-16`` or ``latin-1``.
        line_endings: ``lf``, ``crlf``, ``cr`` or ``mixed``.
        findings: Notes about what was normalised (encoding fallback, continuations).
    """

    data: bytes
    encoding: str
    line_endings: str
    findings: list[Finding] = field(default_factory=list)

    @property
    def text(self) -> str:
        """The normalised text as ``str``."""
        return self.data.decode("utf-8")


def decode_text(data: bytes, path: str, error: type[MeshtoolError]) -> DecodedText:
    """Decode the bytes of a text asset file.

    Order: a UTF-8 or UTF-16 byte-order mark decides; otherwise strict UTF-8; otherwise Latin-1 (every
    byte is a character, so names survive, and a finding says so).

    Args:
        data: Raw file contents.
        path: Name used in findings and errors.
        error: Exception class to raise for data that is not text (binary garbage).

    Returns:
        The normalised text and notes.

    Raises:
        MeshtoolError: (of class ``error``) when the data contains NUL or other binary control bytes.
    """
    findings: list[Finding] = []
    # the common case, nothing to change (a one-byte search for the backslash first: memchr speed)
    if data.isascii() and b"\r" not in data and (b"\\" not in data or b"\\\n" not in data):
        _reject_binary(data, path, error)
        if data and not data.endswith(b"\n"):
            data += b"\n"
        return DecodedText(data, "utf-8", "lf", findings)
    if data.startswith(codecs.BOM_UTF8):
        encoding, text = "utf-8-sig", _decode(data[3:], "utf-8", path, error, 3)
    elif data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        encoding, text = "utf-16", _decode(data, "utf-16", path, error, 0)
    else:
        _reject_binary(data, path, error)
        try:
            encoding, text = "utf-8", data.decode("utf-8")
        except UnicodeDecodeError as exc:
            encoding, text = "latin-1", data.decode("latin-1")
            findings.append(
                info(
                    "encoding-latin1",
                    f"not valid UTF-8 (first bad byte at offset {exc.start}); read as Latin-1",
                    path,
                )
            )
    if encoding != "utf-8":
        _reject_binary(text.encode("utf-8", "surrogatepass"), path, error)

    endings = "lf"
    if "\r" in text:
        crlf = text.count("\r\n")
        cr = text.count("\r") - crlf
        lf = text.count("\n") - crlf
        endings = "mixed" if sum(1 for n in (crlf, cr, lf) if n) > 1 else "crlf" if crlf else "cr"
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    if text and not text.endswith("\n"):
        text += "\n"
    if "\\" in text and _CONTINUATION.search(text):
        text, joined = _join_continuations(text)
        findings.append(info("line-continuation", f"joined {joined} backslash-continued line(s)", path))
    return DecodedText(text.encode("utf-8", "surrogatepass"), encoding, endings, findings)


def _decode(data: bytes, codec: str, path: str, error: type[MeshtoolError], skipped: int) -> str:
    try:
        return data.decode(codec)
    except UnicodeDecodeError as exc:
        raise error(
            f"invalid {codec.upper()} data after a {codec.upper()} byte-order mark",
            path=path,
            offset=exc.start + skipped,
            hint="re-export the file as UTF-8",
        ) from None


def _reject_binary(data: bytes, path: str, error: type[MeshtoolError]) -> None:
    """Refuse data with a control byte that never occurs in text, anywhere in the file (not only its start).

    A bad byte in the first 64 KiB (a binary file) is located by byte offset; one further in (a text file
    with a stray NUL) by line, with the offset in the message.
    """
    if not data.translate(None, _TEXT_BYTES):  # keeps only the binary bytes: one C pass, nothing allocated
        return
    bad = [at for at in (data.find(bytes([b])) for b in _BINARY_BYTES) if at >= 0]
    if not bad:
        return
    offset = min(bad)
    hint = "pass a text OBJ/MTL file; binary formats are not OBJ"
    if offset < _BINARY_HEAD:
        raise error("binary data, not a text file", path=path, offset=offset, hint=hint)
    raise error(
        f"binary data, not a text file (byte 0x{data[offset]:02x} at byte offset {offset})",
        path=path,
        line=_line_at(data, offset),
        hint="remove the control bytes; text OBJ/MTL files contain none",
    )


def _line_at(data: bytes, offset: int) -> int:
    """1-based line of byte ``offset``, counting LF, CRLF and lone CR line endings as the parsers do."""
    lf, cr, crlf = data.count(b"\n", 0, offset), data.count(b"\r", 0, offset), data.count(b"\r\n", 0, offset)
    return lf + cr - crlf + 1


def _join_continuations(text: str) -> tuple[str, int]:
    """Join lines ending in a backslash with the next line, keeping every line at its number."""
    lines = text.split("\n")
    out: list[str] = []
    joined = 0
    pending: list[str] = []
    for line in lines:
        if line.endswith("\\"):
            pending.append(line[:-1])
            joined += 1
            continue
        if pending:
            out.append(" ".join([*pending, line]))
            out.extend([""] * len(pending))
            pending = []
        else:
            out.append(line)
    if pending:
        out.append(" ".join(pending))
        out.extend([""] * (len(pending) - 1))
    return "\n".join(out), joined
