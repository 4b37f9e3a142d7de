"""How much a run's step figures move with its sample of trial sets: a bootstrap over sets.

    python -m stns_experiments.bootstrap RUN ... [--resamples 2000] [--seed 0] [--any-code]
                                         [--at STEP ...] [--blocks-at K ...] [--size N]
                                         [--json FILE]

The convergence step (Exp. 1, 3) and the Exp. 2 delay and blocks above the pre-fault band are
read off a pooled curve, each as the last block outside a 10 % band, so a run of 10 or 20
trial sets gives one draw of a noisy figure. This command resamples the trial sets of the
runs (taken as ``pool`` takes them: each once, the same checks) with replacement, recomputes
the figure on each resample with the definitions of metrics.py, and prints its quantiles
(2.5, 25, 50, 75, 97.5 %; each a resampled value) beside the figure of the sample itself.
Without ``--size``, Exp. 2 resamples the relearning, the from-scratch and the pre-training sets
of each level independently. ``--at`` (Exp. 1, 3) adds the share of resamples whose
convergence step is at or below each given step. Resamples whose figure is undefined (the
curve never stays in the band) count as above every step and are reported as such.
``--size N`` draws N of the pooled sets, without replacement, instead of as many as there are
with replacement: the spread of the figure a run of N sets would report, e.g. the paper's 20
(Exp. 1) or 10 (Exp. 2), from a pool of many more. In Exp. 2 a draw is what such a run holds:
N pre-trained learners, the relearning sets of those same learners (paired by root seed and
set index) and N from-scratch sets. ``--blocks-at K ...`` (Exp. 2) adds the share of resamples
with at most K blocks above the pre-fault band.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from stns_experiments import metrics as M
from stns_experiments.config import ExperimentError
from stns_experiments.pool import collect, print_and_save

QUANTILES = (2.5, 25.0, 50.0, 75.0, 97.5)


def _counts(sets: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per set: block behaviours, block arrivals (sets x blocks) and final (behaviours,
    arrivals) (sets x 2)."""
    bs = np.array([s["block_behaviours"] for s in sets], dtype=np.int64)
    ar = np.array([s["block_arrivals"] for s in sets], dtype=np.int64)
    fin = np.array([[s["final_behaviours"], s["final_arrivals"]] for s in sets], dtype=np.int64)
    return bs, ar, fin


def learning_figures(bs: np.ndarray, ar: np.ndarray, fin: np.ndarray, params: dict
                     ) -> dict[str, float | None]:
    """Final level and the two convergence steps of a group of sets (rows of the counts),
    as ``summarise_sets`` computes them."""
    B, tol = params["block_size"], params["convergence_tol"]
    b, a = bs.sum(0), ar.sum(0)
    final = float(M.ratio(*fin.sum(0)))
    return {"final": final,
            "convergence_step": M.convergence_block(M.ratio(b, a), final, B, tol),
            "convergence_step_trailing": M.convergence_trailing(
                b, a, final, B, params["trailing_window"], tol)}


def fault_figures(relearn: tuple, scratch: tuple | None, base_fin: np.ndarray, params: dict
                  ) -> dict[str, float | None]:
    """Exp. 2 delay and blocks above the pre-fault band of one level, as
    ``exp2_level_entry`` computes them, from (block behaviours, block arrivals, final); no
    delay without from-scratch sets."""
    B, tol = params["block_size"], params["convergence_tol"]
    rc = M.ratio(relearn[0].sum(0), relearn[1].sum(0))
    out: dict[str, float | None] = {"delay_steps": None, "blocks_worse_than_prefault": None}
    level = float(M.ratio(*scratch[2].sum(0))) if scratch is not None else float("nan")
    if np.isfinite(level):
        sc = M.ratio(scratch[0].sum(0), scratch[1].sum(0))
        tr = M.first_block_at_or_below(rc, level, B, tol)
        ts = M.first_block_at_or_below(sc, level, B, tol)
        out["delay_steps"] = None if tr is None or ts is None else tr - ts
    pre = float(M.ratio(*base_fin.sum(0))) if len(base_fin) else float("nan")
    if np.isfinite(pre):
        rc = np.asarray(rc, dtype=float)
        out["blocks_worse_than_prefault"] = int(
            (~(np.isfinite(rc) & (rc <= (1 + tol) * pre))).sum())
    return out


