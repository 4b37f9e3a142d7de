"""The tick loop, per-trial-set seeds, and the parallel runner with progress and Ctrl-C.

Each trial set is one task run in its own process (a ``spawn`` pool, one process per
core by default). A task writes its own outputs (records, learner state, a small JSON
result) as soon as it finishes, so an interrupted run keeps every finished trial set.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import queue
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from stns_experiments.config import ExperimentError


def set_seeds(seed: int, n: int, stream: int = 0) -> list[dict[str, int]]:
    """Seeds of trial sets 0..n-1: world and agent seeds from SeedSequence(seed).spawn.

    ``stream`` separates independent families (0: learners; 1: random-policy runs; 2+:
    experiment-specific), so adding trial sets never changes the seeds of the first ones.
    """
    root = np.random.SeedSequence([int(seed), int(stream)])
    out = []
    for i, child in enumerate(root.spawn(n)):
        w, a, r = (int(v) for v in child.generate_state(3, dtype=np.uint32))
        out.append({"index": i, "world_seed": w, "agent_seed": a, "rng_seed": r})
    return out


class _Progress:
    """Steps done per task, reported from inside the tick loop."""

    def __init__(self, q: Any, key: str, every: int = 250) -> None:
        self.q, self.key, self.every, self.last = q, key, every, 0

    def __call__(self, steps: int) -> None:
        if self.q is not None and steps - self.last >= self.every:
            self.last = steps
            try:
                self.q.put_nowait((self.key, steps))
            except Exception:  # noqa: BLE001 - progress must never break a run
                pass


def run_loop(world, agent, steps: int, progress: Callable[[int], None] | None = None,
             max_ticks_per_step: int = 2000, state: dict | None = None) -> tuple[list, dict]:
    """The tick loop of INTERFACES.md until ``agent.behaviour_steps`` reaches ``steps``.

    ``state`` (obs, reward, term) continues a loop where an earlier call stopped; the
    returned dict is that state. Returns (records, state).
    """
    if state is None:
        obs, _ = world.reset()
        reward, term = 0.0, False
    else:
        obs, reward, term = state["obs"], state["reward"], state["term"]
    records: list = []
    ticks_since = 0
    last_steps = agent.behaviour_steps
    while agent.behaviour_steps < steps:
        a = agent.step(obs, reward, term)
        if agent.behaviour_steps != last_steps:
            last_steps = agent.behaviour_steps
            ticks_since = 0
            if progress is not None:
                progress(last_steps)
            records.extend(agent.pop_records())
        if a is None:
            obs, _ = world.reset()
            reward, term = 0.0, False
            continue
        obs, reward, term, trunc, _ = world.step(int(a))
        ticks_since += 1
        if ticks_since > max_ticks_per_step:
            raise ExperimentError(
                f"no behaviour step finished in {max_ticks_per_step} ticks "
                f"(max_ticks_per_step) at step {agent.behaviour_steps}: the learner or the "
                f"world does not stop behaviours")
        if trunc and not term:
            obs, _ = world.reset()
            reward, term = 0.0, False
    records.extend(agent.pop_records())
    return records, {"obs": obs, "reward": reward, "term": term}


def _init_worker(q: Any) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    global _QUEUE
    _QUEUE = q
    os.environ.setdefault("MPLBACKEND", "Agg")


_QUEUE: Any = None


def _call(job: tuple[Callable, dict]) -> tuple[str, dict | None, str | None]:
    fn, task = job
    return _call_inline(fn, task, _Progress(_QUEUE, task["key"]))


def _fmt(sec: float) -> str:
    sec = int(sec)
    return f"{sec // 60}m{sec % 60:02d}s" if sec >= 60 else f"{sec}s"


class ProgressLine:
    """A one-line progress report on stderr (rewritten in place on a terminal)."""

    def __init__(self, label: str, total_steps: int, n_tasks: int, enabled: bool = True) -> None:
        self.label, self.total, self.n = label, max(1, total_steps), n_tasks
        self.done_steps: dict[str, int] = {}
        self.finished = 0
        self.t0 = time.monotonic()
        self.last = 0.0
        self.tty = sys.stderr.isatty()
        self.enabled = enabled

    def update(self, key: str | None = None, steps: int | None = None, force: bool = False
               ) -> None:
        if key is not None and steps is not None:
            self.done_steps[key] = steps
        now = time.monotonic()
        if not self.enabled or (not force and now - self.last < (1.0 if self.tty else 30.0)):
            return
        self.last = now
        done = sum(self.done_steps.values())
        el = now - self.t0
        frac = min(1.0, done / self.total)
        eta = el * (1 - frac) / frac if frac > 0 else float("nan")
        bar = "#" * int(25 * frac)
        msg = (f"[{self.label}] |{bar:<25}| {100 * frac:5.1f}% {done}/{self.total} steps, "
               f"{self.finished}/{self.n} tasks, {_fmt(el)} elapsed"
               + (f", eta {_fmt(eta)}" if np.isfinite(eta) else ""))
        sys.stderr.write(("\r" + msg + "\x1b[K") if self.tty else (msg + "\n"))
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            self.update(force=True)
            if self.tty:
                sys.stderr.write("\n")
            sys.stderr.flush()


def run_tasks(fn: Callable[[dict, Callable[[int], None]], dict], tasks: list[dict], jobs: int,
              label: str, progress: bool = True
              ) -> tuple[dict[str, dict], dict[str, str], bool]:
    """Run ``fn(task, progress)`` for every task, ``jobs`` at a time.

    Every task has a unique ``key`` and a ``steps`` total (for the progress bar). Returns
    (results by key, errors by key, interrupted). Ctrl-C stops the running tasks and
    returns what finished.
    """
    total = sum(int(t.get("steps", 0)) for t in tasks)
    line = ProgressLine(label, total, len(tasks), enabled=progress)
    results: dict[str, dict] = {}
    errors: dict[str, str] = {}
    interrupted = False
    if jobs <= 1 or len(tasks) <= 1:
        try:
            for t in tasks:
                def prog(steps: int, key: str = t["key"]) -> None:
                    line.update(key, steps)
                key, res, err = _call_inline(fn, t, prog)
                line.finished += 1
                line.update(key, int(t.get("steps", 0)), force=True)
                if err is None:
                    results[key] = res
                else:
                    errors[key] = err
        except KeyboardInterrupt:
            interrupted = True
        line.close()
        return results, errors, interrupted
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    pool = ctx.Pool(processes=min(jobs, len(tasks)), initializer=_init_worker, initargs=(q,))
    try:
        pending = pool.imap_unordered(_call, [(fn, t) for t in tasks])
        remaining = len(tasks)
        while remaining:
            try:
                key, res, err = pending.next(timeout=0.5)
            except mp.TimeoutError:
                _drain(q, line)
                line.update()
                continue
            remaining -= 1
            line.finished += 1
            steps = next(int(t.get("steps", 0)) for t in tasks if t["key"] == key)
            _drain(q, line)
            line.update(key, steps, force=True)
            if err is None:
                results[key] = res
            else:
                errors[key] = err
        pool.close()
    except KeyboardInterrupt:
        interrupted = True
        pool.terminate()
    finally:
        pool.join()
        line.close()
    return results, errors, interrupted


def _drain(q: Any, line: ProgressLine) -> None:
    while True:
        try:
            key, steps = q.get_nowait()
        except queue.Empty:
            return
        line.done_steps[key] = max(line.done_steps.get(key, 0), steps)


def _call_inline(fn: Callable, task: dict, prog: Callable[[int], None]
                 ) -> tuple[str, dict | None, str | None]:
    """(key, result, None), or (key, None, error text): a failing task is reported with its
    name and the other tasks go on, in a worker process or in this one (--jobs 1) alike."""
    try:
        return task["key"], fn(task, prog), None
    except ExperimentError as e:
        return task["key"], None, str(e)
    except Exception as e:  # noqa: BLE001 - reported with the task's name, run goes on
        import traceback
        return task["key"], None, f"{type(e).__name__}: {e}\n{traceback.format_exc()}"


def workspace_root(start: Path | None = None) -> Path | None:
    """The git workspace this package (or the file ``start``) runs from, symlinks resolved,
    or None."""
    for d in Path(start or __file__).resolve().parents:
        if (d / ".git").exists():  # a directory, or a file in a git worktree
            return d
    return None


def git_state(root: Path, paths: list[str]) -> dict[str, Any] | None:
    """{"commit": short HEAD, "uncommitted": files under ``paths`` that differ from it} of
    the git workspace ``root``, or None when git cannot tell."""
    import subprocess

    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root,
                              capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", *paths], cwd=root,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0 or dirty.returncode != 0:
        return None
    return {"commit": head.stdout.strip(),
            "uncommitted": [ln[3:] for ln in dirty.stdout.split("\n") if ln.strip()]}


def library_hashes(packages: dict[str, Path]) -> dict[str, str]:
    """SHA-256 of every ``.py`` file of the given packages (name -> package directory), by
    "name/relative path". Taken when a run starts and when it ends: the trial sets run in
    spawned processes that import the libraries when they start, so a file edited meanwhile
    reaches the later sets, and git's state at either moment alone would not show it."""
    import hashlib

    out: dict[str, str] = {}
    for name, pkg in packages.items():
        pkg = Path(pkg)
        for f in sorted(pkg.rglob("*.py")):
            key = f"{name}/{f.relative_to(pkg).as_posix()}"
            try:
                out[key] = hashlib.sha256(f.read_bytes()).hexdigest()
            except OSError:  # removed while we read: it counts as changed
                out[key] = "unreadable"
    return out


