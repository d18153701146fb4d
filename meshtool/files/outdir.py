"""Outputs: atomic, and never over something meshtool did not write.

Files and folders are written to a temporary name beside the target, then renamed: a reader never sees a
half-written output and a failed run leaves nothing behind.

Before anything is replaced, :func:`check_output` (files) and :func:`write_folder` (folders) make sure that
nothing the user made is destroyed:

* an output path that is one of the inputs (the same file, also through a symbolic link, a hard link or a
  case-insensitive alias) is always refused, ``force`` or not;
* an existing file is replaced only when it is a meshtool output of the same kind, told by its magic
  number and the generator recorded inside (``.mbin``: magic + ``META.tool.name``; GLB: ``glTF`` magic +
  ``asset.generator``; USD: ``customLayerData.generator``; MSH, which has no room for a marker: its exact
  structure), or when its bytes are already exactly those to be written; ``force`` overrides;
* an existing folder is replaced only when its ``asset.json`` carries meshtool's marker
  (``"meshtool_output": {"version", "files", "sha256"}``), the folder holds exactly the files listed there
  and none of them changed since (older ``normalize`` folders without the marker qualify when
  ``asset.json`` names meshtool as its ``tool`` and its ``files`` list every other file); ``force``
  overrides, but never for a folder holding an input.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import json
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, NoReturn

from meshtool import __version__
from meshtool.errors import OutputError
from meshtool.files.recognise import GENERATORS as GENERATORS
from meshtool.files.recognise import read_head
from meshtool.formats import OutputFormat, output_for, output_named

SAFE_FILE = re.compile(r"^[a-z0-9_][a-z0-9_.-]*$")
MARKER = "asset.json"
#: The key meshtool adds to every ``asset.json`` it writes: its version and the folder's content list.
MARKER_KEY = "meshtool_output"
#: What meshtool records as the writer of GLB (``asset.generator``) and USD (``customLayerData.generator``).
GENERATOR = f"meshtool {__version__}"
FORCE_HINT = "choose another output path, remove it, or pass --force to replace it"

_FORCE: contextvars.ContextVar[bool] = contextvars.ContextVar("meshtool_force_overwrite", default=False)


@contextlib.contextmanager
def overwrite_allowed(force: bool = True) -> Iterator[None]:
    """Within the block, outputs that are not meshtool's may be replaced (``--force``); inputs never are."""
    token = _FORCE.set(force)
    try:
        yield
    finally:
        _FORCE.reset(token)


def _force(force: bool | None) -> bool:
    return _FORCE.get() if force is None else force


