"""``simrun test``: scenes with expectations run over seeds and variations, locally or on Dask, with reports.

- :mod:`simrun.expect`: the ``[[expect]]`` tables and how a run is judged;
- :mod:`.spec`: which scenes, their ``[test]`` table, the preflight check and the bundle of files;
- :mod:`.vary`: seeds, ``--vary`` and pose jitter;
- :mod:`.task`: one run (what a worker executes); :mod:`.executors`: this process, a pool, Dask;
- :mod:`.runner`: the plan, the results in order, failed runs recorded; :mod:`.reports`, :mod:`.report_html`.
"""

from __future__ import annotations

from simrun.scenetest.runner import Run, TestOptions, TestReport, run_tests

__all__ = ["Run", "TestOptions", "TestReport", "run_tests"]