def spread(sample: float | None, draws: list[float | None], at: list[int]) -> dict[str, Any]:
    """The figure of the sample, quantiles of the resampled figures (undefined ones as
    +inf), their share undefined, and the share at or below each step of ``at``."""
    vals = np.array([np.inf if v is None else float(v) for v in draws])
    # inverted_cdf: each quantile is a resampled value (a step on the block grid), and an
    # undefined one (+inf) is never interpolated with a finite one
    q = (np.percentile(vals, QUANTILES, method="inverted_cdf") if len(vals)
         else np.full(len(QUANTILES), np.nan))
    return {"sample": sample,
            "quantiles": {f"{k:g}": (None if not np.isfinite(v) else float(v))
                          for k, v in zip(QUANTILES, q, strict=True)},
            "undefined": float(np.mean(~np.isfinite(vals))) if len(vals) else None,
            "at_or_below": {str(s): float(np.mean(vals <= s)) for s in at}}


def _is_whole(value: Any, lowest: int) -> bool:
    """Is ``value`` an int >= ``lowest``? (A bool is not, though Python counts it an int.)"""
    return not isinstance(value, bool) and isinstance(value, int) and value >= lowest


def _check_whole(name: str, value: Any, lowest: int) -> None:
    """Refuse a value that is not an int >= ``lowest`` (bools included), naming it."""
    if not _is_whole(value, lowest):
        raise ExperimentError(f"{name} must be a whole number >= {lowest}, got {value!r}")


def _whole_list(name: str, values: list[int] | None, what: str) -> list[int]:
    """``values`` as a list, each an int >= 0 (bools refused), else an error naming it."""
    values = [] if values is None else list(values)
    bad = [v for v in values if not _is_whole(v, 0)]
    if bad:
        raise ExperimentError(f"{name} takes {what} >= 0, got {bad[0]!r}")
    return values


def _base_of(c: dict[str, Any], relearn: list[dict], level: str) -> list[int]:
    """For each relearning set, the position in ``c['base_sets']`` of the pre-trained learner
    it relearned from (same root seed, same set index), or an error naming the set."""
    pos = {id(b): j for j, b in enumerate(c["base_sets"])}
    base_at: dict[tuple, int] = {}
    seed_of: dict[int, Any] = {}
    for run in c["runs"]:
        root = run["params"]["seed"]
        for b in run["base_sets"]:
            if id(b) in pos:
                base_at.setdefault((root, b.get("index")), pos[id(b)])
        seed_of.update({id(s): root for s in run["sets"]})
    out = []
    for s in relearn:
        k = (seed_of[id(s)], s.get("index"))
        if k[1] is None or k not in base_at:
            raise ExperimentError(f"--size: relearning set {s['key']} of root seed {k[0]} has "
                                  f"no pre-training set of its index ({k[1]!r}) at {level}")
        out.append(base_at[k])
    if len(set(out)) != len(c["base_sets"]):
        raise ExperimentError(f"--size: {level} holds relearning sets for {len(set(out))} of "
                              f"the {len(c['base_sets'])} pre-trained learners: a draw of "
                              f"learners would miss some")
    return out


