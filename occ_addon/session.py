"""One culling session per Blender session: the engine's lifecycle.  It keeps the
extraction cache and the engine (kept while only transforms change), runs a
pass and applies it.  What a pass may hide is :mod:`.policy`'s; where the camera
is, :mod:`.cameras`'; when a pass runs, the operators' and live mode's.

A pass costs, on the Blender side, one ``visible_get`` per object, one
``foreach_get`` of every world matrix and one ``foreach_set`` of the hide
flags; the engine is rebuilt only when the set of objects, some geometry, the
query resolution or the strategy changed.
"""

import threading
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, replace

import bpy
import numpy as np

from ..core import Camera, Culler, CullResult, OccError, Visibility
from ..core.envelope import Envelope
from ..core.motion import AT_REST, AtRest, LivePolicy
from ..core.settings import MAX_RESOLUTION, preset, query_resolution
from ..core.units import ChunkCache
from . import identity, localview, policy, shading, visibility, worker
from .cameras import hide_view, perspective_twin
from .extract import Candidates, Extractor
from .kinds import Kind
from .passes import LastPass, Shown, shown_by
from .worker import EngineThread, Job, drive

# Meshes of 4 x this many triangles or more are cut into chunks of about this
# many (never a user's mesh: index ranges inside the engine's copy): a heavy
# object is then drawn and tested by its visible parts, not as one box.
CHUNK_TRIANGLES = 4096
POLICY = LivePolicy()       # how far a hidden set must hold while the view moves (live.py)

Size = tuple[int, int]


@dataclass(frozen=True, eq=False)
class Held:
    """What the engine was built for and which objects it holds.

    candidates: the session ids of the pass's candidates at the build (another set
    is a rebuild); size: ``(query resolution, display resolution or None)``, the
    engine's GL targets; index: ``(k,) int64`` the candidates it holds, in its
    object order; uids: ``(k,) int64`` their session ids; collection: ``(k,) bool``
    which of them are collection instances.
    """

    candidates: tuple
    size: tuple
    index: np.ndarray
    uids: np.ndarray
    collection: np.ndarray


@dataclass(frozen=True, eq=False)
class Pending:
    """A pass begun (:meth:`Session.begin`) whose cull runs on the engine thread.

    job: the cull's :class:`.worker.Job`; objects, held: the engine's objects and what
    it was built for at the start; camera, display: what the pass culls for; view:
    where it hides (:func:`.cameras.hide_view`, None: everywhere); rule: the shading
    rule (:func:`.shading.rule`); show_only: it hides nothing new; version: the
    session's at the start; layer: ``(scene, view layer)`` names; uids: ``(n,) int64``
    the session ids of every object then (:func:`.identity.uids`); started: its clock
    (``time.perf_counter``); blender_s: the seconds of Blender's update it took so far.
    """

    job: Job
    objects: list
    held: Held
    camera: Camera
    display: Size
    view: tuple | None
    rule: shading.ViewRule
    show_only: bool
    version: int
    layer: tuple
    uids: np.ndarray
    started: float
    blender_s: float


def layer_of(context) -> tuple:
    """``(scene, view layer)`` names of the context: a pass's layer."""
    return (context.scene.name, context.view_layer.name)


