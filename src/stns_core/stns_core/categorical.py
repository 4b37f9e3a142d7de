"""Categorical learning (paper section 5.3) with the history and the STN it rebuilds.

Extraction of R- and T-situations and the five maintenance operations:
1. populations of positive / negative instances, every behaviour step (``add_record``);
2. boundary adjustment (``_refit``), every ``adjust_interval`` steps or every step;
3. re-ordering by utility (``_periodic``), every ``adjust_interval`` steps;
4. validity check, recycling and the five elimination cases (``_validity``), every step;
5. elimination of situations with negative utility (``_periodic``).
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from .classifier import MARGIN, Classifier
from .config import StnsConfig
from .history import History
from .planning import Iprl, Pia
from .situation import R_KIND, T_KIND, Situation, in_nn_window, t_result_mask
from .stn import Stn

GOAL = -1  # target id of a plan element whose result is the goal reward


class Learner:
    """History, situations in discrimination order, STN and planner of one agent."""

    def __init__(self, cfg: StnsConfig, dim: int, n_behaviours: int) -> None:
        self.cfg = cfg
        # option t_result="unpunished": a penalised step reaches no situation (T-extraction,
        # T-positives, recycling); the STN keeps every record as it is
        self._unpunished = cfg.t_result == "unpunished"
        self.dim = dim
        self.n_behaviours = n_behaviours
        self.hist = History(cfg.history_size, dim)
        self.order: list[Situation] = []
        self.by_id: dict[int, Situation] = {}
        self.next_id = 1
        self.classifier = Classifier(dim)
        self.classifier.order = self.order  # the same list: re-ordering happens in place
        self.events: deque[dict[str, Any]] = deque(maxlen=cfg.event_log_size)
        self.event_count = 0
        self.structure_version = 0  # bumps on extraction / elimination / redefinition / order
        self._version = 0  # bumps on any change of history or labels
        self._lut = np.zeros(1, dtype=np.int64)
        self._lut_version = -1
        self._stn: Stn | None = None
        self._stn_version = -1
        self._planner: Iprl | Pia | None = None
        self._planner_version = -1
        self._recent: np.ndarray | None = None  # option nn_window: slots of the newest records
        self._change_at = 0  # option contradiction_window: records before it may be stale
        self.refresh_nn_window()

    # -- classification ---------------------------------------------------------------
    def classify(self, x: np.ndarray) -> int:
        return self.classifier.classify(x, self.hist.x)

    def nearest(self, x: np.ndarray, reach: float, kind: str | None = None) -> int:
        """Situation whose ellipsoid is nearest to ``x`` relative to its boundary, if within
        ``reach`` boundaries; 0: none."""
        return self.classifier.nearest(x, reach, kind)

    def reach_accepts(self, sid: int, x: np.ndarray) -> bool:
        """Option margin_plan="nearest_r_bitten": the bite of the ellipsoid carried beyond its
        boundary. Among situation ``sid``'s positive and negative instances and the margin
        records of its condition behaviour that missed its result, is the one nearest to
        ``x`` (std-scaled Euclidean, as the NN test of Situation.nn_accepts) a positive?
        With no such record, yes (nothing has bitten there yet)."""
        sit = self.by_id[sid]
        h = self.hist
        missed = (h.valid & (h.s == MARGIN) & (h.b == sit.behaviour)
                  & ~self._positive_mask(sit))
        members = in_nn_window(sit.pos | sit.neg | missed, self._recent)
        if not members.any():
            return True
        return self._nearest_is(members, sit.pos, x, sit.std)

    def _nearest_is(self, members: np.ndarray, label: np.ndarray, x: np.ndarray,
                    scale: np.ndarray) -> bool:
        """``label`` of the stored record among ``members`` (history-slot masks) nearest to
        ``x``, Euclidean with each dimension divided by ``scale``; ``members`` is not empty."""
        d2 = np.sum(((self.hist.x[members] - x) / scale) ** 2, axis=1)
        return bool(label[members][int(np.argmin(d2))])

    def pending_t_pairs(self, x: np.ndarray) -> list[tuple[int, int]]:
        """Option pending_t_try: (behaviour, R-situation) pairs that have no T-situation yet,
        whose stored margin records of that behaviour have reached that R-situation (a
        T-result), and whose margin outcome nearest to ``x`` was such a result. An outcome is
        a margin record of the behaviour that did not end at the goal; distances are
        Euclidean, each input dimension scaled by its standard deviation over the stored
        records (the T-situation that would scale them does not exist yet). The behaviour of
        the R-situation itself is left out: it would run on through it."""
        h = self.hist
        rs = [s for s in self.order if s.kind == R_KIND]
        if not rs:
            return []
        have = {(s.behaviour, s.parent) for s in self.order if s.kind == T_KIND}
        margin = h.valid & (h.s == MARGIN) & ~h.terminal
        std: np.ndarray | None = None
        out = []
        for b in range(self.n_behaviours):
            outcome = margin & (h.b == b)
            if not outcome.any():
                continue
            for r in rs:
                if b == r.behaviour or (b, r.id) in have:
                    continue
                reached = outcome & t_result_mask(h, b, r.id, self._unpunished)
                if not reached.any():
                    continue
                if std is None:
                    std = self._history_std()
                if self._nearest_is(outcome, reached, x, std):
                    out.append((b, r.id))
        return out

    def pending_r_behaviours(self, x: np.ndarray) -> list[int]:
        """Option pending_r_try: behaviours that have reached a goal reward
        (> ``r_min_r``) in the stored history but have no R-situation yet, and whose outcome
        nearest to ``x`` was such a reward. An outcome is a record of the behaviour that ended
        on a non-zero reward (a goal or a penalty); a step cut short without a reward says
        nothing about where the behaviour leads. Distances are Euclidean, each input dimension
        scaled by its standard deviation over the stored records (no situation's shape exists
        yet to scale by, as the NN test does)."""
        h = self.hist
        with_r = {s.behaviour for s in self.order if s.kind == R_KIND}
        outcome = h.valid & (h.b >= 0) & (h.reward != 0.0)
        goal = outcome & (h.reward > self.cfg.r_min_r)
        pending = [b for b in np.unique(h.b[goal]).tolist() if b not in with_r]
        if not pending:
            return []
        std = self._history_std()
        return [int(b) for b in pending if self._nearest_is(outcome & (h.b == b), goal, x, std)]

    def _history_std(self) -> np.ndarray:
        """Per-dimension standard deviation of the stored inputs (1 where it is 0): the
        scale of the pending tries' nearest-outcome tests, before any situation's shape."""
        std = self.hist.x[self.hist.valid].std(axis=0)
        std[std <= 0.0] = 1.0
        return std

    def classify_batch(self, xs: np.ndarray) -> np.ndarray:
        return self.classifier.classify_batch(xs, self.hist.x)

    # -- dense node indices, STN, planner ---------------------------------------------
    def lut(self) -> np.ndarray:
        """Situation id -> STN node (0 = margin; eliminated ids map to 0)."""
        if self._lut_version != self.structure_version or len(self._lut) < self.next_id:
            lut = np.zeros(self.next_id, dtype=np.int64)
            for k, sit in enumerate(self.order):
                lut[sit.id] = k + 1
            self._lut = lut
            self._lut_version = self.structure_version
        return self._lut

    def node_to_id(self, node: int) -> int:
        if node == 0:
            return MARGIN
        if node == len(self.order) + 1:
            return GOAL
        return self.order[node - 1].id

    def _stn_records(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(slots, node, next node) of the history's behaviour records that count in the STN."""
        h = self.hist
        sel = h.valid & (h.b >= 0)
        lut = self.lut()
        if self.cfg.margin_stn == "no_positives" and self.order:
            # option margin_stn: a positive instance classified into the margin was bitten
            # out of its situation; its stored success no longer speaks for the margin
            pos = np.logical_or.reduce([sit.pos for sit in self.order])
            sel &= (lut[h.s] != 0) | ~pos
        slots = np.nonzero(sel)[0]
        goal = len(self.order) + 1
        return slots, lut[h.s[slots]], np.where(h.terminal[slots], goal, lut[h.s_next[slots]])

    def stn(self) -> Stn:
        if self._stn_version != self._version or self._stn is None:
            slots, s, sn = self._stn_records()
            h = self.hist
            self._stn = Stn.from_records(s, h.b[slots], sn, h.reward[slots],
                                         len(self.order) + 2, self.n_behaviours)
            self._stn_version = self._version
        return self._stn

    def plan_stn(self) -> Stn:
        """The STN the planner uses: ``stn()``, or with option ``stn_half_life`` H > 0 the same
        maximum likelihood with each record weighted 2^(-age / H) (age in records), so where
        new and old outcomes of a (node, behaviour) pair differ the new ones dominate, while a
        pair used only long ago keeps its estimate (the weights cancel in the ratio)."""
        h_life = self.cfg.stn_half_life
        if h_life <= 0.0:
            return self.stn()
        slots, s, sn = self._stn_records()
        h = self.hist
        return Stn.from_records(s, h.b[slots], sn, h.reward[slots], len(self.order) + 2,
                                self.n_behaviours, weights=np.exp2(-self._ages()[slots] / h_life))

    def planner(self) -> Iprl | Pia:
        if self._planner_version != self._version or self._planner is None:
            cfg = self.cfg
            stn = self.plan_stn()
            if cfg.planner == "pia":
                self._planner = Pia(stn, cfg.gamma, cfg.n_max)
            else:
                self._planner = Iprl(stn, cfg.gamma, cfg.p_min, cfg.n_max,
                                     memo=cfg.iprl_memo)
            self._planner_version = self._version
        return self._planner

    def plan(self, sid: int) -> tuple[float, list[tuple[int, int]]]:
        """(utility, master plan as (behaviour, target id) pairs; GOAL for the goal)."""
        node = int(self.lut()[sid]) if sid < self.next_id else 0
        u, elems = self.planner().plan(node)
        return float(u), [(int(b), self.node_to_id(j)) for b, j in elems]

    def compute_utilities(self) -> dict[int, float]:
        planner = self.planner()
        us = planner.utilities(range(1, len(self.order) + 1))
        for sit, u in zip(self.order, us, strict=True):
            sit.utility = float(u)
        return {sit.id: sit.utility for sit in self.order}

    def compute_utilities_readonly(self) -> dict[int, float]:
        """Utilities under the current STN without touching the stored (ordering) ones."""
        us = self.planner().utilities(range(1, len(self.order) + 1))
        return {sit.id: float(u) for sit, u in zip(self.order, us, strict=True)}

    # -- events -----------------------------------------------------------------------
    def _event(self, kind: str, sit: Situation | None, **detail: Any) -> None:
        ev: dict[str, Any] = {"step": int(self.hist.total), "event": kind}
        if sit is not None:
            ev.update(situation=sit.id, kind=sit.kind, behaviour=sit.behaviour,
                      parent=sit.parent if sit.kind == T_KIND else None)
        ev.update(detail)
        self.events.append(ev)
        self.event_count += 1

    def _structure_changed(self) -> None:
        self.structure_version += 1
        self._version += 1
        self.classifier.invalidate()
        if self.cfg.relabel == "after_modification":
            self.relabel()

    def relabel(self) -> None:
        """Re-classify every stored input (start and end) with the current situations."""
        h = self.hist
        idx = np.flatnonzero(h.valid)
        if len(idx) and self.order:
            h.s[idx] = self.classify_batch(h.x[idx])
            h.s_next[idx] = self.classify_batch(h.x_next[idx])
        elif len(idx):
            h.s[idx] = MARGIN
            h.s_next[idx] = MARGIN
        for sit in self.order:
            if sit.kind == T_KIND:
                new = self._positive_mask(sit)
                if not np.array_equal(new, sit.pos):
                    sit.pos = new
                    sit.neg &= ~new
                    sit.shape_dirty = True
                    sit.nn_dirty = True
        self._version += 1

    def _positive_mask(self, sit: Situation) -> np.ndarray:
        return sit.positive_mask(self.hist, self.cfg.r_min_r, self._unpunished)

    def _met(self, sit: Situation, b: int, reward: float, s_next: int, terminal: bool) -> bool:
        return sit.result_met(b, reward, s_next, terminal, self.cfg.r_min_r, self._unpunished)

    # -- one behaviour step -----------------------------------------------------------
    def add_record(self, x, s: int, b: int, reward: float, x_next, s_next: int,
                   terminal: bool) -> None:
        """Store a record and run the learning of one behaviour step."""
        cfg = self.cfg
        h = self.hist
        slot, _ = h.append(x, s, b, reward, x_next, s_next, terminal)
        if self._recent is not None:
            self._slide_nn_window(slot)
        for sit in self.order:  # forgetting: the slot leaves every population
            if sit.pos[slot] or sit.neg[slot]:
                if sit.pos[slot]:
                    sit.shape_dirty = True
                sit.pos[slot] = sit.neg[slot] = False
                sit.nn_dirty = True
        if b >= 0:  # operation 1
            for sit in self.order:
                if self._met(sit, b, reward, s_next, terminal):
                    sit.pos[slot] = True
                    sit.shape_dirty = sit.nn_dirty = True
            own = self.by_id.get(s)
            if own is not None and own.behaviour == b and not self._met(
                    own, b, reward, s_next, terminal):
                own.neg[slot] = True
                own.nn_dirty = True
        if cfg.contradiction_radius > 0.0 and b >= 0:
            self._forget_contradicted(slot)
        self._version += 1
        self._extract()
        self._validity()
        if h.total % cfg.adjust_interval == 0:
            self._periodic()
            if cfg.validity_check == "also_after_periodic":
                # re-ordering and operation 5 relabel the history: without a second check,
                # situations they make inappropriate stay until the next step's check
                self._validity()
        if cfg.boundary_refit == "every_step":
            self._refit(only_dirty=True)

    # -- operation 2 ------------------------------------------------------------------
    def _refit(self, only_dirty: bool) -> None:
        changed = False
        for sit in self.order:
            if sit.shape_dirty or not only_dirty:
                self._fit(sit)
                changed = True
        if changed:
            self.classifier.invalidate()

    def _fit(self, sit: Situation) -> None:
        """Operation 2 on one situation, with the shape options of section 7.3 if set."""
        cfg = self.cfg
        if cfg.shape_scope == "all" or sit.kind == T_KIND:
            sit.fit(self.hist.x, cfg.cov_reg, cfg.shape_trim, cfg.boundary_quantile)
        else:
            sit.fit(self.hist.x, cfg.cov_reg)

    # -- extraction -------------------------------------------------------------------
    def _extract(self) -> bool:
        cfg = self.cfg
        h = self.hist
        beh = h.valid & (h.b >= 0)
        big = beh & (h.reward > cfg.r_min_r)
        if big.any():
            keys = np.round(h.reward[big], 6)
            bs = h.b[big]
            cands = []
            for key in np.unique(keys).tolist():
                per_b = np.bincount(bs[keys == key], minlength=self.n_behaviours)
                cands += [(-int(c), b, key) for b, c in enumerate(per_b.tolist())
                          if c > cfg.n_init_r]
            for neg_count, b, key in sorted(cands):
                if not self._exists((R_KIND, b, key)):
                    self._new_situation(R_KIND, b, 0, key, -neg_count)
                    return True
        if not self.order:
            return False
        lut = self.lut()
        n_nodes = len(self.order) + 2
        sel = beh & ~big & ~h.terminal & (lut[h.s] == 0)
        if self._unpunished:
            sel &= h.reward >= 0.0
        sn = lut[h.s_next[sel]]
        keep = sn != 0
        if not keep.any():
            return False
        key = h.b[sel][keep] * n_nodes + sn[keep]
        counts = np.bincount(key, minlength=self.n_behaviours * n_nodes)
        for k in np.argsort(-counts, kind="stable"):
            if counts[k] <= cfg.n_init_t:
                break
            b, node = divmod(int(k), n_nodes)
            parent = self.order[node - 1].id
            if not self._exists((T_KIND, b, parent)):
                self._new_situation(T_KIND, b, parent, 0.0, int(counts[k]))
                return True
        return False

    def _exists(self, attrs: tuple, besides: Situation | None = None) -> bool:
        return any(s.attributes() == attrs for s in self.order if s is not besides)

    def _new_situation(self, kind: str, b: int, parent: int, key: float, count: int) -> None:
        h = self.hist
        sit = Situation(self.next_id, kind, b, h.capacity, h.dim, parent=parent,
                        reward_key=key, created=h.total)
        self.next_id += 1
        sit.nn_recent = self._recent
        sit.pos = self._positive_mask(sit)
        self._fit(sit)
        self.order.append(sit)  # bottom of the tree until the next re-ordering
        self.by_id[sit.id] = sit
        self._event("extracted", sit, records=count, positives=sit.n_pos)
        self._structure_changed()
        self._negatives_from_history(sit)

    def _negatives_from_history(self, sit: Situation) -> None:
        """Option ``negatives_from_history`` (not the paper's): a new or redefined situation
        takes as negative instances the stored records that operation 1 would have made
        negatives had it existed then: its behaviour, its result not met, the start input
        classified into it now. Their nearest-neighbour bites then cut out at once the parts
        of the ellipsoid where the behaviour failed; the history is re-labelled after."""
        if not self.cfg.negatives_from_history:
            return
        h = self.hist
        idx = np.flatnonzero(h.valid & (h.b == sit.behaviour)
                             & ~self._positive_mask(sit) & ~sit.pos)
        if len(idx) == 0:
            return
        inside = idx[self.classify_batch(h.x[idx]) == sit.id]
        if len(inside) == 0:
            return
        sit.neg[inside] = True
        sit.nn_dirty = True
        self._event("negatives_seeded", sit, negatives=int(len(inside)))
        self._structure_changed()

    # -- operation 4 ------------------------------------------------------------------
    def _inappropriate(self, sit: Situation, counts: np.ndarray) -> str | None:
        cfg = self.cfg
        n_min = cfg.n_min_r if sit.kind == R_KIND else cfg.n_min_t
        if sit.n_pos < n_min:
            return "too_few_positives"
        if sit.kind == R_KIND:
            return "recent_failures" if self._broken(sit) is not None else None
        if sit.parent not in self.by_id:
            return "parent_eliminated"
        lut = self.lut()
        row = counts[lut[sit.id]]
        total = row.sum()
        if total <= 0:
            return None
        top = row.max()
        own = row[sit.behaviour, lut[sit.parent]]
        if own >= top:
            return None
        if cfg.majority == "plurality" or top > total / 2.0:
            return "not_majority"
        return None

    def _any_inappropriate(self) -> bool:
        """Vectorised pre-check of ``_inappropriate`` over all situations (the usual case)."""
        cfg = self.cfg
        counts = self.stn().counts
        lut = self.lut()
        n = len(self.order)
        rows = counts[1:n + 1].reshape(n, -1)
        totals = rows.sum(axis=1)
        tops = rows.max(axis=1) if rows.shape[1] else np.zeros(n)
        n_nodes = counts.shape[2]
        for k, sit in enumerate(self.order):
            if sit.n_pos < (cfg.n_min_r if sit.kind == R_KIND else cfg.n_min_t):
                return True
            if sit.kind == R_KIND:
                if self._broken(sit) is not None:
                    return True
                continue
            if sit.parent not in self.by_id:
                return True
            own = rows[k, sit.behaviour * n_nodes + lut[sit.parent]]
            if totals[k] > 0 and own < tops[k] and (
                    cfg.majority == "plurality" or tops[k] > totals[k] / 2.0):
                return True
        return False

    def _validity(self) -> None:
        if not self.order or not self._any_inappropriate():
            return
        handled: set[int] = set()  # recycle at most once per check
        while True:
            changed = False
            for sit in list(self.order):
                if sit.id not in self.by_id or sit.id in handled:
                    continue
                counts = self.stn().counts
                reason = self._inappropriate(sit, counts)
                if reason is None:
                    continue
                handled.add(sit.id)
                self._recycle(sit, reason, counts)
                changed = True
            if not changed:
                return

    def _recycle(self, sit: Situation, reason: str, counts: np.ndarray) -> None:
        cfg = self.cfg
        if sit.kind == R_KIND:
            since = (self._broken(sit, first_miss=cfg.r_break_forget == "history")
                     if reason == "recent_failures" else None)
            self._eliminate(sit, reason)  # R-situations are never recycled (algorithm.md)
            if since is not None:
                self._forget_before(sit, since)
            return
        lut = self.lut()
        row = counts[lut[sit.id]]
        per_b = row.sum(axis=1)
        if per_b.sum() <= 0:
            self._eliminate(sit, reason + "; no behaviour taken from it in the history")
            return
        b_new = int(np.argmax(per_b))
        node = int(np.argmax(row[b_new]))
        if node == len(self.order) + 1:
            self._eliminate(sit, reason + "; new result would be the goal reward")
            return
        if node == 0:
            self._eliminate(sit, reason + "; case 1: new parent is situation 0")
            return
        parent = self.order[node - 1]
        if parent is sit:
            self._eliminate(sit, reason + "; case 2: new parent is itself")
            return
        if parent.kind == T_KIND and parent.parent == sit.id:
            self._eliminate(sit, reason + "; case 3: new parent's parent is itself")
            return
        if self._exists((T_KIND, b_new, parent.id), besides=sit):
            self._eliminate(sit, reason + "; case 4: attributes already taken")
            return
        h = self.hist
        mask = t_result_mask(h, b_new, parent.id, self._unpunished)
        if int(mask.sum()) < cfg.n_init_t:
            self._eliminate(sit, reason + "; case 5: too few positive instances")
            return
        old = (sit.behaviour, sit.parent)
        sit.behaviour, sit.parent = b_new, parent.id
        sit.pos = mask
        sit.neg = np.zeros_like(mask)
        self._fit(sit)
        self._event("redefined", sit, reason=reason, old_behaviour=old[0], old_parent=old[1])
        self._structure_changed()
        self._negatives_from_history(sit)

    def refresh_nn_window(self) -> None:
        """Option ``nn_window`` W (not the paper's): the NN test of every situation compares
        only instances among the newest W records (all, if none of its instances is among
        them), so a miss after a fault outweighs the older successes around it within W steps
        instead of the history's length. Rebuilds the window from the history (after a load)."""
        w = self.cfg.nn_window
        if w == 0:
            self._recent = None
        else:
            self._recent = self.hist.valid & (self._ages() < w)
        for sit in self.order:
            sit.nn_recent = self._recent
            sit.nn_dirty = True

    def _slide_nn_window(self, slot: int) -> None:
        """The record just stored in ``slot`` enters the NN window; the one W records older
        leaves it, and the situations it was an instance of rebuild their NN caches."""
        h = self.hist
        w = self.cfg.nn_window
        self._recent[slot] = True
        if w < h.capacity and h.total > w:
            out = (slot - w) % h.capacity
            self._recent[out] = False
            for sit in self.order:
                if sit.pos[out] or sit.neg[out]:
                    sit.nn_dirty = True

    def _ages(self) -> np.ndarray:
        """Age of each history slot in records (0 = the newest)."""
        h = self.hist
        return (h.head - 1 - np.arange(h.capacity)) % h.capacity

    def _broken(self, sit: Situation, first_miss: bool = False) -> int | None:
        """Option ``r_break_window`` W (not the paper's): an R-situation is broken when, of
        the last W behaviours of its condition behaviour started in it since it was
        extracted, more than ``r_break_fraction`` of them (default half) missed its reward.
        Returns the age of the oldest of those W records (``first_miss``: of the oldest miss
        among them), else None. (Older records re-labelled into a new R-situation do not
        count, or the failures that broke one would break its successor at once.)"""
        return self._missing(sit, self.cfg.r_break_window, self.cfg.r_break_fraction,
                             first_miss)

    def _missing(self, sit: Situation, w: int, fraction: float,
                 first_miss: bool) -> int | None:
        """``_broken``'s test for any window ``w`` (0: never) and ``fraction``."""
        if w == 0:
            return None
        h = self.hist
        ages = self._ages()
        idx = np.flatnonzero(h.valid & (h.s == sit.id) & (h.b == sit.behaviour)
                             & (ages < h.total - sit.created))
        if len(idx) < w:
            return None
        ages = ages[idx]
        last = np.argsort(ages, kind="stable")[:w]
        met = sit.pos[idx[last]]
        if int(np.count_nonzero(~met)) <= fraction * w:
            return None
        return int(ages[last][~met].max() if first_miss else ages[last].max())

    def _forget_before(self, sit: Situation, since: int) -> None:
        """With ``r_break_window``: a broken R-situation's positive records older than the
        failures that broke it leave the history, or extraction would rebuild it at once from
        them; the learner then starts again from the blank space there (paper section 7.2).
        ``r_break_forget="history"``: every record older than the first of those failures
        leaves, so the whole learner starts again from the blank space (its situations, left
        without positives, are eliminated by operation 4). From the first failure, not the
        window's start: a rarely used R-situation's window reaches back past the fault, and
        what was learned after the fault stays."""
        h = self.hist
        old = h.valid & (self._ages() > since)
        if self.cfg.r_break_forget == "positives":
            old &= sit.pos
        n = int(np.count_nonzero(old))
        if n == 0:
            return
        self._drop(old)
        self._event("forgotten", sit, records=n)
        self._structure_changed()

    def _drop(self, old: np.ndarray) -> None:
        """The records of history-slot mask ``old`` leave the history and every population
        (the NN window may keep their slots: populations hold valid slots only)."""
        self.hist.valid[old] = False
        for sit in self.order:
            if (sit.pos & old).any():
                sit.shape_dirty = True
            if ((sit.pos | sit.neg) & old).any():
                sit.nn_dirty = True
            sit.pos &= ~old
            sit.neg &= ~old

    def _forget_contradicted(self, slot: int) -> None:
        """Option ``contradiction_radius`` r (not the paper's): the stored records of the
        same behaviour started within r of the record just stored in ``slot`` (Euclidean,
        each input dimension scaled by its standard deviation over the stored records) whose
        outcome differs from its outcome leave the history. An outcome is the goal reward
        (> ``r_min_r``), or else the situation the step ended in. After a fault the newest
        outcome replaces the stale ones around it at once instead of after the history's
        length.

        With ``contradiction_window`` W > 0 only records made before the newest change
        point can leave: a change point is the oldest miss among an R-situation's last W
        uses since its extraction when more than half of them missed (``_broken``'s test
        at half). In a world that has not changed, outcomes that differ around one input
        (the rover's position beyond its goal sensor) would otherwise replace each other
        for ever (docs/RESULTS-LOG.md: a worse level after the fault and from scratch)."""
        h = self.hist
        cfg = self.cfg
        cand = h.valid & (h.b == h.b[slot])  # the same behaviour's other stored records
        cand[slot] = False
        if cfg.contradiction_window:
            for sit in self.order:
                if sit.kind == R_KIND:
                    age = self._missing(sit, cfg.contradiction_window, 0.5, first_miss=True)
                    if age is not None:
                        self._change_at = max(self._change_at, h.total - 1 - age)
            cand &= h.total - 1 - self._ages() < self._change_at  # made before it
        idx = np.flatnonzero(cand)
        if len(idx) == 0:
            return
        scale = self._history_std()  # over every stored record, not only the candidates
        d2 = np.sum(((h.x[idx] - h.x[slot]) / scale) ** 2, axis=1)
        both = np.append(idx, slot)  # outcome: the goal reward (-1), else the situation reached
        outcome = np.where(h.reward[both] > cfg.r_min_r, -1, h.s_next[both])
        idx = idx[(d2 <= cfg.contradiction_radius ** 2) & (outcome[:-1] != outcome[-1])]
        n = len(idx)
        if n == 0:
            return
        old = np.zeros_like(h.valid)
        old[idx] = True
        self._drop(old)
        self._event("contradicted", self.by_id.get(int(h.s[slot])), records=n)

    def _eliminate(self, sit: Situation, reason: str) -> None:
        self.order.remove(sit)
        del self.by_id[sit.id]
        self._event("eliminated", sit, reason=reason)
        self._structure_changed()

    # -- operations 2, 3, 5 at the adjust interval ------------------------------------
    def _useless(self, utilities: dict[int, float]) -> list[Situation]:
        """Operation 5's candidates: negative utility (the paper), or with option
        ``useless="no_positive_plan"`` also utility 0 although behaviours were taken from it
        (Eq. 1 counts an untried behaviour as 0, so a situation whose tried behaviours all
        lose keeps utility 0 while any behaviour stays untried)."""
        tried = self.stn().tried if self.cfg.useless == "no_positive_plan" else None
        lut = self.lut()
        return [s for s in self.order if utilities[s.id] < 0.0 or (
            tried is not None and utilities[s.id] <= 0.0 and bool(tried[lut[s.id]].any()))]

    def _periodic(self) -> None:
        self._refit(only_dirty=False)  # operation 2
        if not self.order:
            return
        self._version += 1
        utilities = self.compute_utilities()
        grace = self.cfg.elimination_grace_steps  # 0: the paper's operation 5
        negative = [s for s in self._useless(utilities)
                    if grace == 0 or self.hist.total - s.created >= grace]
        for sit in negative:  # operation 5
            if sit.id in self.by_id:
                what = "negative utility" if utilities[sit.id] < 0.0 else "no positive plan"
                self._eliminate(sit, f"{what} {utilities[sit.id]:.4g}")
        if negative:
            self.compute_utilities()
        new = sorted(self.order, key=lambda s: -s.utility)  # operation 3 (stable)
        if [s.id for s in new] != [s.id for s in self.order]:
            self.order[:] = new
            self._event("reordered", None, order=[s.id for s in new],
                        utilities=[round(s.utility, 6) for s in new])
            self._structure_changed()
