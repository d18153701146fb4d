"""simrun's file outputs: atomic (temporary file, then a rename) and never over what simrun did not write.

Every simrun writer goes through :func:`write_bytes`, which applies meshtool's rules
(:func:`meshtool.outdir.check_output`): an output path that is one of the run's inputs is always refused;
an existing file is replaced only when it is a meshtool/simrun output of the kind its suffix names, or
when forced. The CLI sets the policy for a command with :func:`output_policy` (``--force`` and the
command's inputs); library callers may pass ``force``/``inputs`` to :func:`check_output` directly.

Kinds recognised by suffix (magic number, plus the generator recorded inside where the format has room):

* ``.mbin``, ``.glb``, ``.usd``/``.usda``/``.usdc``, ``.msh``: as meshtool (generator ``meshtool`` or
  ``simrun`` in GLB ``asset.generator`` / USD ``customLayerData``);
* ``.gltf`` and ``.html``/``.htm``: simrun's generator near the start (``asset.generator``, a
  ``<meta name="generator">``);
* ``.xml``: an MJCF (root element ``<mujoco``); ``.mjz``: a zip holding an ``.xml``; ``.png``, ``.gif``,
  ``.mp4``: their magic numbers; ``.simlog``: its magic line. These formats, as simrun writes them, carry
  no generator marker, so a file of the same kind is replaced (documented in README "Outputs").

Anything else that exists is replaced only when its bytes are already those to be written.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from meshtool import __version__
from meshtool.errors import OutputError
from meshtool.outdir import FORCE_HINT, KINDS, refuse_inputs, write_file
from meshtool.outdir import check_output as meshtool_check_output
from simrun.errors import SimrunError

GENERATOR = f"simrun (meshtool {__version__})"

#: Suffix -> byte prefixes of a file of that kind (for formats without a generator marker).
MAGIC: dict[str, tuple[bytes, ...]] = {
    ".png": (b"\x89PNG\r\n\x1a\n",),
    ".gif": (b"GIF87a", b"GIF89a"),
    ".mjz": (b"PK\x03\x04",),
    ".simlog": (b"\x89SIMLOG\n",),
}

#: Suffix -> the generator marker near the start of text outputs simrun writes (recording pages, .gltf).
_MARKED: dict[str, bytes] = {
    ".html": b'<meta name="generator" content="simrun (',
    ".htm": b'<meta name="generator" content="simrun (',
    ".gltf": b'"generator": "simrun (',
}

_POLICY: contextvars.ContextVar[tuple[bool, tuple[Path, ...]]] = contextvars.ContextVar(
    "simrun_output_policy", default=(False, ())
)


@contextlib.contextmanager
def output_policy(force: bool = False, inputs: Iterable[Path | str | None] = ()) -> Iterator[None]:
    """Within the block, :func:`write_bytes` refuses ``inputs`` always and other files unless ``force``.

    Args:
        force: Replace existing files that simrun did not write (``--force``); never an input.
        inputs: Files the command reads (scene, recording, commands); ``None`` entries are skipped.
    """
    token = _POLICY.set((force, tuple(Path(p) for p in inputs if p is not None)))
    try:
        yield
    finally:
        _POLICY.reset(token)


def check_output(
    path: Path, *, force: bool | None = None, inputs: Iterable[Path] = (), data: bytes | None = None
) -> None:
    """Refuse to write ``path`` when it is an input, or an existing file simrun/meshtool did not write.

    Args:
        path: The file about to be written.
        force: Replace a file of another kind (never an input); ``None`` uses :func:`output_policy`.
        inputs: Files the run reads, added to those of :func:`output_policy`.
        data: The bytes about to be written (an existing file with exactly these bytes may be replaced).

    Raises:
        SimrunError: One line naming the file and how to proceed.
    """
    policy_force, policy_inputs = _POLICY.get()
    force = policy_force if force is None else force
    every_input = (*policy_inputs, *inputs)
    try:
        suffix = path.suffix.lower()
        if suffix in KINDS or suffix not in (*MAGIC, *_MARKED, ".xml", ".mp4"):
            meshtool_check_output(path, KINDS.get(suffix), force=force, inputs=every_input, data=data)
            return
        refuse_inputs(path, every_input)
        if force or not os.path.lexists(path):
            return
        if not stat.S_ISREG(os.lstat(path).st_mode) or not _same_kind(path, suffix):
            raise OutputError(
                f"exists and is not a {suffix[1:]} file simrun wrote; not replacing it", path=str(path), hint=FORCE_HINT
            )
    except OutputError as exc:
        raise SimrunError(exc.one_line()) from None
    except OSError as exc:
        raise SimrunError(f"{path}: cannot check the existing output: {exc.strerror}") from None


def _same_kind(path: Path, suffix: str) -> bool:
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return False
    try:
        head = os.read(fd, 512) if stat.S_ISREG(os.fstat(fd).st_mode) else b""
    except OSError:
        return False
    finally:
        os.close(fd)
    if suffix == ".xml":
        text = head.decode("utf-8", "replace").lstrip("\ufeff \t\r\n")
        while text.startswith("<?") or text.startswith("<!--"):
            end = text.find("?>" if text.startswith("<?") else "-->")
            if end < 0:
                return False
            text = text[end + (2 if text.startswith("<?") else 3) :].lstrip()
        return text.startswith("<mujoco")
    if suffix == ".mp4":
        return head[4:8] == b"ftyp"
    if suffix in _MARKED:
        return _MARKED[suffix] in head
    return head.startswith(MAGIC[suffix])


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, after :func:`check_output`.

    Raises:
        SimrunError: The output is refused, or the folder cannot be written.
    """
    check_output(path, data=data)
    try:
        write_file(path, data)
    except OutputError as exc:
        raise SimrunError(exc.one_line()) from None


def write_text(path: Path, text: str) -> None:
    """Write UTF-8 text atomically (see :func:`write_bytes`)."""
    write_bytes(path, text.encode("utf-8"))


def stamp_glb(tree: dict[str, Any]) -> None:
    """Record simrun as a GLB's ``asset.generator`` (a ``tree_postprocessor`` for trimesh's export)."""
    tree.setdefault("asset", {"version": "2.0"})["generator"] = GENERATOR


def stamp_usd(layer: Any) -> None:
    """Record simrun in a USD layer's ``customLayerData`` so a later export may replace the file."""
    data = dict(layer.customLayerData)
    data["generator"] = GENERATOR
    layer.customLayerData = data