class Session:
    def __init__(self):
        self.extractor = Extractor()
        self.chunks = ChunkCache()  # chunkings outlive engines: a resized viewport re-cuts nothing
        self.worker = EngineThread()
        self.culler = None
        self.held: Held | None = None   # set with culler, dropped with it
        self.last: LastPass | None = None   # the last applied pass (see :meth:`cull`)
        self.version = 0           # bumped by every applied pass
        self.applying = False      # the depsgraph updates now are our own hiding's
        self.warnings = []         # objects left out of the last pass, for the report
        self.bad_geometry = []     # of them, those left out for their vertices (known since the last build)
        self.layer = None          # (scene, view layer) of the last pass
        self.reread = False        # the next pass compares every transform (reread_transforms)
        self.edited_away = False   # an edit reported while another layer was shown (edited_elsewhere)
        self.busy = None           # the label of a modal operator's work in steps (live passes wait)
        self.shown: Shown | None = None  # the view and motion the hidden set holds for
        self.read: Candidates | None = None   # the last pass's candidates (see engine_steps' reuse)
        self.enter_while: tuple | None = None  # (window, area) the pass will put in its own local view
        self.picked = None                     # (object, view layer) selected for that entry (_meanwhile)
        self.pending: Pending | None = None    # the pass in flight (begin .. finish)

    def reset(self) -> None:
        """Forget everything (a file was loaded, an undo or redo, or the add-on goes away):
        Blender may hand back the same session ids with other contents."""
        identity.forget()
        self.discard()
        self.release()
        self.extractor = Extractor()
        self.held = None
        self.bad_geometry = []
        self.last = None
        self.shown = None
        self.read = None
        self.version += 1

    def release(self) -> None:
        if self.culler is not None:
            culler, self.culler = self.culler, None
            self.worker.run(culler.close)

    def shutdown(self) -> None:
        self.reset()
        self.chunks = ChunkCache()
        self.worker.shutdown()

    def reread_transforms(self) -> None:
        """The next pass compares every transform it reads with the evaluated one (as
        after a view-layer switch): a Cull click and an analysis's frames, where the
        file has several view layers or scenes, trust no original ``matrix_world``
        another layer's evaluation may have left behind."""
        self.reread = True

    def edited_elsewhere(self, scene, depsgraph) -> None:
        """A depsgraph update not our own, from ``depsgraph``: where it evaluates another
        scene or view layer than the last pass's, the edit may touch an object that layer
        leaves out, which no evaluation reports, and a layer whose depsgraph is made
        after the edit reports nothing at its first evaluation: the next pass in another
        layer reads every cached geometry again (:meth:`candidates`)."""
        if self.layer is not None and (scene.name, depsgraph.view_layer.name) != self.layer:
            self.edited_away = True

    def left_layer(self, context) -> int:
        """The context shows another scene or view layer than the last pass's: what the
        add-on hid everywhere (``hide_viewport``, which every layer shares) was hidden for
        that layer's occluders, and an occluder there may be missing here (a collection
        excluded in this layer).  Shown again, until a pass here decides (live mode makes
        one at once, see :func:`.live.changed`); returns how many."""
        if self.layer is None or (context.scene.name, context.view_layer.name) == self.layer:
            return 0
        culled = identity.flags("occ_culled")
        if not culled.any():
            return 0
        self.shown = None
        return visibility.release(culled)

    def candidates(self, context, verify: bool = False) -> Candidates:
        """The candidates of a pass; objects the add-on hid and must give back
        (hidden by the user too, not evaluated and able to change, or, with
        ``verify``, edited since they were read) are shown first and evaluated,
        so the pass sees them as Blender draws them.

        The rule for every call into Blender a pass makes (issue 30): a pass tags,
        writes and evaluates nothing the user did not change, beyond what hiding needs
        (its hide flags and records, the tags of the objects it shows again, one
        ``view_layer.update()`` of the window's layer to take pending edits and to
        apply its hiding).  No ``update_tag`` of objects it does not show, no
        evaluation of other view layers or scenes, no ``frame_set``, no operator beside
        the engine thread (:func:`.worker.quiet`).  Tagging every object's transform
        once made a Cull click the trigger of a Blender crash (a hair system's instance
        object tagged after an emitter's delete and undo, with a second view layer:
        ``../shared/repro/blender_hair_undo_two_layers.py``)."""
        layer = layer_of(context)
        # (with one scene of one view layer no object can have moved elsewhere)
        alone = len(bpy.data.scenes) == 1 and len(context.scene.view_layers) == 1
        # Another view layer than the last pass's: an object moved while it was not in
        # the evaluated layer keeps a stale original matrix_world until this layer's
        # evaluation writes it back, and the candidates read originals in bulk: once
        # per switch, every one is compared with its evaluated copy (Extractor.fresh_matrices).
        every = (layer != self.layer or self.reread) and not alone
        # ... and what the add-on hides is checked against its data (as on a click): in
        # another layer an object may be drawn that no edit report reached while it was not
        verify = verify or layer != self.layer
        if self.layer is not None and layer != self.layer:
            # ... and so may an object the last layer left out: an edit is reported only by
            # the evaluation of a layer that holds the object, and a layer's first
            # evaluation reports its objects without their geometry changes (workflow seed
            # 7053: a vertex made NaN while the active layer left the object out, then a
            # new layer).  Read again, every cached geometry the last engine did not hold;
            # and every one, where something was edited while another layer was shown: an
            # object the last engine held, edited while left out there, is reported by no
            # evaluation when this layer's depsgraph is new.
            held = set(self.held.uids.tolist()) if self.held is not None and not self.edited_away else set()
            self.extractor.mark(geometry=[u for u in self.extractor.cache if u not in held])
        self.layer, self.reread, self.edited_away = layer, False, False
        cand = self.extractor.candidates(context, verify, every)
        if len(cand.give_back):
            visibility.release(np.isin(identity.uids(), cand.give_back))
            identity.evaluate(context.view_layer)
            cand = self.extractor.candidates(context)
        self.extractor.check_shown(cand)
        return cand

    def engine_steps(self, context, resolution: Size, strategy: str, verify: bool = False,
                     display: Size | None = None, reuse: bool = False) -> Generator[object, None, tuple[Culler, list]]:
        """The engine for the current candidates, ``(culler, objects)``: rebuilt when
        objects or geometry changed, otherwise only the moved objects' matrices are
        sent.  A generator (see :func:`.worker.drive`): it yields progress while it
        reads geometry and the build's :class:`.worker.Job` while the engine thread
        builds.  Stopped early (Esc), the session keeps no half
        state: the engine is dropped (closed on its thread once built) and the next
        pass builds again; nothing in the scene was touched.  ``reuse``: the last pass's
        candidates stand (nothing in the scene can have changed since: an analysis whose
        frames move the camera alone, in background mode, see :mod:`.keyed_camera`)."""
        cand = self.read if reuse and self.read is not None else self.candidates(context, verify)
        self.read = cand
        self.warnings = list(cand.bad)
        if not len(cand):
            raise OccError("nothing to cull: the view layer has no visible mesh objects")
        uids = tuple(cand.uids.tolist())
        # the engine is bound to its query and display resolutions (GL targets)
        size = (resolution, display)
        held = self.held
        rebuild = (self.culler is None or held is None or uids != held.candidates or size != held.size
                   or (not reuse and self.extractor.needs_geometry(cand)))
        if rebuild:
            scene, kept, bad = yield from self.extractor.scene_steps(context, cand)
            self.warnings += bad
            old, self.culler, self.held = self.culler, None, None      # no half state if stopped
            if old is not None and held is not None and size == held.size:
                # same context; meshes read unchanged from the cache keep their chunks
                job = self.worker.submit(_replaced, old, scene, strategy)
            else:
                if old is not None:
                    self.worker.submit(old.close)
                job = self.worker.submit(_built, scene, resolution, strategy, self.chunks, display)
            try:
                self._meanwhile()                     # (a pass's: see cull)
                yield job
            except BaseException:                     # stopped or failed: close what the build makes
                self.worker.submit(_close_built, job)
                raise
            self.culler = job.result()
            self.held = Held(uids, size, kept, cand.uids[kept],
                             np.array([cand.kinds[i] is Kind.COLLECTION for i in kept], dtype=bool))
            self.bad_geometry = bad
        else:
            assert held is not None                   # not rebuilt: the engine it holds is this one
            self.warnings += self.bad_geometry
            if strategy != self.culler.strategy_name:
                self.worker.run(self.culler.set_strategy, strategy)
            m = cand.matrices[held.index]
            moved = np.flatnonzero(np.any(m != self.culler.scene.matrices, axis=(1, 2)))
            if len(moved):
                self.worker.run(self.culler.set_matrices, moved, m[moved])
        held = self.held
        assert held is not None                       # built above, or the one it was
        return self.culler, identity.pick(cand.objects, held.index.tolist())

    def _sizes(self, context, display: Size):
        """``(options, query resolution, display resolution or None)`` of a pass."""
        settings = context.scene.occ
        options = preset(settings.preset)
        res = query_resolution(fit(display, settings.max_resolution), options)
        # Below the display's own resolution (the fast preset, or a display larger than
        # the max query size), occluders are drawn at the display's resolution and each
        # query pixel keeps the farthest depth it stands for: a gap the display shows
        # stays open in the query (conservative by construction; core.gl, display=).
        shown = fit(display, MAX_RESOLUTION)
        return options, res, (shown if shown != res else None)

    def prepare_steps(self, context, display: Size, fresh: bool = True) -> Generator:
        """The slow part of a first pass (reading geometry, building the engine) in
        steps, hiding nothing: a modal operator runs it, then :meth:`cull` (which then
        finds the engine built, or rebuilds what changed in between)."""
        self.discard()
        _, res, shown = self._sizes(context, display)
        yield from self.engine_steps(context, res, context.scene.occ.strategy, verify=fresh, display=shown)

    def compute(self, context, camera: Camera, display: Size, fresh: bool = True,
                progress: Callable | None = None, restart: bool = False,
                envelope: Envelope | AtRest | None = None, lights: list | None = None) -> tuple[CullResult, list]:
        """Visibility from ``camera`` at ``display`` resolution, without hiding anything.
        ``fresh``: the strategy forgets what earlier passes taught it that would cost
        accuracy (a Cull click, a camera cut, analyze, a scene change); only a live
        pass right after a small view change keeps all of it.  ``restart``: the answer
        is a new engine's first pass, whatever came before (a Cull click, an analysis's
        first frame: the same click gives the same answer).  ``progress``: called with
        the steps' :class:`.worker.Progress`.  ``envelope``: hide only what stays hidden
        while the view moves that far (:mod:`..core.envelope`; ``AT_REST``: live mode's
        envelope at rest).  Returns ``(result, the engine's objects)``."""
        return drive(self.compute_steps(context, camera, display, fresh, restart, envelope, lights), progress)

    def compute_steps(self, context, camera: Camera, display: Size, fresh: bool = True, restart: bool = False,
                      envelope: Envelope | AtRest | None = None, lights: list | None = None,
                      strategy: str | None = None,
                      reuse: bool = False) -> Generator[object, None, tuple[CullResult, list]]:
        """:meth:`compute` in steps (see :meth:`engine_steps`, also for ``reuse``);
        ``strategy``: this pass's, instead of the scene's setting."""
        job, objects = yield from self._submit_steps(context, camera, display, fresh, restart, envelope, lights,
                                                     strategy, reuse)
        self._meanwhile()
        return job.result(), objects

    def _submit_steps(self, context, camera: Camera, display: Size, fresh: bool, restart: bool,
                      envelope: Envelope | AtRest | None, lights: list | None,
                      strategy: str | None = None, reuse: bool = False,
                      clip: np.ndarray | None = None) -> Generator[object, None, tuple[Job, list]]:
        """The engine for the pass (:meth:`engine_steps`) and its cull handed to the engine
        thread: ``(the cull's Job, the engine's objects)``.  ``clip``: the view's clipping
        region (what it cuts is kept and occludes nothing; :meth:`..core.Culler.cull`)."""
        self.discard()                        # one pass at a time on the engine
        options, res, shown = self._sizes(context, display)
        # a fresh pass (a click, analyze, a scene change) also checks what the add-on
        # hides against its data: edits to hidden objects are never reported
        culler, objects = yield from self.engine_steps(context, res, strategy or context.scene.occ.strategy,
                                                       verify=fresh or restart, display=shown, reuse=reuse)
        culler.set_options(options)
        # a pass during motion draws the envelope's image only while it helps: its time
        # sizes the next passes' envelopes
        probe = envelope is None or envelope is AT_REST
        if envelope is AT_REST:
            envelope = POLICY.rest(culler.scene_size)
        if isinstance(envelope, Envelope) and camera.is_orthographic:
            twin = perspective_twin(context)         # the view may turn perspective before a redraw
            if twin is not None:
                envelope = replace(envelope, also=(twin,))
        lights = lights or None
        if restart:
            culler.forget(everything=True)
        elif fresh:
            culler.forget()
        return self.worker.submit(culler.cull, camera, envelope=envelope, lights=lights, probe=probe,
                                  clip=clip), objects

    def _meanwhile(self) -> None:
        """While the engine thread builds or culls (a pass that will enter the add-on's own
        local view): select the object Blender's local view needs (where the view draws no
        selected one) and evaluate that selection now.  Blender lets Python threads run
        while it evaluates, so the engine's work covers it (about a base update: 0.5 s
        at 50,000 objects); the entry after the pass then evaluates nothing.  Only an
        evaluation runs beside the engine thread, never an operator (see
        :func:`.worker.quiet`)."""
        view, self.enter_while = self.enter_while, None
        if view is None or view[1].spaces.active.local_view is not None:
            return
        win, area = view
        picked = localview.pick(win, area)
        if picked is not None:
            self.picked = (picked, win.view_layer)
            identity.evaluate(win.view_layer)

    def _unpick(self) -> None:
        """Deselect what :meth:`_meanwhile` selected (its evaluation joins the pass's last update)."""
        picked, self.picked = self.picked, None
        if picked is not None:
            try:
                picked[0].select_set(False, view_layer=picked[1])
            except ReferenceError:            # undone or deleted since: nothing of ours is selected
                pass

    def cull(self, context, camera: Camera, display: Size, fresh: bool = False, progress: Callable | None = None,
             restart: bool = False, envelope: Envelope | AtRest | None = None,
             show_only: bool = False) -> tuple[CullResult, list]:
        """One pass: cull from ``camera`` at ``display`` resolution and apply it
        (:meth:`begin`, then :meth:`finish` once the engine's work is done).

        ``envelope``: the pass hides only what stays hidden for every view of it
        (:attr:`shown` then holds the view and the envelope the hidden set is good
        for: live mode checks every redraw against it).  ``show_only``: it shows what
        it finds visible and hides nothing new (what stays hidden is hidden in this
        pass too, so it holds for its envelope)."""
        with identity.one_pass():     # one call, nothing of the user's between the halves: one read of the records
            return self.finish(context, self.begin(context, camera, display, fresh, progress, restart, envelope,
                                                   show_only))

    def begin(self, context, camera: Camera, display: Size, fresh: bool = False, progress: Callable | None = None,
              restart: bool = False, envelope: Envelope | AtRest | None = None, show_only: bool = False,
              beside: bool = False) -> "Pending":
        """The first half of :meth:`cull`: the pass's reads from Blender and the engine
        (built or updated here, waiting), then its cull handed to the engine thread.
        Returns the :class:`Pending` pass (also :attr:`pending`) that :meth:`finish`
        applies, or :meth:`discard` drops.  ``beside``: the interface goes on while the
        engine culls (live mode): nothing is selected meanwhile for an entry into the
        add-on's local view (the user would see it, and act on it)."""
        with identity.one_pass():             # the records are read once a pass
            t = time.perf_counter()
            visibility.reconcile()                 # what the user showed is the user's
            t_update = time.perf_counter()
            identity.evaluate(context.view_layer)   # edits still pending reach the handler now, not below
            blender_s = time.perf_counter() - t_update
            view_rule = shading.rule(context)
            view = None if show_only else hide_view(context)
            # a pass after one that hid nothing (live mode over an open view) likely hides
            # nothing either: no selection for an entry that will not come (its deselection
            # would cost the pass a base update)
            ahead = not beside and (self.last is None or self.last.hidden.any())
            self.enter_while = view if ahead else None
            try:
                job, objects = drive(self._submit_steps(context, camera, display, fresh, restart, envelope,
                                                        view_rule.lights, clip=view_rule.clip), progress)
                self._meanwhile()
            except BaseException:
                self._unpick()                     # the pass failed: the selection as it was
                raise
            finally:
                self.enter_while = None
            assert self.held is not None              # the engine the pass was handed to
            self.pending = Pending(job, objects, self.held, camera, (display[0], display[1]), view, view_rule,
                                   show_only, self.version, layer_of(context), identity.uids().copy(), t, blender_s)
            return self.pending

    def current(self, context, pending: "Pending") -> bool:
        """Whether ``pending`` can still be applied: it is the pass in flight, the session
        and its engine are the ones it began with, the window shows the same view layer
        and the same objects are there.  (What changed in them since is the caller's to
        know: live mode listens to the change bus.)"""
        try:
            return (pending is self.pending and pending.version == self.version and pending.held is self.held
                    and self.culler is not None and pending.layer == layer_of(context)
                    and np.array_equal(pending.uids, identity.uids()))
        except ReferenceError:
            return False

    def show_all(self, context) -> int:
        """Show everything the add-on hid, as its own change (live mode, when the view
        leaves the hidden set's envelope): edits still pending are evaluated first, as
        the user's (the handlers announce them); then the shows and Blender's update
        under :attr:`applying`, which the handlers ignore (no engine re-read of the
        objects shown, no change on the bus).  Call from a timer, never from a handler
        (an update inside an update).  Returns how many were shown."""
        self.shown = None
        context.view_layer.update()
        self.applying = True
        try:
            n = visibility.restore()
            if n:
                context.view_layer.update()
        finally:
            self.applying = False
        return n

    def discard(self) -> None:
        """Drop the pass in flight, if any: its engine work is waited for (the engine is
        consistent again) and what it selected is deselected; nothing is applied."""
        pending, self.pending = self.pending, None
        if pending is not None:
            try:
                pending.job.wait()
            finally:
                self._unpick()

    def finish(self, context, pending: "Pending") -> tuple[CullResult, list]:
        """The second half of :meth:`cull`: waits for the engine's answer and applies it
        (what may be hidden is :mod:`.policy`'s), then Blender's update."""
        if pending is not self.pending:
            raise RuntimeError("occlusion culling: a pass finished that is not the one in flight")
        self.pending = None
        with identity.one_pass():
            settings = context.scene.occ
            held, objects, view, blender_s = pending.held, pending.objects, pending.view, pending.blender_s
            try:
                # what the policy reads whatever the engine answers, read while it culls (a
                # Cull click finishes at once; live mode once the answer is in)
                picked = None if self.picked is None else self.picked[0]
                known = policy.settled(context, objects, held.uids, held.collection, picked)
                result = pending.job.result()
                state = result.state
                culled = state != Visibility.VISIBLE
                protected = policy.never_hidden(context, objects, held.uids, held.collection, culled,
                                                self.extractor, known)
                protected |= policy.drawn_beyond_depth(pending.rule, state, settings.cull_raytraced)
            except BaseException:
                self._unpick()                     # the pass failed: the selection as it was
                raise
            hide = np.isin(identity.uids(), held.uids[culled & ~protected])
            before = visibility.COUNT["changed"]
            self.applying = True
            try:
                if pending.show_only:
                    visibility.release(~hide)
                else:
                    if view is None:                   # hidden everywhere: not evaluated from now on
                        sealed = np.flatnonzero(culled & ~protected)
                        self.extractor.seal([objects[i] for i in sealed.tolist()], held.uids[sealed])
                    try:
                        visibility.apply(hide, view)
                    finally:
                        self._unpick()
                # Showing an object again makes the depsgraph report it, and every
                # object sharing its mesh, as changed geometry.  Nothing else can have
                # changed since the update above, so evaluate now and let the handler
                # ignore it all: hiding never costs an engine rebuild on the next pass.
                t_update = time.perf_counter()
                identity.evaluate(context.view_layer)
                blender_s += time.perf_counter() - t_update
            finally:
                self.applying = False
            changed = visibility.COUNT["changed"] - before
            # the pass's time, from its first read until it landed (Blender's update included)
            hidden = np.flatnonzero(culled & ~protected)
            scene = self.culler.scene
            self.last = LastPass(state, protected, scene.mesh_bounds[scene.mesh_of[hidden]], scene.matrices[hidden],
                                 result.occupancy, result.stats,
                                 1e3 * (time.perf_counter() - pending.started), 1e3 * blender_s, changed,
                                 int(self.culler.scene.triangle_counts[hidden].sum()), _rule_words(pending, result),
                                 shading.key(pending.rule), held.uids[~(culled & ~protected)])
            self.shown = shown_by(result, pending.camera)
            self.version += 1
            return result, objects


