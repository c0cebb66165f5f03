"""The engine's OpenGL work runs on one thread of its own.

The engine makes its own (EGL or platform) context current and leaves it
current; on the main thread that would displace Blender's context behind its
back, depending on how the platform's GL dispatch treats two APIs on one
thread.  On a thread of its own the engine's context is the only one there,
and Blender's main thread is never touched.  :meth:`EngineThread.run` waits
for its call; :meth:`EngineThread.submit` returns a :class:`Job` at once, so a
modal operator can keep the interface alive while a long build runs (it polls
:meth:`Job.done` from its timer).  bpy is never used on the worker.

The thread is a daemon with its own queue (not a ``concurrent.futures`` pool,
which refuses work once the interpreter starts to exit): Blender unregisters
add-ons at exit, and the engine's last ``close`` must neither fail nor print.
When the thread can no longer run (interpreter finalizing), work that only
frees resources is dropped: the process frees them.

A context that is current on a thread when the thread ends is never freed (EGL
keeps it for the thread until the thread releases it; Mesa frees a context
destroyed while current only when it stops being current): the thread releases its
EGL state before it ends (:func:`release_thread_gl`).  Without it every
disable/enable of the add-on kept its last engine's context, about 20 MB
(``tools/checks/soak.py``, issue 30).

The thread keeps one context for its whole life (:func:`thread_gl_context`): every
engine built on it, after an undo, a file load or a resize too, draws on that context,
and the thread releases it before it ends.  A context made and released per engine kept
memory each time (moderngl's and the driver's: the soak's undo phase, two new engines a
cycle, grew about 20 MB over 200 undo/redo pairs).
"""

import ctypes
import gc
import os
import queue
import sys
import threading
import weakref
from typing import NamedTuple

_LOCAL = threading.local()        # the engine thread's own GL context (thread_gl_context)


def thread_gl_context():
    """On the engine thread: its GL context, made at the first engine and kept until the
    thread ends (module doc).  Engines built with it leave it open when they close."""
    ctx = getattr(_LOCAL, "ctx", None)
    if ctx is None:
        from ..core.gl import create_context  # the engine's GL, made on the thread that uses it
        ctx = _LOCAL.ctx = create_context()
    return ctx


def drop_thread_gl_context():
    """On the engine thread: release its context (the thread ends, or an engine failed
    on it and the next one starts on a fresh context).  Never raises."""
    ctx, _LOCAL.ctx = getattr(_LOCAL, "ctx", None), None
    if ctx is not None:
        from ..core.gl import release_context
        try:
            release_context(ctx)
        except Exception:  # a broken context: the thread's end frees what is left  # noqa: BLE001
            pass


class Progress(NamedTuple):
    """What a step generator yields between jobs: where it is, and how far (0 .. 1)."""

    label: str
    fraction: float | None      # None: not known (a job running)


class Job:
    """One call handed to the engine thread: :meth:`done` polls, :meth:`result` waits."""

    def __init__(self):
        self._ok = self._value = None
        self._done = threading.Event()

    @classmethod
    def finished(cls, value):
        job = cls()
        job._set(True, value)
        return job

    def _set(self, ok, value):
        self._ok, self._value = ok, value
        self._done.set()

    def done(self):
        if self._done.is_set():
            _GC.settle()
            return True
        return False

    def wait(self):
        self._done.wait()
        _GC.settle()

    def result(self):
        """The call's value (waiting for it), or its exception raised here."""
        self._done.wait()
        _GC.settle()
        if not self._ok:
            raise self._value
        return self._value


def drive(steps, progress=None):
    """Run a generator of steps to its end on this thread and return its value: each
    :class:`Job` it yields is waited for, each :class:`Progress` goes to ``progress``
    if given; a step generator yields nothing else.  A modal operator drives the same generators from its
    timer instead."""
    try:
        while True:
            item = next(steps)
            if isinstance(item, Job):
                item.wait()
            elif not isinstance(item, Progress):
                raise TypeError(f"a step generator yielded {item!r}, not a Job or Progress")
            elif progress is not None:
                progress(item)
    except StopIteration as stop:
        return stop.value


