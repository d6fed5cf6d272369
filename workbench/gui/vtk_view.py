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
vtkGenericRenderWindowInteractor), so trackball rotation, zoom and VTK widgets work as before;
moves queued while the thread is busy are merged into the newest. Keys are not forwarded (VTK's
default keys quit, or switch to wireframe). Everything touching the plotter or its actors must run
in a `call`: VTK objects are not thread-safe.
"""
from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtGui import QColor, QImage, QPainter
from PySide6.QtWidgets import QWidget

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
            self.call(lambda pl, s=size: _resize(pl, s), merge="size")

    # -- mouse → the interactor ----------------------------------------------------------------
    def _forward(self, event, vtk_event: str, repeat: int = 0, merge: str | None = None) -> None:
        dpr = self.devicePixelRatioF()
        pos = event.position()
        x, y = round(pos.x() * dpr), round(pos.y() * dpr)
        mods = event.modifiers()
        ctrl = bool(mods & Qt.KeyboardModifier.ControlModifier)
        shift = bool(mods & Qt.KeyboardModifier.ShiftModifier)

        def forward(pl):
            iren = pl.iren.interactor
            iren.SetEventInformationFlipY(x, y, ctrl, shift, chr(0), repeat, None)
            iren.InvokeEvent(vtk_event)
        self.call(forward, merge=merge)

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
