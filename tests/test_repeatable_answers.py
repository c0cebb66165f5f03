"""Answers that do not depend on timing: the default strategy gives the same visible
sets whatever the clock says (a busy machine), a fresh pass is a new engine's first
pass whatever came before, and the default stays close to the tightest strategy."""

import threading
import time

import numpy as np
import pytest

from core import DEFAULT_STRATEGY, Culler, Visibility
from tests import scenes


class BusyClock:
    """``time.perf_counter`` of a machine whose load comes and goes: every reading
    advances by a seeded random amount, from microseconds to a tenth of a second.

    Only the thread that made it reads this clock: another thread left running by an
    earlier test (a worker, a collector) reads the real one, so it cannot take readings
    from the pass and make the sequence depend on what ran before."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)
        self.real = time.perf_counter
        self.now = self.real()
        self.owner = threading.get_ident()

    def __call__(self):
        if threading.get_ident() != self.owner:
            return self.real()
        self.now += float(self.rng.choice([1e-6, 1e-4, 1e-2, 1e-1]))
        return self.now


def states(scene, cams, strategy, ctx, clock=None, monkeypatch=None, fresh=False):
    """Per camera, the states of one engine's passes along the path."""
    if clock is not None:
        monkeypatch.setattr(time, "perf_counter", clock)
    try:
        with Culler(scene, (160, 120), strategy=strategy, ctx=ctx) as c:
            return [c.cull(cam, fresh=fresh).state.copy() for cam in cams]
    finally:
        if clock is not None:
            monkeypatch.undo()


def path(seed):
    scene, cams, _ = scenes.random_city(seed, 300)
    return scene, [c for c in cams for _ in range(3)]      # each view thrice: coherence has time to act


def test_the_default_is_not_auto():
    assert DEFAULT_STRATEGY == "gpu"


@pytest.mark.parametrize("seed", [3, 11])
def test_the_default_answers_the_same_on_a_busy_machine(ctx, monkeypatch, seed):
    scene, cams = path(seed)
    calm = states(scene, cams, DEFAULT_STRATEGY, ctx)
    for clock_seed in (1, 2):
        busy = states(scene, cams, DEFAULT_STRATEGY, ctx, BusyClock(clock_seed), monkeypatch)
        for k, (a, b) in enumerate(zip(calm, busy, strict=True)):
            assert np.array_equal(a, b), f"frame {k}: the answer changed with the clock"


class PhaseClock(BusyClock):
    """A clock under which one of ``auto``'s two kinds of pass looks costly: every
    reading inside that kind advances a tenth of a second, every other one a
    microsecond.  Deterministic whatever the machine's load, unlike the real clock."""

    def __init__(self, costly):
        super().__init__(0)
        self.costly, self.phase = costly, None

    def __call__(self):
        if threading.get_ident() != self.owner:
            return self.real()
        self.now += 1e-1 if self.phase == self.costly else 1e-6
        return self.now


def phase_states(scene, cams, ctx, monkeypatch, costly):
    """``states`` of ``auto`` under a PhaseClock that makes ``costly`` look costly."""
    from core.cull.auto import Auto
    clock = PhaseClock(costly)
    for name in ("_tests", "_frustum_only"):
        run = getattr(Auto, name)

        def timed(self, *a, _name=name, _run=run, **k):
            clock.phase = _name
            try:
                return _run(self, *a, **k)
            finally:
                clock.phase = None
        monkeypatch.setattr(Auto, name, timed)
    try:
        return states(scene, cams, "auto", ctx, clock, monkeypatch)
    finally:
        monkeypatch.undo()


def test_the_busy_clock_does_change_a_timing_strategy(ctx, monkeypatch):
    """The check above can fail: ``auto`` chooses by timing, and under a clock that makes
    its tests look costly it stops testing, so its answer changes from the one under a
    clock that makes drawing everything look costly."""
    scene, cams = path(11)
    tests_pay = phase_states(scene, cams, ctx, monkeypatch, costly="_frustum_only")
    tests_lose = phase_states(scene, cams, ctx, monkeypatch, costly="_tests")
    changed = [k for k, (a, b) in enumerate(zip(tests_pay, tests_lose, strict=True)) if not np.array_equal(a, b)]
    assert changed
    # where the tests lose, auto draws everything in the frustum: more objects visible
    def visible(runs):
        return sum(int((s == Visibility.VISIBLE).sum()) for s in runs)
    assert visible(tests_lose) > visible(tests_pay)


@pytest.mark.parametrize("strategy", ["gpu", "om_coherent", "om_multi", "two_pass"])
def test_a_fresh_pass_is_a_new_engines_first_pass(ctx, strategy):
    """``cull(fresh=True)`` after any history answers as a new engine's first pass does:
    what an analysis split into chunks needs to merge into exactly the whole run."""
    scene, cams = path(5)
    with Culler(scene, (160, 120), strategy=strategy, ctx=ctx) as walked:
        for cam in cams:
            walked.cull(cam)                                   # history: memory, learnt rounds
        after = [walked.cull(cam, fresh=True).state.copy() for cam in cams[::3]]
    for cam, got in zip(cams[::3], after, strict=True):
        with Culler(scene, (160, 120), strategy=strategy, ctx=ctx) as new:
            assert np.array_equal(new.cull(cam).state, got)


def test_fresh_passes_stay_within_a_tenth_of_the_steady_default(ctx):
    """An analysis culls every frame fresh; summed over a path it keeps at most 1.1x the
    objects the default keeps along the same path with its memory."""
    for seed in (3, 11):
        scene, cams = path(seed)
        with Culler(scene, (160, 120), ctx=ctx) as c:
            steady = sum(int(c.cull(cam).visible.sum()) for cam in cams)
            fresh = sum(int(c.cull(cam, fresh=True).visible.sum()) for cam in cams)
        assert fresh <= 1.1 * steady, (seed, fresh, steady)


def test_analyses_never_run_a_strategy_whose_answer_depends_on_timing():
    """``repeatable`` (what occ.analyze runs) swaps a timed strategy for the default, and
    ``analyze`` does not offer one."""
    import subprocess
    import sys

    from core import REGISTRY, repeatable
    from tests.cli_helpers import ROOT
    timed = [n for n, info in REGISTRY.items() if info.timed]
    assert timed == ["auto"]
    assert repeatable("auto") == DEFAULT_STRATEGY
    assert all(repeatable(n) == n for n in REGISTRY if n not in timed)
    p = subprocess.run([sys.executable, "-m", "core", "analyze", "city-small", "--strategy", "auto", "-q"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "auto" in p.stderr and p.stdout == ""
