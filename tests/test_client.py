"""simrun.client.Client against a real ``simrun serve --edit`` on 127.0.0.1: a request the server's budgets
refuse (429, with Retry-After: it did not run) is sent again, and raised at once with ``retries=0``.

Ground truth: the server's own answers (the raw statuses of a storm from other threads) and the world's
state after the client's edits (the teleported body where the last teleport put it).
"""

from __future__ import annotations

import threading

import pytest
from serve_helpers import SCENES, serve

from simrun.client import Client, ClientError

BALL = {"type": "Sphere", "name": "ball", "radius": 0.05, "free": True, "pose": {"position": [2.0, 2.0, 0.05]}}


def test_a_refused_request_is_sent_again_after_retry_after_and_raised_without_retries() -> None:
    with serve(SCENES / "boebot.toml", "--rate", "1", "--edit") as server:
        patient, impatient = Client(server.url, retries=10), Client(server.url, retries=0)
        patient.insert(BALL)
        stop = threading.Event()

        def storm() -> None:  # other requests from this address spend its budgets
            while not stop.is_set():
                server.request("POST", "/api/entities/ball/teleport", {"position": [2.0, 2.0, 0.05]})

        threads = [threading.Thread(target=storm) for _ in range(4)]
        for thread in threads:
            thread.start()
        try:
            refused = []
            for _ in range(200):
                try:
                    impatient.teleport("ball", [2.0, 2.0, 0.05])
                except ClientError as exc:
                    refused.append(exc.status)
                    break
            assert refused == [429]  # no retries: the budget's refusal, at once
            for k in range(10):  # every one of these goes through, however often it is refused first
                patient.teleport("ball", [2.5, 0.1 * k, 0.05])
        finally:
            stop.set()
            for thread in threads:
                thread.join()
        position = patient.entity("ball")["pose"][:3]  # world [x, y, z, qw, qx, qy, qz] now
        assert position[0] == pytest.approx(2.5, abs=0.05) and position[1] == pytest.approx(0.9, abs=0.05)