def bootstrap(folders: list[Path], resamples: int = 2000, seed: int = 0,
              any_code: bool = False, at: list[int] | None = None,
              size: int | None = None, blocks_at: list[int] | None = None) -> dict[str, Any]:
    """Bootstrap figures of the runs in ``folders`` (see the module docstring); ``size``:
    sets per draw, without replacement (None: all, with replacement); ``blocks_at`` (Exp. 2):
    block counts whose share at or below is reported."""
    _check_whole("--resamples", resamples, 1)
    _check_whole("--seed", seed, 0)
    at = _whole_list("--at", at, "steps")
    blocks_at = _whole_list("--blocks-at", blocks_at, "block counts")
    if size is not None:
        _check_whole("--size", size, 1)
    c = collect(folders, any_code)
    p = c["params"]
    if blocks_at and p["experiment"] in ("exp1", "exp3"):
        raise ExperimentError(f"--blocks-at is for exp2 runs, not {p['experiment']}")
    if at and p["experiment"] not in ("exp1", "exp3"):
        raise ExperimentError(f"--at is for exp1 and exp3 runs, not {p['experiment']} "
                              f"(there: --blocks-at)")
    rng = np.random.default_rng(seed)
    out: dict[str, Any] = {"experiment": p["experiment"], "resamples": resamples,
                           "seed": seed, "pooled_from": c["pooled_from"]}
    if p["experiment"] in ("exp1", "exp3"):
        bs, ar, fin = _counts(c["sets"])
        n = len(bs)
        if size is not None and size > n:
            raise ExperimentError(f"--size {size} is more than the {n} trial sets pooled")
        draws = []
        for _ in range(resamples):
            i = (rng.integers(n, size=n) if size is None
                 else rng.choice(n, size=size, replace=False))
            draws.append(learning_figures(bs[i], ar[i], fin[i], p))
        own = learning_figures(bs, ar, fin, p)
        out["trial_sets"] = n
        out["size"] = size
        out["figures"] = {k: spread(own[k], [d[k] for d in draws], at if "step" in k else [])
                          for k in own}
        return out
    base_fin = _counts(c["base_sets"])[2] if c["base_sets"] else np.zeros((0, 2), np.int64)
    nb = len(base_fin)
    out["trial_sets"] = nb
    out["size"] = size
    out["levels"] = {}
    if size is not None and size > nb:
        raise ExperimentError(f"--size {size} is more than the {nb} pre-trained learners pooled")
    for name, rl, sc in c["levels"].values():
        if not rl:
            continue  # nothing relearned at this level: no figure to resample
        r, s = _counts(rl), (_counts(sc) if sc else None)
        if size is not None:
            rl_base = np.array(_base_of(c, rl, name))
            if s is not None and size > len(sc):
                raise ExperimentError(f"--size {size} is more than the {len(sc)} from-scratch "
                                      f"sets pooled at {name}")
        draws = []
        for _ in range(resamples):
            rs = None
            if size is None:  # each group resampled on its own, with replacement
                # (in this order of draws, so that earlier --seed figures repeat)
                ir = rng.integers(len(rl), size=len(rl))
                if s is not None:
                    i_s = rng.integers(len(sc), size=len(sc))
                    rs = tuple(x[i_s] for x in s)
                ib = rng.integers(max(nb, 1), size=nb)
            else:  # a run of `size` learners: their pre-training and their relearning
                ib = rng.choice(nb, size=size, replace=False)
                ir = np.flatnonzero(np.isin(rl_base, ib))
                if s is not None:
                    i_s = rng.choice(len(sc), size=size, replace=False)  # one draw for all
                    rs = tuple(x[i_s] for x in s)
            draws.append(fault_figures(tuple(x[ir] for x in r), rs, base_fin[ib], p))
        own = fault_figures(r, s, base_fin, p)
        out["levels"][name] = {
            "relearn_sets": len(rl), "scratch_sets": len(sc),
            "delay_steps": spread(own["delay_steps"], [d["delay_steps"] for d in draws], []),
            "blocks_worse_than_prefault": spread(
                own["blocks_worse_than_prefault"],
                [d["blocks_worse_than_prefault"] for d in draws], blocks_at)}
    return out


def _fmt(v: float | None) -> str:
    return "never" if v is None else f"{v:g}"


def _row(label: str, f: dict) -> str:
    q = " / ".join(_fmt(v) for v in f["quantiles"].values())
    cells = [label, _fmt(f["sample"]), q, f"{100 * (f['undefined'] or 0.0):.1f} %"]
    cells += [f"{100 * v:.1f} %" for v in f["at_or_below"].values()]
    return "| " + " | ".join(cells) + " |"


