"""`DirectClient`: one headless pybullet physics server with its id bound into every call.

The same idea as ``pybullet_utils.bullet_client.BulletClient`` (which the world used
first), with two differences: it connects without the ``options`` argument (which makes
pybullet print ``argv[0]=`` on stdout), and it caches the bound functions, so that the
hot loop does not build a new ``functools.partial`` per call.
"""

from __future__ import annotations

import functools
import inspect
import os
from typing import Any

import pybullet


class DirectClient:
    """A pybullet DIRECT (headless) client; ``close()`` is safe to call twice."""

    def __init__(self) -> None:
        self._pid = os.getpid()
        self._id: int = pybullet.connect(pybullet.DIRECT)
        if self._id < 0:
            raise RuntimeError("pybullet could not start a DIRECT physics server")

    @property
    def client_id(self) -> int:
        """The pybullet physics client id (-1 once closed)."""
        return self._id

    def __getattr__(self, name: str) -> Any:
        attribute = getattr(pybullet, name)
        if inspect.isbuiltin(attribute):
            if self._id < 0:
                raise RuntimeError("the pybullet client is closed")
            attribute = functools.partial(attribute, physicsClientId=self._id)
            self.__dict__[name] = attribute
        return attribute

    def close(self) -> None:
        """Disconnect (idempotent; a no-op in a forked child)."""
        if self._id >= 0 and self._pid == os.getpid():
            try:
                pybullet.disconnect(physicsClientId=self._id)
            except pybullet.error:
                pass
        pid = self._pid
        self.__dict__.clear()
        self.__dict__.update(_id=-1, _pid=pid)

    def __del__(self) -> None:
        if self.__dict__.get("_id", -1) >= 0:
            self.close()
