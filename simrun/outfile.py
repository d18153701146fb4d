"""simrun's file outputs: atomic (temporary file, then a rename) and never over what simrun did not write.

Every simrun writer goes through :func:`write_bytes`, which applies meshtool's rules
(:func:`meshtool.files.outdir.check_output`): an output path that is one of the run's inputs is always refused;
an existing file is replaced only when it is a meshtool/simrun output of the kind its suffix names, or
when forced. The CLI sets the policy for a command with :func:`output_policy` (``--force`` and the
command's inputs); library callers may pass ``force``/``inputs`` to :func:`check_output` directly.

Kinds are recognised by suffix through the formats registry (:data:`meshtool.formats.OUTPUTS`, its table
in ``docs/formats.md``): by the generator recorded inside where the format has room (``.mbin``, GLB,
glTF, USD, HTML), by magic number or root element where it has none (PNG, GIF, MP4, MJCF XML, ``.mjz``,
``.simlog``: a file of the same kind is replaced, documented in README "Outputs").

Anything else that exists is replaced only when its bytes are already those to be written.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from meshtool import __version__
from meshtool.errors import OutputError
from meshtool.files.outdir import check_output as meshtool_check_output
from meshtool.files.outdir import write_file
from simrun.errors import SimrunError

GENERATOR = f"simrun (meshtool {__version__})"

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
        meshtool_check_output(path, None, force=force, inputs=every_input, data=data, any_of_kind=True)
    except OutputError as exc:
        raise SimrunError(exc.one_line()) from None
    except OSError as exc:
        raise SimrunError(f"{path}: cannot check the existing output: {exc.strerror}") from None


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
