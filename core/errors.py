"""The one domain exception of the engine.

Everything a user can cause (bad files, bad cameras, empty scenes, a machine
without EGL) raises :class:`OccError` with a message that says what to do.  The
Blender add-on maps it to ``self.report``; the CLI prints it and exits 2.
"""


class OccError(Exception):
    """A problem with the input or the machine, described for the user."""