class EngineThread:
    """``run(fn, *args)`` on the engine thread, returning its result or raising its
    exception; ``submit(fn, *args)`` hands it over and returns a :class:`Job`."""

    def __init__(self):
        self._thread = None
        self._jobs = None
        self._last = None            # the last job handed over (jobs run in order)
        _THREADS.add(self)

    def _loop(self, jobs):
        while True:
            job = jobs.get()
            if job is None:
                drop_thread_gl_context()
                release_thread_gl()
                return
            fn, args, kwargs, out = job
            try:
                ok, value = True, fn(*args, **kwargs)
            except BaseException as e:  # handed back to the caller, raised there
                ok, value = False, e
            del fn, args, kwargs, job
            _GC.ran()
            release_free_memory()
            # the result last: once a waiter sees it, this thread only goes back to the
            # queue's wait (see guard_operator_calls)
            out._set(ok, value)
            del out, value

    def alive(self):
        return self._thread is not None and self._thread.is_alive()

    def submit(self, fn, *args, **kwargs):
        """Queue ``fn(*args, **kwargs)`` (jobs run one at a time, in order); a :class:`Job`."""
        if not self.alive():                  # started by the first pass, never at registration
            if sys.is_finalizing():
                return Job.finished(None)
            self._jobs = queue.SimpleQueue()
            self._thread = threading.Thread(target=self._loop, args=(self._jobs,), name="occ-engine",
                                            daemon=True)
            self._thread.start()
        out = Job()
        _GC.hold()
        self._jobs.put((fn, args, kwargs, out))
        self._last = out
        return out

    def wait_idle(self):
        """Wait until every job handed over so far has run."""
        last = self._last
        if last is not None and self.alive():
            last.wait()
        _GC.settle()

    def run(self, fn, *args, **kwargs):
        return self.submit(fn, *args, **kwargs).result()

    def shutdown(self):
        if self.alive():
            self._jobs.put(None)
            self._thread.join(timeout=10)
        self._thread = self._jobs = None
        _GC.settle()


class CollectorHold:
    """Python's cyclic garbage collector never runs while the engine thread works.

    A collection runs on whichever thread happens to allocate, and it walks (and may
    free) every object of the process: on the engine thread it can free a main-thread
    cycle holding bpy objects, or walk a context override's dictionary while Blender
    reads it without the GIL inside another add-on's operator (``temp_override`` from
    a timer during a build).  Blender segfaulted so, its engine thread collecting inside
    ``build_hierarchy`` while the main thread ran ``object.delete`` (``tools/checks/override_stress.py``).
    So the main thread turns the collector off when it hands over work (where it was
    on) and back on, on the main thread, once every job handed over has run: a
    collection then runs on the main thread, between Blender's operators.  Reference
    counting frees everything else as before; what the collector would have freed waits
    for the end of the build."""

    def __init__(self):
        self._lock = threading.Lock()
        self._pending = 0          # jobs handed over and not yet run
        self._held = False         # the collector was on and this hold turned it off

    def hold(self):
        """On the main thread, before a job is handed over."""
        with self._lock:
            self._pending += 1
            if not self._held and gc.isenabled():
                gc.disable()
                self._held = True

    def ran(self):
        """On the engine thread, after a job ran (the collector stays off: see settle)."""
        with self._lock:
            self._pending -= 1

    def settle(self):
        """On the main thread: the collector back on once no job is left."""
        with self._lock:
            if self._held and self._pending <= 0:
                self._held = False
                gc.enable()


_GC = CollectorHold()


_THREADS = weakref.WeakSet()


_LIBC = []        # glibc's malloc_trim, once looked up (empty list: not looked up yet)


