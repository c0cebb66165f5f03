"""The ``auto`` strategy: occlusion tests where they pay on this machine, frustum
culling alone where they cannot, chosen by measured costs."""

import time

import numpy as np

from .baseline import Strategy
from .gpu import Gpu


class Auto(Strategy):
    """The default: occlusion tests (``gpu``, which is ``om_coherent`` where the GPU
    path cannot run) where they pay on this machine, frustum culling alone where they
    cannot (few or cheap triangles behind what is seen, or a GPU that draws
    everything faster than the tests' round trips).

    Costs are measured on real passes, not assumed: the first pass tests occlusion
    (and times a query batch's round trip); the second draws everything in the
    frustum, which gives the cost of a triangle as the scene really draws (fill
    included) and of a frustum-only pass beyond its drawing; one such pass comes
    again every ``PROBE_EVERY`` test passes while the tests cost more than ``CLOSE``
    of that estimate (where they clearly win, re-learning would only cost).  After each test pass it compares the
    pass's time with what frustum culling would have cost -- the triangles drawn
    plus those the tests proved hidden, at the measured cost, plus the frustum-only
    overhead -- and after ``LOSSES`` passes in a row where the tests did not pay it
    switches to frustum culling, probing the tests again after ``PROBE_EVERY``
    passes (twice as many after each probe that loses, up to ``PROBE_MAX``: on a
    scene where the tests never pay, the probes fade out; back to ``PROBE_EVERY``
    once one wins), or at once when a frustum-only pass is ``PROBE_SLOWER`` times
    slower than the last test pass (``FIRST_SLOWER`` for the first one after a
    switch), so a view that gets heavy is tested at once whatever the interval.
    Both modes are conservative, so the choice changes speed only.
    """

    ROUND_TRIPS = 3          # blocking reads that time a batch's round trip (median of them)

    LOSSES = 3                   # passes in a row where the tests did not pay (timing noise is common)
    PROBE_EVERY = 16
    PROBE_MAX = 128              # the longest interval between probes, after probes that lost
    PROBE_SLOWER = 2.0           # a frustum-only pass this much slower than the last test pass: probe at once
    FIRST_SLOWER = 1.0           # ... and the first frustum-only pass after a switch: was the switch right?
    PROBE_MARGIN = 0.9           # a probe switches back when it beats the frustum-only estimate by this much
    LOSS_MARGIN = 1.05           # a test pass loses when it costs this much more than the estimate (noise)
    SAVED_MIN = 0.05             # a test pass that hides less than this share of the frustum's triangles loses
    CLOSE = 0.5                  # test passes above this share of the estimate re-learn the costs every PROBE_EVERY
    LEARN = 0.3                  # weight of a new measurement in the running cost

    def __init__(self, max_tests=8, costs=None):
        self.occlusion = Gpu(max_tests)
        # tri_ms: ms per triangle a frustum-only pass draws; vfc_cpu_ms: such a pass's
        # time beyond its drawing; round_trip_ms: one query batch
        self.costs = dict(costs) if costs is not None else None
        self.use_tests = True
        self.losses = 0
        self.since_probe = 0             # frustum-only passes since the last test pass
        self.probe_every = self.PROBE_EVERY  # frustum-only passes before the next probe
        self.since_learn = 0             # test passes since the last frustum-only one
        self.last_test_ms = None
        self.close = True                # the last test pass was near the frustum-only estimate
        self.learn_count = 0             # frustum-only passes made to learn the costs

    def reset(self):
        self.occlusion.reset()

    def forget(self):
        self.occlusion.forget()

    def moved(self, objects=None):
        self.occlusion.moved(objects)

    @property
    def learned(self):
        """Whether a frustum-only pass's costs were measured (or given)."""
        return self.costs is not None and self.costs.get("tri_ms") is not None

    def _round_trip(self, cp):
        start = time.perf_counter()
        # a small box ahead of the eye (only the round trip's time is used)
        centre = cp.camera.direction * (0.01 * cp.scene_size)
        box = (centre + np.array([[-1.0], [1.0]]) * (1e-3 * cp.scene_size))[None]
        trips = []
        for _ in range(self.ROUND_TRIPS):
            t = time.perf_counter()
            cp.renderer.query(box, counts=False)
            trips.append(1e3 * (time.perf_counter() - t))
        cp.t_query += time.perf_counter() - start     # GL work: not the pass's CPU time
        self.costs = {"tri_ms": None, "vfc_cpu_ms": 0.0, "round_trip_ms": float(np.median(trips))}

    def __call__(self, cp, chunk=16, truth=None):
        if self.costs is None:
            self._round_trip(cp)
        if self.use_tests:
            # learn on the second pass, again on the fourth (the first frustum-only pass
            # pays first-draw costs), then every PROBE_EVERY while the result is close
            due = 1 if self.learn_count < 2 else (self.PROBE_EVERY if self.close else None)
            if due is not None and self.since_learn >= due:
                self._frustum_only(cp, learning=True)
            else:
                self._tests(cp, chunk, probe=False)
        elif self.since_probe >= self.probe_every:
            self._tests(cp, chunk, probe=True)
        else:
            self._frustum_only(cp, learning=False)

    def _tests(self, cp, chunk, probe):
        self.since_probe = 0
        self.since_learn += 1
        cp.stats.occlusion_pass = 1
        self.occlusion(cp, chunk)
        cp.finish_gl()
        spent = self.last_test_ms = 1e3 * (time.perf_counter() - cp.t0)
        if not self.learned:
            return                                   # nothing to compare with yet
        c, s = self.costs, cp.stats
        frustum_only = (s.triangles_drawn + s.triangles_occluded) * c["tri_ms"] + c["vfc_cpu_ms"]
        paid = spent < frustum_only * (self.PROBE_MARGIN if probe else self.LOSS_MARGIN)
        # whatever the clock says: tests that hide almost nothing cannot pay for themselves
        saved = s.triangles_occluded
        paid &= saved >= self.SAVED_MIN * (s.triangles_drawn + saved)
        self.close = spent > self.CLOSE * frustum_only
        self.losses = 0 if paid else self.losses + 1
        self.use_tests = paid if probe else self.losses < self.LOSSES
        if probe:
            self.probe_every = self.PROBE_EVERY if paid else min(2 * self.probe_every, self.PROBE_MAX)

    def _frustum_only(self, cp, learning):
        if learning:
            self.since_learn = 0
        else:
            self.since_probe += 1
        leaves = cp.frustum_leaves()
        t = time.perf_counter()
        cp.draw_leaves(leaves)
        cp.finish_gl()
        end = time.perf_counter()
        c = self.costs
        drawn = cp.stats.triangles_drawn
        learn = self.LEARN if self.learned else 1.0
        if drawn:
            self.learn_count += learning
            # down at once, up slowly: load, and first draws, only ever add time
            tri_ms = 1e3 * (end - t) / drawn
            c["tri_ms"] = tri_ms if c["tri_ms"] is None else min(tri_ms, c["tri_ms"] + learn * (tri_ms - c["tri_ms"]))
        elif c["tri_ms"] is None:
            return                                   # nothing drawn: learn on a later pass
        c["vfc_cpu_ms"] += learn * (1e3 * (t - cp.t0) - c["vfc_cpu_ms"])
        if learning:
            return
        # the first frustum-only pass after a switch is measured against the last test
        # pass as it is (was the switch right?), later ones with a margin (the view got heavier)
        slower = self.PROBE_SLOWER if self.since_probe > 1 else self.FIRST_SLOWER
        if self.last_test_ms is not None and 1e3 * (end - cp.t0) > slower * self.last_test_ms:
            self.since_probe = self.probe_every = self.PROBE_EVERY     # test again next pass
