"""The engine's OpenGL work runs on one thread of its own.

The engine makes its own (EGL or platform) context current and leaves it
current; on the main thread that would displace Blender's context behind its
back, depending on how the platform's GL dispatch treats two APIs on one
thread.  On a thread of its own the engine's context is the only one there,
and Blender's main thread is never touched.  Calls are synchronous: the main
thread waits for each (operators must finish before Blender redraws), and bpy
is never used on the worker.
"""

from concurrent.futures import ThreadPoolExecutor


class EngineThread:
    """``run(fn, *args)`` on the engine thread, returning its result or raising its exception."""

    def __init__(self):
        self._pool = None

    def run(self, fn, *args, **kwargs):
        if self._pool is None:               # started by the first pass, never at registration
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="occ-engine")
        return self._pool.submit(fn, *args, **kwargs).result()

    def shutdown(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
