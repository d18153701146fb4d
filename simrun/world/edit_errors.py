"""The error of an edit of a running world (:mod:`simrun.world.edit`): the field refused and why."""

from __future__ import annotations

from simrun.errors import EntityError


class EditError(EntityError):
    """An edit simrun or MuJoCo refused; the world is as it was before.

    Attributes:
        key: The field refused (``entity.mass``, ``entities[2].pose.position[1]``, ``name``); ``None``: the edit.
        reason: ``invalid`` (a bad value: HTTP 422), ``missing`` (no such entity, service or sensor: 404) or
            ``conflict`` (a name taken, a binding that cannot go: 409).
    """

    def __init__(self, message: str, key: str | None = None, entity: str | None = None, reason: str = "invalid"):
        super().__init__(message, key=key, entity=entity)
        self.reason = reason
