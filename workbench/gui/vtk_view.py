"""A pyvista plotter drawn off screen on a thread of its own and shown in the window as an image.

The window's 3-D view used to be a QOpenGLWidget (pyvistaqt). A window that holds one is composited
through OpenGL on every repaint of any of its widgets (10-25 ms a repaint at 1600×1000 on a
software renderer), and each redraw of the city ran on the GUI thread (60-100 ms). Here the
plotter lives on a worker thread, which owns its OpenGL context: the GUI thread posts commands
(`call`), the thread runs them in order, renders once for the whole batch, reads the pixels back
and sends the image, which the widget paints like any other. VTK releases the GIL while it
renders, so the GUI thread keeps running; no native or GL child window is made, so the view works
the same under X, Wayland, Xvfb and Qt's offscreen platform (VTK picks X or EGL itself).

Mouse events are forwarded to the plotter's interactor (pyvista gives an off-screen plotter a
vtkGenericRenderWindowInteractor), so trackball rotation and zoom work as before; moves queued
while the thread is busy are merged into the newest. A drag handler (`set_drag_handler`) may claim
a left drag at its press (a handle the user can see there); its moves and release then go to the
handler, not to the camera. While a button is held for any other drag (orbit, pan, zoom) the view
renders at INTERACTIVE_PIXEL_FRACTION of its pixels, painted scaled up, and at full size again on
release: a software OpenGL's frame cost is nearly all per pixel (the full city, 44.5k triangles,
500×380 px: 110 ms, at a ninth of the pixels 32 ms, on 2 loaded cores). Keys are not forwarded
(VTK's default keys quit, or switch to wireframe). Everything touching the plotter or its actors
must run in a `call`: VTK objects are not thread-safe.
"""
from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtGui import QColor, QImage, QPainter
from PySide6.QtWidgets import QWidget

INTERACTIVE_PIXEL_FRACTION = 0.25      # of the view's pixels, drawn while a button drags the camera
VIEW_THREAD_NICE = 10
"""The render thread (and the threads a software OpenGL such as Mesa's llvmpipe starts from it,
one per core) runs at this niceness: a redraw after a camera move used to take both cores from the
GUI thread for 0.1–0.5 s, and the panes painted 3–5× slower meanwhile."""

_BUTTON_EVENTS = {Qt.MouseButton.LeftButton: "Left", Qt.MouseButton.MiddleButton: "Middle",
                  Qt.MouseButton.RightButton: "Right"}
_STOP = object()


def _lower_thread_priority(nice: int) -> None:
    """Raise the calling thread's niceness by `nice` (Linux: a thread's own value, which the
    threads it starts inherit); nothing where threads have no priority of their own."""
    import os
    import sys
    if sys.platform.startswith("linux"):
        try:
            tid = threading.get_native_id()
            os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + nice))
        except OSError:
            pass


class _Relay(QObject):
    """Carries the render thread's images to the GUI thread (a queued signal). It has no parent,
    so emitting stays safe after the widget is gone: Qt drops the connection with the widget."""
    image = Signal(object, int)
    failed = Signal(str)