def describe(s: dict) -> str:
    src = s["pooled_from"]
    lines = [f"### {s['experiment']}: bootstrap over trial sets, {s['resamples']} resamples "
             f"(seed {s['seed']})", "",
             f"Runs: {', '.join('`' + r + '`' for r in src['runs'])}; {src['code']}.", "",
             "Quantiles 2.5 / 25 / 50 / 75 / 97.5 %; 'never': the curve does not stay in the "
             "band (counted as above every step).", ""]
    if "figures" in s:
        at = list(s["figures"]["convergence_step"]["at_or_below"])
        lines.append(f"{s['trial_sets']} trial sets" + (
            "." if s.get("size") is None else
            f"; each draw {s['size']} of them without replacement (the figure a run of "
            f"{s['size']} sets would report)."))
        lines.append("")
        lines.append("| figure | sample | resampled quantiles | undefined |"
                     + "".join(f" at or below {a} |" for a in at))
        lines.append("|---|---|---|---|" + "---|" * len(at))
        for key, label in (("convergence_step", "convergence (block rule), steps"),
                           ("convergence_step_trailing", "convergence (trailing rule), steps")):
            lines.append(_row(label, s["figures"][key]))
        f = s["figures"]["final"]
        q = " / ".join("-" if v is None else f"{v:.2f}" for v in f["quantiles"].values())
        lines.append(f"| behaviours to goal, final window | {f['sample']:.2f} | {q} | "
                     f"{100 * (f['undefined'] or 0.0):.1f} % |" + " |" * len(at))
    else:
        if s.get("size") is None:
            lines.append(f"{s['trial_sets']} pre-training sets; per level the relearning and "
                         f"from-scratch sets resampled independently.")
        else:
            lines.append(f"{s['trial_sets']} pre-trained learners; each draw {s['size']} of "
                         f"them without replacement, with their own relearning sets, and "
                         f"{s['size']} from-scratch sets (the figure a run of {s['size']} "
                         f"sets would report).")
        lines.append("")
        first = next(iter(s["levels"].values()), None)
        at = list(first["blocks_worse_than_prefault"]["at_or_below"]) if first else []
        lines.append("| level | figure | sample | resampled quantiles | undefined |"
                     + "".join(f" at most {a} blocks |" for a in at))
        lines.append("|---|---|---|---|---|" + "---|" * len(at))
        for name, e in s["levels"].items():
            if e["scratch_sets"]:
                lines.append(_row(f"{name} | delay against scratch, steps", e["delay_steps"])
                             + " |" * len(at))
            else:  # not "never": there is no scratch curve to be late against
                lines.append(f"| {name} | delay against scratch, steps | - | no from-scratch "
                             f"sets | - |" + " |" * len(at))
            lines.append(_row(f"{name} | blocks above the pre-fault band",
                              e["blocks_worse_than_prefault"]))
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stns_experiments.bootstrap",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders of one experiment")
    ap.add_argument("--resamples", type=int, default=2000, help="bootstrap resamples (2000)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the resampling (0)")
    ap.add_argument("--at", type=int, nargs="*", default=[],
                    help="Exp. 1, 3: also the share of resamples converged at or before "
                         "these steps")
    ap.add_argument("--any-code", action="store_true",
                    help="pool runs made on different library code (named in the output)")
    ap.add_argument("--size", type=int, default=None,
                    help="draw this many of the pooled sets without replacement (the spread "
                         "a run of that many sets would show; Exp. 2: that many learners)")
    ap.add_argument("--blocks-at", type=int, nargs="*", default=[],
                    help="Exp. 2: also the share of resamples with at most these blocks "
                         "above the pre-fault band")
    ap.add_argument("--json", type=Path, help="also write the figures to this file")
    args = ap.parse_args(argv)
    try:
        s = bootstrap(args.runs, args.resamples, args.seed, args.any_code, args.at,
                      args.size, args.blocks_at)
    except ExperimentError as e:
        sys.stderr.write(f"error: {e}\n")
        return 2
    return print_and_save(describe(s), s, args.json)


if __name__ == "__main__":
    sys.exit(main())