def _rule_words(pending, result) -> str:
    """What the panel says of the pass's rule; an orthographic view under an envelope also
    says why it hides less than a perspective one (:mod:`..core.envelope`: what stands
    close behind a continuous surface, for the parallel view and the perspective one it may
    turn into), lest few read as nothing being behind anything."""
    if result.envelope is not None and pending.camera.is_orthographic:
        return f"{pending.rule.why}; orthographic: hides what stays hidden from this view and its perspective twin"
    return pending.rule.why


def _built(scene, resolution, strategy, chunks, display):
    """On the engine thread: a new engine for ``scene`` on the thread's own GL context
    (:func:`.worker.thread_gl_context`); where the build fails, the context goes too
    (the next engine starts on a fresh one)."""
    try:
        return Culler(scene, resolution, strategy=strategy, chunk_triangles=CHUNK_TRIANGLES, chunk_cache=chunks,
                      display=display, query_pixels=False, ctx=worker.thread_gl_context())
    except BaseException:
        worker.drop_thread_gl_context()
        raise


def _replaced(culler, scene, strategy):
    """On the engine thread: ``culler`` rebuilt for ``scene`` (same GL context; meshes
    read unchanged keep their chunks), with ``strategy``."""
    try:
        culler.replace_scene(scene)
        if strategy != culler.strategy_name:
            culler.set_strategy(strategy)
    except BaseException:  # half replaced: the session dropped it, nothing else will close it
        culler.close()
        worker.drop_thread_gl_context()           # (as _built: the next engine on a fresh context)
        raise
    return culler


def _close_built(job):
    """On the engine thread, after the build ``job`` (jobs run in order): close what it built."""
    try:
        built = job.result()
    except Exception:  # noqa: BLE001 -- a build that failed built nothing to close
        return
    built.close()


SESSION = Session()


def rendering() -> bool:
    """Whether a render job runs (Blender calls its frame handlers from the render's own
    thread, and its start reports an update of the window's depsgraph naming nothing)."""
    running = getattr(bpy.app, "is_job_running", None)
    return bool(running and running("RENDER"))


def render_thread() -> bool:
    """Whether this call comes from a render job's own thread (a handler Blender calls
    there): nothing may be read or written beside the render.  A script that drives
    ``bpy`` from a thread of its own, with no render job, is not one."""
    return threading.current_thread() is not threading.main_thread() and rendering()


def fit(display: Size, longest: int) -> Size:
    """Scale ``display`` (W, H) down so its longest side is at most ``longest``."""
    w, h = display
    if w < 1 or h < 1:
        raise OccError(f"the view is {w}x{h} pixels: nothing to cull for")
    s = min(1.0, longest / max(w, h))
    return max(1, round(w * s)), max(1, round(h * s))
