"""Behavioural learning (paper section 6.2): IPRL and PIA on the STN.

IPRL: forward search from the current situation. A node reached by a path of length ``k``
with success probability ``P`` is expanded when ``P > p_min`` and ``k < n_max``; any other
node is a leaf with utility 0 (the goal node always is). Utilities are backed up with Eq. 1;
each node feeds back to its parent the behaviour maximising the right side and the successor
maximising the summand; the root's chain is the master plan ``((b1, d1), (b2, d2), ...)``.

Memoisation: the result of expanding node ``i`` at depth ``k`` depends on the path
probability ``P`` only through which descendants pass ``p_min``; each result is cached with
the interval of ``P`` over which it holds, so repeated sub-searches are answered exactly.

Untried behaviours count in Eq. 1's max with value 0 (an empty sum).
"""

from __future__ import annotations

import math

import numpy as np

from .stn import Stn

Plan = tuple[tuple[int, int], ...]


class Iprl:
    """IPRL search over one STN; one memo shared by every root searched on that STN."""

    def __init__(self, stn: Stn, gamma: float, p_min: float, n_max: int,
                 memo: bool = True) -> None:
        self.stn = stn
        self.gamma = gamma
        self.p_min = p_min
        self.n_max = n_max
        self.memo: dict[tuple[int, int], list] | None = {} if memo else None
        self.expansions = 0
        goal = stn.goal
        # Per node: [(b, [(j, p, r, p * r, threshold), ...]), ...] for the tried behaviours.
        # A successor j is expanded iff j is not the goal and prob > threshold = p_min / p.
        self._nodes: list[list[tuple[int, list[tuple]]]] = []
        self._untried: list[bool] = []
        # Value of a node none of whose successors is expanded (depth limit, or
        # prob <= _all_pruned[i]): independent of prob.
        self._leaf: list[tuple[float, Plan]] = []
        self._all_pruned: list[float] = []
        for row in stn.successors:
            node = []
            untried = False
            best_u, best_plan = -math.inf, ()
            max_p = 0.0
            for b, succ in enumerate(row):
                if succ is None:
                    untried = True
                    continue
                elems = []
                total, best_term, best_j = 0.0, -math.inf, -1
                for j, p, r in succ:
                    thr = p_min / p if j != goal else math.inf
                    if j != goal:
                        max_p = max(max_p, p)
                    elems.append((j, p, r, p * r, thr))
                    term = p * (r + gamma * 0.0)
                    total += term
                    if term > best_term:
                        best_term, best_j = term, j
                node.append((b, elems))
                if total > best_u:
                    best_u, best_plan = total, ((b, best_j),)
            if best_u == -math.inf or (untried and best_u < 0.0):
                best_u, best_plan = 0.0, ()
            self._nodes.append(node)
            self._untried.append(untried)
            self._leaf.append((best_u, best_plan))
            self._all_pruned.append(p_min / max_p if max_p > 0.0 else math.inf)

    def plan(self, root: int) -> tuple[float, Plan]:
        """(utility of ``root``, master plan) with node indices of the STN."""
        u, plan, _, _ = self._expand(root, 0, 1.0)
        return u, plan

    def _expand(self, i: int, k: int, prob: float):
        leaf = self._leaf
        if k + 1 >= self.n_max:
            u, plan = leaf[i]
            return u, plan, 0.0, math.inf
        all_pruned = self._all_pruned
        if prob <= all_pruned[i]:
            u, plan = leaf[i]
            return u, plan, 0.0, all_pruned[i]
        memo = self.memo
        if memo is not None:
            entries = memo.get((i, k))
            if entries is not None:
                for lo, hi, u, plan in entries:
                    if lo < prob <= hi:
                        return u, plan, lo, hi
        self.expansions += 1
        gamma = self.gamma
        child_leaf = k + 2 >= self.n_max  # children at depth k + 1 have leaf children
        lo, hi = 0.0, math.inf
        best_u = -math.inf
        best_b, best_j, best_sub = -1, -1, ()
        for b, elems in self._nodes[i]:
            total = 0.0
            best_term = -math.inf
            bj, bsub = -1, ()
            for j, p, r, pr, thr in elems:
                if prob > thr:
                    if thr > lo:
                        lo = thr
                    cp = prob * p
                    # the child's own shortcuts, inlined (same tests on the same numbers)
                    if child_leaf:
                        u_j, sub = leaf[j]
                    elif cp <= all_pruned[j]:
                        u_j, sub = leaf[j]
                        if all_pruned[j] / p < hi:
                            hi = all_pruned[j] / p
                    else:
                        u_j, sub, clo, chi = self._expand(j, k + 1, cp)
                        if clo / p > lo:
                            lo = clo / p
                        if chi / p < hi:
                            hi = chi / p
                    term = p * (r + gamma * u_j)
                else:
                    if thr < hi:
                        hi = thr
                    sub = ()
                    term = pr
                total += term
                if term > best_term:
                    best_term = term
                    bj, bsub = j, sub
            if total > best_u:
                best_u = total
                best_b, best_j, best_sub = b, bj, bsub
        if best_u == -math.inf or (self._untried[i] and best_u < 0.0):
            best_u, best_plan = 0.0, ()
        else:
            best_plan = ((best_b, best_j),) + best_sub
        if memo is not None:
            memo.setdefault((i, k), []).append((lo, hi, best_u, best_plan))
        return best_u, best_plan, lo, hi

    def utilities(self, roots) -> np.ndarray:
        return np.array([self.plan(i)[0] for i in roots])