class _RenderLoop:
    """The render thread's side: the command queue and the plotter. It holds no widget (a thread
    holding one could drop its last reference off the GUI thread), only the relay, which the view
    keeps alive too."""

    def __init__(self, size_px: tuple[int, int], background: tuple[str, str], relay: _Relay):
        self.size_px = size_px
        self.background = background
        self.relay = relay
        self.queue: deque = deque()
        self.wake = threading.Condition()
        self.posted = 0
        self.drag_handler: Callable | None = None   # set and read on the render thread only
        self.dragging = False                       # a left drag the handler claimed is under way
        self.scale = 1.0                            # render size / view size (< 1 while a drag orbits)

    def interact(self, plotter, on: bool) -> None:
        """(render thread) Render at INTERACTIVE_PIXEL_FRACTION of the pixels while a camera drag
        lasts (on), at full size again after it."""
        scale = INTERACTIVE_PIXEL_FRACTION ** 0.5 if on else 1.0
        if scale != self.scale:
            self.scale = scale
            _resize(plotter, _scaled(self.size_px, scale))

    def resize(self, plotter, size_px: tuple[int, int]) -> None:
        """(render thread) The view's new size, rendered at the current scale."""
        self.size_px = size_px
        _resize(plotter, _scaled(size_px, self.scale))

    def forward(self, plotter, vtk_event: str, x: int, y: int, ctrl: bool, shift: bool, repeat: int) -> None:
        """(render thread) One mouse event at view pixel (x, y), top row 0: to a claimed drag's
        handler, else to the interactor at the render size."""
        h = self.size_px[1]
        if vtk_event == "LeftButtonPressEvent" and self.drag_handler is not None and not repeat:
            self.dragging = bool(self.drag_handler(plotter, x, h - 1 - y, "press"))
            if self.dragging:
                return
        if self.dragging:
            if vtk_event in ("MouseMoveEvent", "LeftButtonReleaseEvent"):
                self.dragging = vtk_event == "MouseMoveEvent"
                self.drag_handler(plotter, x, h - 1 - y, "move" if self.dragging else "release")
            return
        if vtk_event.endswith("ButtonPressEvent"):
            self.interact(plotter, True)
        iren = plotter.iren.interactor
        iren.SetEventInformationFlipY(round(x * self.scale), round(y * self.scale), ctrl, shift, chr(0), repeat, None)
        iren.InvokeEvent(vtk_event)
        if vtk_event.endswith("ButtonReleaseEvent"):
            self.interact(plotter, False)

    def post(self, fn, merge: str | None) -> None:
        with self.wake:
            if merge is not None and self.queue and self.queue[-1][0] == merge:
                self.queue[-1] = (merge, fn)
            else:
                self.queue.append((merge, fn))
            self.posted += 1
            self.wake.notify()

    def run(self) -> None:
        import pyvista as pv
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray
        _lower_thread_priority(VIEW_THREAD_NICE)     # before the GL context: its renderer's threads inherit it
        plotter = pv.Plotter(off_screen=True, window_size=self.size_px)
        plotter.set_background(self.background[0], top=self.background[1])
        plotter.iren.interactor.EnableRenderOff()    # the thread renders once per batch of commands
        _resize(plotter, self.size_px)
        pixels = vtkUnsignedCharArray()
        while True:
            with self.wake:
                while not self.queue:
                    self.wake.wait()
                batch = list(self.queue)
                self.queue.clear()
                done = self.posted
            for _merge, fn in batch:
                if fn is _STOP:
                    plotter.close()
                    return
                if fn is not None:
                    try:
                        fn(plotter)
                    except Exception as exc:     # a failed command is reported; the view goes on
                        self.relay.failed.emit(f"{type(exc).__name__}: {exc}")
            self.relay.image.emit(_render_image(plotter, pixels), done)