def same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name the same file: same inode (links, case-insensitive aliases) or real path."""
    return how_same(a, b) is not None


def how_same(a: Path, b: Path) -> str | None:
    """How ``a`` names the file ``b``, ``None`` when they are different files (the rule of :func:`same_file`).

    ``"the same path"`` (equal once made absolute), ``"a symbolic link to it"`` (equal real paths),
    ``"a case alias of it"`` (real paths equal but for case: a case-insensitive system or file system),
    ``"a hard link to it"`` (same device and inode under other real paths).
    """
    try:
        same_inode = os.path.samefile(a, b)
    except OSError:
        same_inode = False
    try:
        real_a, real_b = os.path.realpath(a), os.path.realpath(b)
        if not same_inode and os.path.normcase(real_a) != os.path.normcase(real_b):
            return None
        if os.path.abspath(a) == os.path.abspath(b):
            return "the same path"
    except (OSError, ValueError):
        return "the same file" if same_inode else None
    if real_a == real_b:
        return "a symbolic link to it"
    if os.path.normcase(real_a) == os.path.normcase(real_b) or real_a.casefold() == real_b.casefold():
        return "a case alias of it"
    return "a hard link to it"


def is_within(path: Path, folder: Path) -> bool:
    """Whether ``path`` lies strictly inside ``folder``, both with links resolved and case folded as the system does."""
    try:
        real, root = os.path.normcase(os.path.realpath(path)), os.path.normcase(os.path.realpath(folder))
    except (OSError, ValueError):
        return False
    return real.startswith(root.rstrip(os.sep) + os.sep)


def refuse_inputs(out: Path, inputs: Iterable[Path]) -> None:
    """Refuse ``out`` when it is one of ``inputs`` (always, whatever ``--force`` says).

    Raises:
        OutputError: ``out`` is an input.
    """
    for source in inputs:
        how = how_same(out, source)
        if how is not None:
            raise OutputError(
                f"is an input ({source}; {how}); refusing to overwrite it",
                path=str(out),
                hint="choose another output path (--force does not override this)",
            )


def check_output(
    out: Path,
    kind: str | None = None,
    *,
    force: bool | None = None,
    inputs: Iterable[Path] = (),
    data: bytes | None = None,
    recognise: tuple[str, Callable[[bytes], bool]] | None = None,
    any_of_kind: bool = False,
) -> None:
    """Refuse to replace ``out`` unless it is a meshtool output of ``kind`` (see the module docstring).

    Args:
        out: The file about to be written.
        kind: An output of :data:`meshtool.formats.OUTPUTS` (``mbin``, ``glb``, ``usd``...); ``None`` infers it
            from the suffix (an unknown suffix has no recognisable kind: an existing file is replaced only when
            ``data`` equals it, or forced).
        force: Replace a file that is not meshtool's (never an input); ``None`` uses
            :func:`overwrite_allowed`'s setting.
        inputs: Files this run reads; ``out`` may never be one of them.
        data: The bytes about to be written; an existing file with exactly these bytes may be replaced.
        recognise: For outputs without a kind of their own (reports): what they are called and a test of an
            existing file's first 64 KiB that says it is one (then it may be replaced).
        any_of_kind: Also replace files of kinds recognised only by their magic number or root element (rows
            with ``marked`` false: PNG, GIF, MP4, MJCF XML, ``.mjz``, ``.simlog``), as simrun's writers do; a
            meshtool command refuses those unless forced.

    Raises:
        OutputError: ``out`` is an input, not a regular file, or an existing file meshtool did not write.
    """
    refuse_inputs(out, inputs)
    try:
        info = os.lstat(out)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputError(f"cannot check the existing output: {exc.strerror}", path=str(out)) from None
    if stat.S_ISDIR(info.st_mode):
        raise OutputError("is a folder, not a file", path=str(out), hint="name a file")
    if _force(force):
        return
    if not stat.S_ISREG(info.st_mode):
        raise OutputError(
            "exists and is not a regular file (a link, pipe or device); not replacing it",
            path=str(out),
            hint=FORCE_HINT,
        )
    row = output_named(kind) if kind else _inferred(out, any_of_kind)
    if data is not None and info.st_size == len(data) and read_head(out, len(data)) == data:
        return
    if recognise is not None:
        what, test = recognise
        if not test(read_head(out, 1 << 16) or b""):
            raise OutputError(f"exists and is not {what}; not replacing it", path=str(out), hint=FORCE_HINT)
        return
    if row is None or not row.recogniser()(out, info.st_size):
        what = f"a {row.owner} {row.name} output" if row else "written by meshtool"
        raise OutputError(f"exists and is not {what}; not replacing it", path=str(out), hint=FORCE_HINT)


def _inferred(out: Path, any_of_kind: bool) -> OutputFormat | None:
    """The output row of ``out``'s suffix, when its recogniser tells our files apart (or ``any_of_kind``)."""
    row = output_for(out)
    return row if row is not None and (row.marked or any_of_kind) else None


def write_output(
    out: Path, data: bytes, kind: str | None = None, *, force: bool | None = None, inputs: Iterable[Path] = ()
) -> None:
    """:func:`check_output`, then :func:`write_file`."""
    check_output(out, kind, force=force, inputs=inputs, data=data)
    write_file(out, data)


def stamp_glb(tree: dict[str, Any]) -> None:
    """Record meshtool as the GLB's ``asset.generator`` (a ``tree_postprocessor`` for trimesh's export)."""
    tree.setdefault("asset", {"version": "2.0"})["generator"] = GENERATOR


def stamp_usd(layer: Any, generator: str = GENERATOR) -> None:
    """Record ``generator`` in a USD layer's ``customLayerData`` (how :func:`check_output` knows it)."""
    data = dict(layer.customLayerData)
    data["generator"] = generator
    layer.customLayerData = data


