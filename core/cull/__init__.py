"""Culling: the strategies, registered in one place (:data:`REGISTRY`) that the CLI,
the add-on's choices and the benchmark read.  Each strategy is an object made
per engine by its factory; it takes a :class:`~core.cull.view_pass.CullPass` ``cp``,
draws what it finds visible into the pass's depth buffer, marks what it proves
occluded, and leaves its counters in ``cp.stats``.  Whatever it keeps from one pass to
the next (the 0.7 m rule's ``max_tests``, last pass's visible leaves) lives in
the strategy object; ``reset()`` drops it.

Correctness is the same for all of them and does not depend on the occupancy
map: an object is culled only when it is outside the frustum or when an
occlusion query of a box around it (or around a group containing it) passed no
more than ``threshold`` samples against real geometry already drawn.  Drawing
less before a query can only make it say "visible" more often.

- ``vfc``      hierarchical frustum culling, draws everything inside.
- ``stopwait`` front to back, one query per node, waiting for each answer.
- ``leaf_stopwait`` the leaves in the frustum front to back, one query per leaf,
               waiting for each (no hierarchy, no map): the papers' plain baseline.
- ``om_single`` Staneker et al. 2003 as published: leaves front to back; the
               occupancy map skips queries in still-empty screen regions; every
               other leaf gets its own query, awaited before the next.
- ``om``       the 2003 map with the queries that remain batched: at most
               ``occupancy_queries.OM_MAX_BATCHES`` occupancy-map-arranged multiple queries.
- ``om_multi`` Staneker et al. 2004: hierarchical.  Stage 1 draws or opens what the
               occupancy map proves visible and defers the rest; stage 2 fills test
               lists through one cleared occupancy map per list (a box joins while
               one of its tiles is still free there) and issues each as one multiple
               query, at most ``max_tests`` rounds, ``max_tests(f + 1) = 0.7 m(f)``;
               stage 3 queries all that remain.
- ``om_coherent`` om_multi that draws last pass's visible leaves first, without
               queries, re-checking each every few passes (temporal coherence);
               after a camera cut or a sparse pass it starts fresh; at most
               ``occupancy_queries.COHERENT_READS`` multiple queries (GPU round trips) a pass.
- ``two_pass`` GPU-driven: last pass's visible leaves drawn first, every other leaf
               of the frustum tested in one batch, the nearer half of those that pass
               drawn and the rest tested once more (a handful of GL calls a pass);
               after a camera cut, an ``om_multi`` pass.
- ``gpu``      GPU-resident two passes: the units' boxes and matrices on the GPU, five
               compute dispatches and four indirect draws whose commands the GPU writes,
               one read-back a pass (:mod:`core.gl.gpucull`); ``om_coherent`` on the
               4.1 path.
- ``auto``     ``gpu`` where occlusion tests pay on this machine (costs measured),
               frustum culling alone where they cannot: the only strategy whose answer
               depends on timing, so never a default (the default is ``gpu``).
- ``oracle``   draws exactly the ground-truth set, no queries: the physical limit.

Homes: :mod:`.result` (states and counters), :mod:`.view_pass` (one pass),
:mod:`.stages` (the occupancy-map stages), :mod:`.memory` (the coherent strategies'
memory), :mod:`.baseline`, :mod:`.occupancy_queries`, :mod:`.gpu`, :mod:`.auto` (the
strategies by family).
"""

from dataclasses import dataclass

from ..errors import OccError
from .auto import Auto
from .baseline import LeafStopWait, OmSingle, Oracle, StopWait, Strategy, Vfc
from .gpu import Gpu
from .occupancy_queries import COHERENT_READS, Om, OmMulti, TwoPass
from .result import STAT_KEYS, CullResult, PassStats, Visibility
from .view_pass import CullPass


@dataclass(frozen=True)
class StrategyInfo:
    """One registered strategy: its factory ``(max_tests) -> Strategy``, a short
    label and description (the add-on's menu), and whether the default may pick it."""

    name: str
    factory: object
    label: str
    description: str
    default_candidate: bool = False
    needs_truth: bool = False
    timed: bool = False             # its answer depends on the clock (auto): never for a repeatable answer


REGISTRY = {info.name: info for info in (
    StrategyInfo("vfc", lambda m: Vfc(), "Frustum only", "Hide only what is outside the view", True),
    StrategyInfo("stopwait", lambda m: StopWait(), "Stop and wait",
                 "Hierarchical, one query per node, waiting for each"),
    StrategyInfo("leaf_stopwait", lambda m: LeafStopWait(), "Leaf queries",
                 "One query per object part, waiting for each (baseline)"),
    StrategyInfo("om_single", lambda m: OmSingle(), "Occupancy map, single queries",
                 "Staneker et al. 2003 as published: occupancy map, one query at a time"),
    StrategyInfo("om", lambda m: Om(), "Occupancy map",
                 "Staneker et al. 2003: occupancy map, remaining queries batched"),
    StrategyInfo("om_multi", lambda m: OmMulti(m), "Multiple queries",
                 "Staneker et al. 2004: occupancy-map-arranged multiple queries", True),
    StrategyInfo("om_coherent", lambda m: OmMulti(m, coherent=True, read_budget=COHERENT_READS), "Coherent",
                 "Occupancy map, multiple queries, last pass's visible first", True),
    StrategyInfo("two_pass", lambda m: TwoPass(m), "Two passes",
                 "Last pass's visible first, every other leaf tested in one batch (GPU-driven)", True),
    StrategyInfo("gpu", lambda m: Gpu(m), "GPU-driven",
                 "Units' boxes on the GPU: last pass's visible drawn, everything else tested there, "
                 "one read a pass; Coherent where the GPU path cannot run (OpenGL 4.1, macOS)", True),
    StrategyInfo("auto", lambda m: Auto(m), "Automatic",
                 "Occlusion tests where they pay on this machine, frustum culling where they cannot", True,
                 timed=True),
    StrategyInfo("oracle", lambda m: Oracle(), "Oracle",
                 "Draws exactly the truly visible set (benchmark limit, needs the truth)",
                 needs_truth=True),
)}
STRATEGIES = tuple(REGISTRY)
# The default answers the same whatever the machine's load: ``auto`` chooses by timing
# whether to test occlusion at all, so its answer depends on the clock; it is never a default.
DEFAULT_STRATEGY = "gpu"


def repeatable(name: str) -> str:
    """``name``, or the default where ``name``'s answer depends on timing: what an analysis
    runs, so that the same scene, cameras and settings give the same report every time."""
    return DEFAULT_STRATEGY if REGISTRY[name].timed else name


def make_strategy(name, max_tests=8):
    """A strategy object (``strategy(frame, chunk=, truth=)``) for a registered name."""
    if name not in REGISTRY:
        raise OccError(f"unknown strategy '{name}'; choose one of {', '.join(STRATEGIES)}")
    return REGISTRY[name].factory(max_tests)


__all__ = ["Auto", "CullPass", "CullResult", "DEFAULT_STRATEGY", "Gpu", "LeafStopWait", "Om", "OmMulti",
           "OmSingle", "Oracle", "PassStats", "REGISTRY", "STAT_KEYS", "STRATEGIES", "StopWait", "Strategy",
           "StrategyInfo", "TwoPass", "Vfc", "Visibility", "make_strategy", "repeatable"]
