"""``simrun test``: scenes with expectations run over seeds and variations, locally or on Dask, with reports.

- :mod:`simrun.scenetest.expect`: the ``[[expect]]`` tables; :mod:`.observer`: how a run is judged against them;
- :mod:`.spec`: which scenes, their ``[test]`` table, the preflight check and the bundle of files;
- :mod:`.vary`: seeds, ``--vary`` and pose jitter;
- :mod:`.task`: one run (what a worker executes, through meshtool's batch layer: this process, worker
  processes or Dask);
- :mod:`.runner`: the plan, the results in order, failed runs recorded; :mod:`.reports`, :mod:`.report_html`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from simrun.scenetest.runner import Run, TestOptions, TestReport, run_tests


def __getattr__(name: str) -> Any:
    """The runner's names, imported on first use: ``simrun test --help`` does not load MuJoCo (PEP 562)."""
    if name in __all__:
        from simrun.scenetest import runner

        return getattr(runner, name)
    raise AttributeError(f"module 'simrun.scenetest' has no attribute {name!r}")


__all__ = ["Run", "TestOptions", "TestReport", "run_tests"]