def changed_files(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """The files of two ``library_hashes`` readings that were added, removed or edited."""
    return sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))


def outside_libraries(root: Path, packages: dict[str, Path]) -> dict[str, dict[str, Any]]:
    """The packages (name -> package directory) that are imported from outside the
    workspace ``root``, e.g. another checkout put first on PYTHONPATH, each with its path and,
    when it lies in a git workspace of its own, that workspace's commit and uncommitted files.
    The workspace's commit alone would otherwise name code the run did not use."""
    root = Path(root).resolve()
    out: dict[str, dict[str, Any]] = {}
    for name, pkg in packages.items():
        pkg = Path(pkg).resolve()
        if pkg == root or root in pkg.parents:
            continue
        entry: dict[str, Any] = {"path": str(pkg)}
        own = workspace_root(pkg / "__init__.py")
        state = git_state(own, [str(pkg.relative_to(own))]) if own is not None else None
        if state is not None:
            entry.update(state)
        out[name] = entry
    return out


def write_json(path: Path, data: Any) -> None:
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(sanitize(data), indent=2, default=_json_default) + "\n")
    tmp.replace(path)


def sanitize(o: Any) -> Any:
    """Replace NaN/inf by None recursively (JSON has no NaN)."""
    if isinstance(o, float):
        return o if np.isfinite(o) else None
    if isinstance(o, dict):
        return {k: sanitize(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [sanitize(v) for v in o]
    if isinstance(o, np.ndarray):
        return sanitize(o.tolist())
    if isinstance(o, np.floating):
        return sanitize(float(o))
    if isinstance(o, np.integer):
        return int(o)
    return o


def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
