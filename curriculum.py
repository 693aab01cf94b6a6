"""curriculum.py: the adaptive error curriculum of the paper (Sec. 4.3.1, Eq. 16), numpy only.

A difficulty delta in [0, 1] sets the guidance error range E_r = delta * E_final (how wrong the
hand-designed trajectory's goal may be) and the exploration range Ex_r (how far the compliance lets
the residual push, through the stiffness of Eq. 9). After every episode, Eq. 16 moves delta by
eps from the success rate sr of the last 15 episodes:

    delta <- delta + eps * 1(sr > alpha) - eps * 1(sr < beta),   [alpha, beta] = [0.5, 0.7]

so delta rises above the window, falls below it and holds inside it; eps is 0.5 mm of error range.

Schedules (the paper's ablation, Sec. 5.1.4), as (E_r floor, Ex_r floor) in mm:
    adaptive   both grow from 0 with delta                       (the method)
    g2-c30     E_r grows from 2 mm, Ex_r held at 30 mm            (Curri-g2-c30)
    g2-c10     E_r from 2 mm, Ex_r 10 mm until E_r passes 10 mm   (Curri-g2-c10)
    g2-c2      both from 2 mm                                    (Curri-g2-c2)
    none       E_r = Ex_r = E_final throughout, delta fixed at 1  (no curriculum)
With E_r = max(g, delta E_final) and Ex_r = max(c, E_r) the one rule covers all of them. One more,
for the observation ablation, which "trained each policy variant under an increasing error range
and a constant exploration range of 10 mm":
    ex10       E_r grows from 0 with delta, Ex_r held at 10 mm whatever E_r is
"""
from collections import deque

import numpy as np

SCHEDULES = {"adaptive": (0.0, 0.0), "g2-c30": (0.002, 0.030), "g2-c10": (0.002, 0.010), "g2-c2": (0.002, 0.002)}
KINDS = ("adaptive", "none", "g2-c30", "g2-c10", "g2-c2", "ex10")
EX_FIXED = 0.010                    # ex10's exploration range, m


class Curriculum:
    """kind: one of KINDS; final: E_final, m; step: eps in m of error range; window: (alpha, beta);
    history: episodes in the success rate."""

    def __init__(self, kind="adaptive", final=0.020, step=0.0005, window=(0.5, 0.7), history=15):
        if kind not in KINDS:
            raise ValueError(f"unknown curriculum {kind!r} ({', '.join(KINDS)})")
        self.kind, self.final, self.window, self.history = kind, float(final), tuple(window), history
        self.eps = step / final if final > 0 else 0.0       # eps in units of delta
        g, _ = SCHEDULES.get(kind, (0.0, 0.0))
        self.delta = 1.0 if kind == "none" else (min(g / final, 1.0) if final > 0 else 1.0)
        self.successes = deque(maxlen=history)

    @property
    def success_rate(self):
        """sr of Eq. 16: mean success over the last `history` episodes (fewer at the start)."""
        return float(np.mean(self.successes)) if self.successes else 0.0

    def ranges(self):
        """(E_r, Ex_r) in m for the next episode."""
        if self.kind == "none":
            return self.final, self.final
        if self.kind == "ex10":
            return self.delta * self.final, EX_FIXED
        g, c = SCHEDULES[self.kind]
        e_r = max(g, self.delta * self.final)
        return e_r, max(c, e_r)

    def update(self, success):
        """Record one episode and apply Eq. 16; returns the new delta."""
        self.successes.append(bool(success))
        if self.kind != "none":
            sr, (alpha, beta) = self.success_rate, self.window
            self.delta += self.eps * (sr > alpha) - self.eps * (sr < beta)      # Eq. 16
            self.delta = float(np.clip(self.delta, 0.0, 1.0))
        return self.delta

    def state_dict(self):
        return {"kind": self.kind, "final": self.final, "delta": self.delta,
                "successes": [int(s) for s in self.successes]}

    def load_state_dict(self, d):
        if d["kind"] != self.kind or abs(d["final"] - self.final) > 1e-12:
            raise ValueError(f"curriculum mismatch: saved {d['kind']} to {d['final']} m, "
                             f"asked {self.kind} to {self.final} m")
        self.delta = float(d["delta"])
        self.successes = deque((bool(s) for s in d["successes"]), maxlen=self.history)
