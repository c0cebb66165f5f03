"""The add-on's change bus: who announces a change and who acts on it meet here, and
this module imports nothing (so neither side imports the other).

Events (each listener is called with the event's arguments, in subscription order):

- ``"changed"`` (): something changed that may change what is visible (an edit, a new
  frame, a setting, another view layer); not the view, which live mode polls.
- ``"edited"`` (scene, data): an edit not the add-on's own, or a new frame; ``data``:
  it touched a datablock beside the scene and its cameras (an object, its data, a
  material, a light, a world, a collection), or Blender did not say what (a change of
  the scene alone is a selection, a setting; a camera's moves the view through it).
- ``"setting"`` (): an add-on property with an update callback changed (an object's
  "never cull"): Blender reports it to no depsgraph handler.
- ``"camera"`` (scene): a frame change or an edit may have moved the scene camera.
- ``"window"`` (): a window shows another scene or view layer (after the add-on's own
  local view followed it).
- ``"loaded"`` (): a file was opened.
- ``"undone"`` (): an undo or redo replaced Blender's data.

Each module subscribes what it owns when the add-on registers, and unsubscribes it
when it unregisters.
"""

from collections.abc import Callable

EVENTS = ("changed", "edited", "setting", "camera", "window", "loaded", "undone")

_listeners: dict[str, list[Callable[..., None]]] = {e: [] for e in EVENTS}


def subscribe(event: str, listener: Callable[..., None]) -> None:
    """Call ``listener`` after every ``event`` (once, however often subscribed)."""
    if listener not in _listeners[event]:
        _listeners[event].append(listener)


def unsubscribe(event: str, listener: Callable[..., None]) -> None:
    if listener in _listeners[event]:
        _listeners[event].remove(listener)


def emit(event: str, *args) -> None:
    for f in list(_listeners[event]):
        f(*args)


def notify() -> None:
    """Something changed that may change what is visible (the ``"changed"`` event)."""
    emit("changed")