def write_folder(
    parent: Path, name: str, files: dict[str, bytes], *, force: bool | None = None, inputs: Iterable[Path] = ()
) -> Path:
    """Write ``files`` as ``parent/name/`` atomically, with meshtool's marker in ``asset.json``.

    Args:
        parent: Output folder (created when missing).
        name: Folder name, ``[a-z0-9_.-]+``.
        files: File name (``[a-z0-9_.-]+``, no folders) to contents; must include ``asset.json`` holding a
            JSON object, to which the marker ``"meshtool_output": {"version", "files"}`` is added.
        force: Replace an existing folder meshtool did not write (never one holding an input); ``None``
            uses :func:`overwrite_allowed`'s setting.
        inputs: Files this run reads; the folder may not be or hold one of them.

    Returns:
        The written folder.

    Raises:
        OutputError: A bad name, an existing folder that meshtool did not write (or that holds files it
            did not write), a folder holding an input, or an OS error (the temporary folder is removed and
            an existing folder restored).
    """
    for file_name in (name, *files):
        if not SAFE_FILE.match(file_name):
            raise OutputError(f"unsafe output name {file_name!r}", hint="names must match [a-z0-9_.-]+")
    files = {**files, MARKER: with_marker(files)}
    target = parent / name
    for source in inputs:
        if same_file(target, source) or is_within(Path(source), target):
            raise OutputError(
                f"would replace a folder holding an input ({source})",
                path=str(target),
                hint="write to a folder outside the source (--force does not override this)",
            )
    if os.path.lexists(target) and not _force(force):
        reason = replaceable_folder(target)
        if reason:
            raise OutputError(f"{reason}; not replacing it", path=str(target), hint=FORCE_HINT)
    elif os.path.islink(target) or (os.path.lexists(target) and not target.is_dir()):
        raise OutputError("exists and is not a folder; not replacing it", path=str(target), hint="remove it")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=parent))
    except OSError as exc:
        raise OutputError(f"cannot create the output folder: {exc.strerror}", path=str(parent)) from None
    old: Path | None = None
    try:
        for file_name in sorted(files):
            with open(tmp / file_name, "wb") as handle:
                handle.write(files[file_name])
                handle.flush()
                os.fsync(handle.fileno())
        os.chmod(tmp, 0o755)
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{name}.old-", dir=parent))
            os.rmdir(old)
            os.rename(target, old)
        os.rename(tmp, target)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and old.exists() and not target.exists():
            os.rename(old, target)
        raise OutputError(f"cannot write the output: {exc.strerror}", path=str(target)) from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return target


def with_marker(files: dict[str, bytes]) -> bytes:
    """``files["asset.json"]`` with meshtool's marker: its version, the folder's files and their SHA-256.

    The digests cover every file but ``asset.json`` itself, so a file the user edited in place after
    meshtool wrote it is noticed (and not silently replaced).

    Raises:
        OutputError: ``asset.json`` is missing or not a JSON object (a bug in the caller).
    """
    try:
        manifest = json.loads(files[MARKER])
    except (KeyError, ValueError):
        manifest = None
    if not isinstance(manifest, dict):
        raise OutputError("an output folder needs an asset.json holding a JSON object", path=MARKER)
    digests = {n: hashlib.sha256(files[n]).hexdigest() for n in sorted(files) if n != MARKER}
    manifest[MARKER_KEY] = {
        "tool": "meshtool",
        "version": __version__,
        "files": sorted({*files, MARKER}),
        "sha256": digests,
    }
    return (json.dumps(manifest, indent=1, ensure_ascii=False) + "\n").encode("utf-8")