def release_free_memory():
    """Hand the memory a job freed back to the system (glibc's ``malloc_trim``; elsewhere
    nothing).  A pass's temporaries are large numpy arrays; glibc serves them from its
    arenas once its mmap threshold has risen, and keeps what they free for reuse:
    without this, 600 live passes on the sample city took Blender from 661 to 1,229 MB
    resident, with it from 633 to 920 MB (``tools/checks/soak.py --only live --count live=600``);
    a trim costs about 4 ms after an envelope pass on the city.  Runs on the engine thread
    before the job's result is handed over (no Python on this thread after that: see
    :func:`guard_operator_calls`).  Never raises."""
    if not _LIBC:
        trim = None
        if sys.platform.startswith("linux"):
            try:
                trim = ctypes.CDLL("libc.so.6").malloc_trim
                trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
            except (OSError, AttributeError):      # not glibc (musl has no malloc_trim)
                trim = None
        _LIBC.append(trim)
    if _LIBC[0] is not None:
        _LIBC[0](0)


def release_thread_gl():
    """On a thread about to end: release what EGL keeps for it (its current context,
    which stays allocated while it is current, destroyed or not).  Only where the
    engine made an EGL context (Linux: glcontext's EGL backend loaded, so libEGL is
    in the process); elsewhere nothing.  Never raises: the thread ends anyway."""
    if not sys.platform.startswith("linux") or "glcontext.egl" not in sys.modules:
        return
    # the library the engine's context came from (core.gl.context's OCC_LIBEGL, glcontext's
    # own variable, else the system's, as glcontext finds it)
    name = os.environ.get("OCC_LIBEGL") or os.environ.get("GLCONTEXT_LINUX_LIBEGL") or "libEGL.so.1"
    try:
        ctypes.CDLL(name).eglReleaseThread()
    except (OSError, AttributeError):  # no such library or symbol: nothing of ours was current
        pass


def quiet():
    """Wait until no engine thread runs: the add-on calls a Blender operator only then.
    Inside an operator Blender may let other Python threads run (while it evaluates)
    and then read a Python context override without holding the GIL: with an engine
    thread running Python at that moment, Blender crashed (bpy 5.0.1: a save, whose
    handler ends the own local view through ``view3d.localview``, while a modal first
    Cull built the engine; the core dump in ``BPY_context_member_get``)."""
    for thread in list(_THREADS):
        thread.wait_idle()


class _OperatorGuard:
    """Every operator a Python script calls (``bpy.ops``: another add-on's timer, a user
    script, this add-on) first waits until the engine thread is idle.

    Blender 4.2 and 5.0 read a ``temp_override``'s dictionary without holding Python's
    lock inside an operator; any other Python thread running Python then crashes Blender
    (``tools/repro/override_thread_crash.py``: plain bpy and a plain ``threading.Thread``,
    every run crashes within the first calls on 4.2 and 5.0.1; 5.2 runs them all).  The
    engine thread runs Python while it builds or culls, and another add-on's operator
    cannot be held back otherwise (``tools/checks/override_stress.py``), so the call Blender's
    ``bpy.ops`` makes (``bpy.ops._op_call``) is wrapped: the wait costs nothing while the
    engine is idle, and blocks the caller until the engine's job ends while it works.
    Installed at registration, taken out at unregistration (or, where something wrapped
    it since, left as a pass-through).  Blender 5.2 has no such call (its operators are
    functions made in C) and needs none: nothing is wrapped there."""

    def __init__(self, ops_module):
        self.module = ops_module
        self.inner = ops_module._op_call
        self.active = True

    def __call__(self, *args):
        if self.active:
            quiet()
        return self.inner(*args)


_GUARD = None


def guard_operator_calls(ops_module):
    """Wrap ``ops_module._op_call`` (``sys.modules["bpy.ops"]``) once: see :class:`_OperatorGuard`."""
    global _GUARD
    if _GUARD is not None or not callable(vars(ops_module).get("_op_call")):
        return                     # Blender 5.2 makes each operator a function of its own: no such call
    _GUARD = _OperatorGuard(ops_module)
    ops_module._op_call = _GUARD


def unguard_operator_calls():
    """Take the wrapper out (or turn it into a pass-through where another wrapped it since)."""
    global _GUARD
    guard, _GUARD = _GUARD, None
    if guard is None:
        return
    guard.active = False
    if guard.module._op_call is guard:
        guard.module._op_call = guard.inner
