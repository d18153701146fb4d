"""Run a command line of meshtool, obj2bin or simrun in a child process with a time and memory bound.

Hostile-input tests assert not only the exit code and the message but that the refusal came quickly and
small: the child gets ``RLIMIT_AS`` (address space) and a wall-clock timeout, so an amplification that
comes back shows up as a ``MemoryError`` traceback (exit 3 or 1 with a traceback) or a ``TimeoutExpired``.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass

#: The entry points, as ``pyproject.toml`` declares them.
_ENTRY = {
    "meshtool": "meshtool.cli.main:main",
    "obj2bin": "meshtool.cli.main:obj2bin",
    "simrun": "simrun.cli.main:main",
}


@dataclass(frozen=True, slots=True)
class Outcome:
    """What the child did: exit status, standard output and standard error (text)."""

    code: int
    out: str
    err: str


def run_bounded(
    argv: Sequence[str], *, seconds: float = 60.0, memory_mb: int = 1500, env: dict[str, str] | None = None
) -> Outcome:
    """Run ``argv`` (``["meshtool", "normalize", ...]``) in a child limited to ``memory_mb`` MiB of address space.

    Raises:
        subprocess.TimeoutExpired: The child ran longer than ``seconds`` (the child is killed).
    """
    module, _, func = _ENTRY[argv[0]].partition(":")
    code = f"import sys; sys.argv[0] = {argv[0]!r}; from {module} import {func}; sys.exit({func}())"
    limit = memory_mb << 20

    def _limit() -> None:  # pragma: no cover - runs in the child
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    full_env = {**os.environ, "PYTHONHASHSEED": "0", **(env or {})}
    done = subprocess.run(
        [sys.executable, "-c", code, *argv[1:]],
        capture_output=True,
        text=True,
        timeout=seconds,
        preexec_fn=_limit,
        env=full_env,
        stdin=subprocess.DEVNULL,
        check=False,
    )
    return Outcome(done.returncode, done.stdout, done.stderr)


__all__ = ["Outcome", "run_bounded"]
