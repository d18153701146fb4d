"""``simrun serve``: a running world whose services and sensors anyone can reach over HTTP/JSON and WebSocket.

Modules: :mod:`~simrun.serve.loop` (the simulation thread), :mod:`~simrun.serve.catalogue` (entities,
services, sensors and request validation), :mod:`~simrun.serve.app` (the Starlette routes),
:mod:`~simrun.serve.openapi` (the published schema), :mod:`~simrun.serve.recording` (``.simlog`` of a
served run), :mod:`~simrun.serve.page` (the dashboard), :mod:`~simrun.serve.foxglove_live` (the Foxglove
WebSocket protocol) and :mod:`~simrun.serve.server` (uvicorn, signals).
docs/serve.md describes the interface.
"""