class OffscreenPlotterView(QWidget):
    """A 3-D view: `call(fn)` runs fn(plotter) on the render thread and redraws. `background` is
    the gradient's (bottom, top) colours; a command that raises is reported by `failed`."""

    failed = Signal(str)

    def __init__(self, background: tuple[str, str] = ("#dfe8f0", "#7fa7cf"), parent=None):
        super().__init__(parent)
        self.setMinimumSize(120, 90)
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)
        self.background = background
        self.image: QImage | None = None
        self.frames_rendered = 0               # images received (tests and benchmarks wait on it)
        self.commands_rendered = 0             # commands whose effect is in the newest image
        self.last_error = ""
        self._relay = _Relay()
        self._relay.image.connect(self._image_ready)
        self._relay.failed.connect(self._failed)
        self._size_px = self._physical_size()
        self._loop = _RenderLoop(self._size_px, background, self._relay)
        self._thread = threading.Thread(target=self._loop.run, name="3-D view", daemon=True)
        self._thread.start()

    # -- GUI thread ------------------------------------------------------------------------
    def call(self, fn: Callable | None, merge: str | None = None) -> None:
        """Queue fn(plotter) for the render thread, then a render. With `merge`, a command of the
        same kind still waiting in the queue is replaced (mouse moves, resizes)."""
        self._loop.post(fn, merge)

    def render(self) -> None:
        self.call(None)

    def is_current(self) -> bool:
        """Whether the image shown has every command posted so far drawn in it."""
        return self.commands_rendered == self._loop.posted

    def close_view(self, timeout_s: float = 5.0) -> None:
        """Close the plotter on its thread and end the thread."""
        self._loop.post(_STOP, None)
        self._thread.join(timeout_s)

    def _physical_size(self) -> tuple[int, int]:
        dpr = self.devicePixelRatioF()
        return max(1, round(self.width() * dpr)), max(1, round(self.height() * dpr))

    def _image_ready(self, image: QImage, done: int) -> None:
        self.image = image
        self.frames_rendered += 1
        self.commands_rendered = done
        self.update()

    def _failed(self, message: str) -> None:
        self.last_error = message
        self.failed.emit(message)

    def paintEvent(self, _event) -> None:
        painter = QPainter(self)
        if self.image is None:
            painter.fillRect(self.rect(), QColor(self.background[1]))
        else:                                   # a resize in progress shows the last image scaled
            painter.drawImage(self.rect(), self.image)
        painter.end()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        size = self._physical_size()
        if size != self._size_px:
            self._size_px = size
            self.call(lambda pl, s=size, loop=self._loop: loop.resize(pl, s), merge="size")

    def set_drag_handler(self, handler: Callable | None) -> None:
        """handler(plotter, x, y, phase) runs on the render thread for left drags, (x, y) in display
        pixels (VTK's: bottom row 0): phase 'press' returns True to claim the drag; a claimed drag
        then gets 'move' for each move and 'release' at its end, and the camera does not move."""
        self.call(lambda _pl, loop=self._loop: setattr(loop, "drag_handler", handler))

    # -- mouse → the interactor ----------------------------------------------------------------
    def _forward(self, event, vtk_event: str, repeat: int = 0, merge: str | None = None) -> None:
        dpr = self.devicePixelRatioF()
        pos = event.position()
        x, y = round(pos.x() * dpr), round(pos.y() * dpr)
        mods = event.modifiers()
        ctrl = bool(mods & Qt.KeyboardModifier.ControlModifier)
        shift = bool(mods & Qt.KeyboardModifier.ShiftModifier)
        self.call(lambda pl, loop=self._loop: loop.forward(pl, vtk_event, x, y, ctrl, shift, repeat), merge=merge)

    def mousePressEvent(self, event) -> None:
        side = _BUTTON_EVENTS.get(event.button())
        if side:
            self._forward(event, f"{side}ButtonPressEvent")

    def mouseDoubleClickEvent(self, event) -> None:
        side = _BUTTON_EVENTS.get(event.button())
        if side:
            self._forward(event, f"{side}ButtonPressEvent", repeat=1)

    def mouseReleaseEvent(self, event) -> None:
        side = _BUTTON_EVENTS.get(event.button())
        if side:
            self._forward(event, f"{side}ButtonReleaseEvent")

    def mouseMoveEvent(self, event) -> None:
        self._forward(event, "MouseMoveEvent", merge="move")

    def wheelEvent(self, event) -> None:
        dy = event.angleDelta().y()
        if dy:
            self._forward(event, "MouseWheelForwardEvent" if dy > 0 else "MouseWheelBackwardEvent")


def _scaled(size: tuple[int, int], scale: float) -> tuple[int, int]:
    return max(1, round(size[0] * scale)), max(1, round(size[1] * scale))


def _resize(plotter, size: tuple[int, int]) -> None:
    plotter.render_window.SetSize(*size)
    plotter.iren.interactor.UpdateSize(*size)


def _render_image(plotter, pixels) -> QImage:
    """Render and read the image back (RGBA, top row first)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    window = plotter.render_window
    window.Render()
    w, h = window.GetSize()
    window.GetRGBACharPixelData(0, 0, w - 1, h - 1, 0, pixels)
    rgba = np.ascontiguousarray(vtk_to_numpy(pixels).reshape(h, w, 4)[::-1])
    return QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy()
