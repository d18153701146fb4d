"""Child process that runs CoACD once: ``python -m meshtool.coacd_worker IN.npz OUT.npz``.

Kept apart from the caller because CoACD can abort the process on bad input and writes to C stdout.
Writes the hulls' vertices as ``hull_0``, ``hull_1``... in OUT.npz.
"""

from __future__ import annotations

import json
import sys

import numpy as np


def run(job: str, out: str) -> None:
    """Read the job, run CoACD, write the hull vertices."""
    import coacd

    coacd.set_log_level("error")
    with np.load(job) as archive:
        points = np.asarray(archive["points"], dtype=np.float64)
        faces = np.asarray(archive["faces"], dtype=np.int64)
        params = json.loads(bytes(archive["params"]).decode())
    parts = coacd.run_coacd(coacd.Mesh(points, faces), **params)
    np.savez(out, **{f"hull_{k}": np.asarray(v, dtype=np.float64) for k, (v, _) in enumerate(parts)})  # type: ignore[arg-type]


if __name__ == "__main__":
    run(sys.argv[1], sys.argv[2])
