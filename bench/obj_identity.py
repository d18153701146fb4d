"""Byte-identity check for the OBJ reader: every corpus OBJ parsed and normalised, outputs written to a folder.

Usage: python bench/obj_identity.py ../shared/corpus OUT [--no-normalize]

Run it once with the old reader (``PYTHONPATH=<old checkout>``) and once with the new one, then compare the
two folders byte by byte (``diff -r OLD NEW``). For each OBJ under the corpus it writes:
  * ``parse.txt``: one line per file, the SHA-256 of every array ``parse_obj`` returns (dtype, shape and
    bytes), its names, header comments and findings, or the error message (with file:line) it raised;
  * ``normalize/<n>/``: what ``meshtool normalize`` writes for the file (a fresh process per file, default
    options), with its exit code and JSON output in ``normalize/<n>.log``.
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np

from meshtool.read.obj.parse import parse_obj

CLI = "import sys; from meshtool.cli.main import main; sys.exit(main())"


def digest(path: Path) -> str:
    """One line: the SHA-256 of everything ``parse_obj`` returns for ``path``, or its error."""
    try:
        mesh = parse_obj(path.read_bytes(), path.name)
    except Exception as error:  # the error text is what is compared
        return f"error {type(error).__name__}: {error}"
    h = hashlib.sha256()
    for name in sorted(mesh.__dataclass_fields__):
        value = getattr(mesh, name)
        h.update(name.encode())
        if isinstance(value, np.ndarray):
            h.update(f"{value.dtype}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).tobytes())
        else:
            h.update(repr(value).encode())
    return h.hexdigest()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("corpus", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--no-normalize", action="store_true")
    args = parser.parse_args()
    files = sorted(p for p in args.corpus.rglob("*") if p.suffix.lower() == ".obj" and p.is_file())
    args.out.mkdir(parents=True, exist_ok=True)
    lines = [f"{p.relative_to(args.corpus)} {digest(p)}" for p in files]
    (args.out / "parse.txt").write_text("\n".join(lines) + "\n")
    if not args.no_normalize:
        for n, p in enumerate(files):
            out = args.out / "normalize" / str(n)
            run = subprocess.run(
                [sys.executable, "-c", CLI, "normalize", str(p), "-o", str(out), "--name", "mesh", "--json"],
                capture_output=True,
                text=True,
                check=False,
            )
            log = f"{p.relative_to(args.corpus)}\nexit {run.returncode}\n{run.stdout}\n{run.stderr}"
            (args.out / "normalize" / f"{n}.log").write_text(log)
    print(f"{len(files)} OBJ files -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