def iprl_plan(stn: Stn, root: int, gamma: float, p_min: float, n_max: int,
              memo: bool = True) -> tuple[float, Plan]:
    """Convenience: one IPRL search."""
    return Iprl(stn, gamma, p_min, n_max, memo).plan(root)


class Pia:
    """Policy iteration on the whole STN (paper section 6.2, the alternative planner)."""

    def __init__(self, stn: Stn, gamma: float, n_max: int, max_iter: int = 200) -> None:
        self.stn = stn
        self.gamma = gamma
        self.n_max = n_max
        n = stn.n_nodes
        exp_r = np.einsum("ibj,ibj->ib", stn.p, stn.r)
        idx = np.arange(n)
        q = np.where(stn.tried, exp_r, 0.0)
        policy = np.argmax(q, axis=1)
        u = np.zeros(n)
        for _ in range(max_iter):
            live = stn.tried[idx, policy]
            p_pi = np.where(live[:, None], stn.p[idx, policy], 0.0)
            r_pi = np.where(live, exp_r[idx, policy], 0.0)
            u = np.linalg.solve(np.eye(n) - gamma * p_pi, r_pi)
            q = exp_r + gamma * np.einsum("ibj,j->ib", stn.p, u)
            q[~stn.tried] = 0.0
            best = q.max(axis=1)
            keep = q[idx, policy] >= best - 1e-12
            new_policy = np.where(keep, policy, np.argmax(q, axis=1))
            if np.array_equal(new_policy, policy):
                break
            policy = new_policy
        self.policy = policy
        self.u = u

    def plan(self, root: int) -> tuple[float, Plan]:
        stn = self.stn
        u_root = float(self.u[root])
        elems: list[tuple[int, int]] = []
        i = root
        while len(elems) < self.n_max and i != stn.goal:
            b = int(self.policy[i])
            if not stn.tried[i, b] or self.u[i] <= 0.0:
                break
            terms = stn.p[i, b] * (stn.r[i, b] + self.gamma * self.u)
            terms[stn.counts[i, b] <= 0] = -math.inf
            j = int(np.argmax(terms))
            elems.append((b, j))
            i = j
        return u_root, tuple(elems)

    def utilities(self, roots) -> np.ndarray:
        return np.array([float(self.u[i]) for i in roots])
