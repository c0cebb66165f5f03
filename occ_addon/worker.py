"""The engine's OpenGL work runs on one thread of its own.

The engine makes its own (EGL or platform) context current and leaves it
current; on the main thread that would displace Blender's context behind its
back, depending on how the platform's GL dispatch treats two APIs on one
thread.  On a thread of its own the engine's context is the only one there,
and Blender's main thread is never touched.  Calls are synchronous: the main
thread waits for each (operators must finish before Blender redraws), and bpy
is never used on the worker.

The thread is a daemon with its own queue (not a ``concurrent.futures`` pool,
which refuses work once the interpreter starts to exit): Blender unregisters
add-ons at exit, and the engine's last ``close`` must neither fail nor print.
When the thread can no longer run (interpreter finalizing), work that only
frees resources is dropped: the process frees them.
"""

import queue
import sys
import threading


class EngineThread:
    """``run(fn, *args)`` on the engine thread, returning its result or raising its exception."""

    def __init__(self):
        self._thread = None
        self._jobs = None

    def _loop(self, jobs):
        while True:
            job = jobs.get()
            if job is None:
                return
            fn, args, kwargs, box, done = job
            try:
                box.append((True, fn(*args, **kwargs)))
            except BaseException as e:  # handed back to the caller, raised there
                box.append((False, e))
            done.set()

    def alive(self):
        return self._thread is not None and self._thread.is_alive()

    def run(self, fn, *args, **kwargs):
        if not self.alive():                  # started by the first pass, never at registration
            if sys.is_finalizing():
                return None
            self._jobs = queue.SimpleQueue()
            self._thread = threading.Thread(target=self._loop, args=(self._jobs,), name="occ-engine",
                                            daemon=True)
            self._thread.start()
        box, done = [], threading.Event()
        self._jobs.put((fn, args, kwargs, box, done))
        done.wait()
        ok, value = box[0]
        if not ok:
            raise value
        return value

    def shutdown(self):
        if self.alive():
            self._jobs.put(None)
            self._thread.join(timeout=10)
        self._thread = self._jobs = None