def replaceable_folder(target: Path) -> str | None:
    """Why meshtool may not replace the existing ``target`` (``None``: it may: meshtool wrote all of it).

    A folder qualifies when it is a real folder (not a link) whose ``asset.json`` carries the marker and
    whose entries are exactly the files the marker lists, all regular files. A folder written before the
    marker existed qualifies when its ``asset.json`` names meshtool as ``tool`` and its ``files`` (what
    ``normalize`` recorded: ``obj``, ``mtl``, ``textures``) plus ``asset.json`` are exactly its entries.
    """
    if os.path.islink(target) or not target.is_dir():
        return "exists and is not a folder"
    data = read_head(target / MARKER, 16 << 20)
    try:
        manifest = json.loads(data) if data is not None else None
    except (ValueError, RecursionError):  # not an asset.json meshtool wrote
        manifest = None
    if not isinstance(manifest, dict):
        return "exists and was not written by meshtool (no asset.json of meshtool's)"
    marker = manifest.get(MARKER_KEY)
    listed: set[str] | None = None
    digests: dict[str, Any] = {}
    if isinstance(marker, dict) and isinstance(marker.get("files"), list):
        listed = {str(f) for f in marker["files"]}
        recorded = marker.get("sha256")
        digests = recorded if isinstance(recorded, dict) else {}
    elif isinstance(manifest.get("tool"), dict) and manifest["tool"].get("name") == "meshtool":
        legacy = manifest.get("files")
        if isinstance(legacy, dict):
            names = [legacy.get("obj"), legacy.get("mtl"), *(legacy.get("textures") or [])]
            listed = {str(n) for n in names if n} | {MARKER}
    if listed is None:
        return "exists and was not written by meshtool (its asset.json has no meshtool marker)"
    try:
        entries = {e.name: e for e in os.scandir(target)}
    except OSError as exc:
        return f"exists and cannot be listed ({exc.strerror})"
    extra = sorted(set(entries) - listed)
    if extra:
        return f"holds files meshtool did not write ({', '.join(extra[:3])}{', ...' if len(extra) > 3 else ''})"
    odd = sorted(n for n, e in entries.items() if not e.is_file(follow_symlinks=False))
    if odd:
        return f"holds something other than a plain file ({', '.join(odd[:3])})"
    changed = sorted(n for n, digest in digests.items() if n in entries and _sha256(target / n) != digest)
    if changed:
        return f"holds files changed since meshtool wrote them ({', '.join(changed[:3])})"
    return None


def _sha256(path: Path) -> str | None:
    """SHA-256 of a regular file, read in chunks without following a link; ``None`` when unreadable."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    digest = hashlib.sha256()
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        while chunk := os.read(fd, 1 << 20):
            digest.update(chunk)
    except OSError:
        return None
    finally:
        os.close(fd)
    return digest.hexdigest()


class AtomicFile:
    """An output written through a temporary file in the same folder, renamed over ``out`` when committed.

    Readers of ``out`` see the old file or the whole new one, never a torn one; a write that fails (a full
    disk) or an :meth:`abort` leaves ``out`` as it was and no temporary file. :func:`write_file` writes bytes
    in one go; a stream (``simrun play --record``) writes as it goes.

    Raises:
        OutputError: The temporary file cannot be made, written or renamed (it is removed first).
    """

    def __init__(self, out: Path) -> None:
        self.out = out
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
        except (OSError, ValueError) as exc:
            raise OutputError(f"cannot write: {getattr(exc, 'strerror', None) or exc}", path=str(out)) from None
        self._tmp: str | None = tmp
        self._handle = os.fdopen(fd, "wb")

    def write(self, data: bytes) -> None:
        """Append ``data``; on failure the file is dropped (:meth:`abort`) and the error raised."""
        try:
            self._handle.write(data)
        except OSError as exc:
            self._fail(exc)

    def commit(self) -> None:
        """Flush to disk and rename over ``out`` (mode 0644); a second call does nothing."""
        if self._tmp is None:
            return
        try:
            self._handle.flush()
            os.fsync(self._handle.fileno())
            self._handle.close()
            os.chmod(self._tmp, 0o644)
            os.replace(self._tmp, self.out)
        except OSError as exc:
            self._fail(exc)
        self._tmp = None

    def abort(self) -> None:
        """Drop what was written: close and remove the temporary file; ``out`` stays as it was."""
        tmp, self._tmp = self._tmp, None
        with contextlib.suppress(OSError):
            self._handle.close()  # may flush into a full disk once more; its error changes nothing
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)

    def _fail(self, exc: OSError) -> NoReturn:
        self.abort()
        raise OutputError(f"cannot write: {exc.strerror or exc}", path=str(self.out)) from None


def write_file(out: Path, data: bytes) -> None:
    """Write ``data`` to ``out`` through a temporary file in the same folder and a rename (:class:`AtomicFile`)."""
    target = AtomicFile(out)
    try:
        target.write(data)
        target.commit()
    finally:
        target.abort()  # nothing left behind, whatever interrupted the write (a no-op once committed)
