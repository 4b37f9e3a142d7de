"""History database (paper section 4, section 5.3 operation 1): the newest records only.

A ring buffer of ``capacity`` behaviour-step records. Appending to a full buffer overwrites
(forgets) the oldest record; the caller clears that slot from every instance population.
"""

from __future__ import annotations

import numpy as np

ARRIVAL = -1  # behaviour code of a goal-arrival record (footnote 8: data, no behaviour)


class History:
    """Columns of the stored records, indexed by ring slot.

    ``x``: input at the start of the behaviour; ``b``: behaviour (ARRIVAL for an arrival
    record); ``reward``: summed over the behaviour; ``x_next``: input where the behaviour
    step ended; ``s`` / ``s_next``: situation ids of ``x`` / ``x_next`` (re-labelled after big
    modifications, see algorithm.md); ``terminal``: the behaviour ended at goal arrival.
    """

    def __init__(self, capacity: int, dim: int) -> None:
        self.capacity = int(capacity)
        self.dim = int(dim)
        self.x = np.zeros((capacity, dim))
        self.x_next = np.zeros((capacity, dim))
        self.b = np.full(capacity, ARRIVAL, dtype=np.int64)
        self.reward = np.zeros(capacity)
        self.s = np.zeros(capacity, dtype=np.int64)
        self.s_next = np.zeros(capacity, dtype=np.int64)
        self.terminal = np.zeros(capacity, dtype=bool)
        self.valid = np.zeros(capacity, dtype=bool)
        self.head = 0  # slot written next
        self.total = 0  # records ever appended

    def __len__(self) -> int:
        return min(self.total, self.capacity)

    def append(self, x, s, b, reward, x_next, s_next, terminal) -> tuple[int, bool]:
        """Store one record; returns (slot, whether an old record was forgotten)."""
        slot = self.head
        forgot = bool(self.valid[slot])
        self.x[slot] = x
        self.x_next[slot] = x_next
        self.b[slot] = b
        self.reward[slot] = reward
        self.s[slot] = s
        self.s_next[slot] = s_next
        self.terminal[slot] = terminal
        self.valid[slot] = True
        self.head = (slot + 1) % self.capacity
        self.total += 1
        return slot, forgot

    def chronological(self) -> np.ndarray:
        """Valid slots, oldest first."""
        if self.total <= self.capacity:
            return np.arange(self.total)
        return np.concatenate([np.arange(self.head, self.capacity), np.arange(self.head)])

    ARRAYS = ("x", "x_next", "b", "reward", "s", "s_next", "terminal", "valid")

    def state(self) -> dict[str, np.ndarray]:
        out = {name: getattr(self, name).copy() for name in self.ARRAYS}
        out["counters"] = np.array([self.head, self.total], dtype=np.int64)
        return out

    @classmethod
    def from_state(cls, data: dict[str, np.ndarray]) -> History:
        capacity, dim = data["x"].shape
        hist = cls(capacity, dim)
        for name in cls.ARRAYS:
            arr = np.asarray(data[name])
            if arr.shape != getattr(hist, name).shape:
                raise ValueError(f"history array {name} has shape {arr.shape}")
            getattr(hist, name)[...] = arr
        hist.head, hist.total = (int(v) for v in data["counters"])
        if not 0 <= hist.head < capacity or hist.total < 0:
            raise ValueError("history counters out of range")
        return hist
