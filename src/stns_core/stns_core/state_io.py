"""Save and load the learner's whole state (one versioned .npz file, written atomically).

Layout: ``meta`` (a JSON string: format, version, config, dimensions, RNG state, agent and
situation scalars, event log, pending records) plus numpy arrays (history columns, each
situation's mean / covariance / instance slots). Loading checks everything and raises
StnsStateError naming the file and the problem; saving writes a temporary file beside the
target and renames it, so a failed save never destroys the previous file.
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
from collections import deque
from os import PathLike
from typing import TYPE_CHECKING, Any

import numpy as np

from .config import StnsConfig
from .errors import StnsError, StnsStateError
from .history import History
from .records import StepRecord
from .situation import R_KIND, T_KIND, Situation

if TYPE_CHECKING:
    from .agent import StnsAgent

FORMAT = "stns_core.learner"
FORMAT_VERSION = 1


def save_agent(agent: StnsAgent, path: str | PathLike) -> None:
    path = os.fspath(path)
    learner = agent.learner
    arrays: dict[str, np.ndarray] = {}
    for name, arr in learner.hist.state().items():
        arrays[f"hist_{name}"] = arr
    sits = []
    for k, sit in enumerate(learner.order):
        sits.append({
            "id": sit.id, "kind": sit.kind, "behaviour": sit.behaviour, "parent": sit.parent,
            "reward_key": sit.reward_key, "created": sit.created, "utility": sit.utility,
            "boundary": sit.boundary, "fitted": sit.fitted, "shape_dirty": sit.shape_dirty,
        })
        arrays[f"sit{k}_mean"] = sit.mean
        arrays[f"sit{k}_cov"] = sit.cov
        arrays[f"sit{k}_pos"] = np.flatnonzero(sit.pos)
        arrays[f"sit{k}_neg"] = np.flatnonzero(sit.neg)
    meta = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "config": agent.config.to_dict(),
        "obs_dim": agent.obs_dim,
        "n_behaviours": agent.n_behaviours,
        "rng_state": agent.rng.bit_generator.state,
        "trial": agent.trial,
        "current": agent._current,
        "plan_utility": agent._plan_utility,
        "running": None if agent._run is None else agent._run.to_dict(),
        "plan": [list(e) for e in agent._plan],
        "prev_reached": agent._prev_reached,
        "pending": [r.to_dict() for r in agent._pending],
        "next_id": learner.next_id,
        "situations": sits,
        "events": list(learner.events),
        "event_count": learner.event_count,
    }
    if agent._margin_uses:  # only when used (option margin_plan="nearest_r")
        meta["margin_uses"] = {str(k): v for k, v in agent._margin_uses.items()}
    if agent._tries:  # only when used (option explore_untried)
        meta["tries"] = {str(k): v for k, v in agent._tries.items()}
    if learner._change_at:  # only when used (option contradiction_window)
        meta["change_at"] = learner._change_at
    arrays["meta"] = np.array(json.dumps(meta))
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".stns-", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def load_agent(cls, path: str | PathLike) -> StnsAgent:
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            head = f.read(4)
        if head != b"PK\x03\x04":  # np.load would try it as a pickle and say so, not why
            raise StnsStateError(f"{path}: not a readable learner file (not an .npz archive: it "
                                 f"starts with {head!r}, not b'PK\\x03\\x04')")
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except FileNotFoundError as exc:
        raise StnsStateError(f"{path}: no such file") from exc
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise StnsStateError(f"{path}: not a readable learner file ({exc})") from exc
    try:
        return _restore(cls, arrays)
    except StnsStateError as exc:
        raise StnsStateError(f"{path}: {exc}") from exc
    except (StnsError, KeyError, ValueError, TypeError, IndexError, AttributeError,
            json.JSONDecodeError, np.linalg.LinAlgError) as exc:
        raise StnsStateError(f"{path}: incompatible or corrupt learner state "
                             f"({type(exc).__name__}: {exc})") from exc


def _restore(cls, arrays: dict[str, np.ndarray]) -> StnsAgent:
    from .agent import _Running

    if "meta" not in arrays:
        raise StnsStateError("no 'meta' entry: not a stns_core learner file")
    meta: dict[str, Any] = json.loads(str(arrays["meta"]))
    if meta.get("format") != FORMAT:
        raise StnsStateError(f"format {meta.get('format')!r} is not {FORMAT!r}")
    if meta.get("version") != FORMAT_VERSION:
        raise StnsStateError(
            f"format version {meta.get('version')!r} unsupported (expected {FORMAT_VERSION})")
    config = StnsConfig.from_dict(meta["config"])
    agent = cls(config, int(meta["obs_dim"]), int(meta["n_behaviours"]))
    learner = agent.learner
    hist = History.from_state({k[5:]: v for k, v in arrays.items() if k.startswith("hist_")})
    if hist.capacity != config.history_size or hist.dim != agent.obs_dim:
        raise StnsStateError(f"history shape ({hist.capacity}, {hist.dim}) does not match "
                             f"history_size {config.history_size} / obs_dim {agent.obs_dim}")
    learner.hist = hist
    learner.next_id = int(meta["next_id"])
    _check_history(hist, agent.n_behaviours, learner.next_id)
    for k, d in enumerate(meta["situations"]):
        if d["kind"] not in (R_KIND, T_KIND):
            raise StnsStateError(f"situation kind {d['kind']!r}")
        sit = Situation(d["id"], d["kind"], d["behaviour"], hist.capacity, hist.dim,
                        parent=d["parent"], reward_key=d["reward_key"], created=d["created"])
        if not 0 < sit.id < learner.next_id or sit.id in learner.by_id:
            raise StnsStateError(f"situation id {sit.id} invalid or repeated")
        mean, cov = arrays[f"sit{k}_mean"], arrays[f"sit{k}_cov"]
        if mean.shape != (hist.dim,) or cov.shape != (hist.dim, hist.dim):
            raise StnsStateError(f"situation {sit.id} shape arrays have the wrong size")
        _check_situation(sit.id, d, mean, cov, agent.n_behaviours)
        sit.set_shape(mean, cov, d["boundary"], d["fitted"])
        sit.shape_dirty = bool(d["shape_dirty"])
        sit.utility = float(d["utility"])
        sit.pos[arrays[f"sit{k}_pos"]] = True
        sit.neg[arrays[f"sit{k}_neg"]] = True
        learner.order.append(sit)
        learner.by_id[sit.id] = sit
    learner.events = deque(meta["events"], maxlen=config.event_log_size)
    learner._change_at = int(meta.get("change_at", 0))
    if not 0 <= learner._change_at <= hist.total:
        raise StnsStateError(f"change_at {learner._change_at} outside the history's "
                             f"0..{hist.total} records")
    learner.event_count = int(meta["event_count"])
    learner.structure_version += 1
    learner.classifier.invalidate()
    learner.refresh_nn_window()
    rng = np.random.default_rng()
    rng.bit_generator.state = meta["rng_state"]
    agent.rng = rng
    agent.trial = int(meta["trial"])
    agent._current = int(meta["current"])
    agent._plan_utility = float(meta["plan_utility"])
    agent._run = None if meta["running"] is None else _Running.from_dict(meta["running"])
    agent._plan = [(int(b), int(d)) for b, d in meta["plan"]]
    _check_agent_scalars(agent, learner.next_id)
    agent._prev_reached = meta["prev_reached"]
    agent._pending = [StepRecord.from_dict(r) for r in meta["pending"]]
    agent._margin_uses = {int(k): [bool(u) for u in v]
                          for k, v in meta.get("margin_uses", {}).items()}
    agent._tries = {int(k): [int(t) for t in v] for k, v in meta.get("tries", {}).items()}
    if any(len(t) != agent.n_behaviours for t in agent._tries.values()):
        raise StnsStateError(f"tries per situation must have {agent.n_behaviours} entries "
                             f"(n_behaviours), got {meta['tries']!r}")
    return agent


# A file that unzips can still hold values no learner produces (a hand edit, a flipped bit):
# loaded, a NaN shape classifies nothing and an unknown behaviour fails only later, mid-run.

def _first_non_finite(arr: np.ndarray) -> tuple[int, ...] | None:
    bad = np.argwhere(~np.isfinite(arr))
    return None if bad.size == 0 else tuple(int(i) for i in bad[0])


def _check_history(hist: History, n_behaviours: int, next_id: int) -> None:
    for name in ("x", "x_next", "reward"):
        at = _first_non_finite(getattr(hist, name))
        if at is not None:
            raise StnsStateError(f"history {name} holds a non-finite value "
                                 f"({getattr(hist, name)[at]}) in slot {at[0]}")
    valid = np.flatnonzero(hist.valid)
    bad = valid[(hist.b[valid] < -1) | (hist.b[valid] >= n_behaviours)]
    if bad.size:
        raise StnsStateError(f"history behaviour {hist.b[bad[0]]} in slot {bad[0]} is not -1 "
                             f"(arrival) or 0..{n_behaviours - 1}")
    for labels in (hist.s, hist.s_next):
        bad = valid[(labels[valid] < 0) | (labels[valid] >= next_id)]
        if bad.size:
            raise StnsStateError(f"history situation label {labels[bad[0]]} in slot {bad[0]} "
                                 f"is not 0..{next_id - 1}")


def _check_situation(sit_id: int, d: dict[str, Any], mean: np.ndarray, cov: np.ndarray,
                     n_behaviours: int) -> None:
    for what, arr in (("mean", mean), ("covariance", cov)):
        at = _first_non_finite(arr)
        if at is not None:
            raise StnsStateError(f"situation {sit_id}: {what} holds a non-finite value "
                                 f"({arr[at]})")
    boundary, utility = float(d["boundary"]), float(d["utility"])
    if not (np.isfinite(boundary) and boundary >= 0.0):
        raise StnsStateError(f"situation {sit_id}: boundary {boundary} is not a finite number "
                             f">= 0")
    if not np.isfinite(utility):
        raise StnsStateError(f"situation {sit_id}: utility {utility} is not finite")
    if not 0 <= int(d["behaviour"]) < n_behaviours:
        raise StnsStateError(f"situation {sit_id}: behaviour {d['behaviour']} is not "
                             f"0..{n_behaviours - 1}")


def _check_agent_scalars(agent: StnsAgent, next_id: int) -> None:
    if not 0 <= agent._current < next_id:
        raise StnsStateError(f"current situation {agent._current} is not 0..{next_id - 1}")
    if not np.isfinite(agent._plan_utility):
        raise StnsStateError(f"plan_utility {agent._plan_utility} is not finite")
    for b, d in agent._plan:
        if not 0 <= b < agent.n_behaviours:
            raise StnsStateError(f"plan step [{b}, {d}]: behaviour {b} is not "
                                 f"0..{agent.n_behaviours - 1}")
