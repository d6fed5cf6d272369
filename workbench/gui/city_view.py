"""The 3-D city view: the project's city, the camera with its view frustum, a gizmo to drag the
camera, typed pose values, colour by class, and "look through camera".

The gizmo (a magenta sphere at the camera) moves the camera only when a drag starts on it where it
can be seen: a press is picked through the depth buffer (visible_actor_at), so a drag whose pick
ray passes a gizmo hidden behind a building orbits the view instead. A dragged gizmo slides in the
horizontal plane at the camera's height, and the camera moves there when it is dropped. The first
view of a city looks down on the camera from the lowest of a few elevations at which the gizmo is
visible (a street, the camera and its frustum; not the wall of the nearest building).

Generating the city (seed, arrangement) and merging it into one mesh run on a superqt worker
thread. The view is an OffscreenPlotterView: its plotter lives on a render thread of its own, so
adding the city, moving the frustum, switching "Colour by class" and every redraw run there, not
on the GUI thread; the actors it keeps (the `_gl` dict) are touched only in its `call`s. A camera
move only moves the frustum's points and the gizmo. Pose edits go through the document (one
undoable edit). The view is made for the first city project: a chart project's window has none."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QCheckBox, QDoubleSpinBox, QFormLayout, QHBoxLayout, QLabel,
                               QPushButton, QSpinBox, QVBoxLayout, QWidget)

from workbench.project import Project


def city_and_pose(project: Project, city=None):
    """The city and camera pose of the project's frame 0, as the pipeline's scene stage renders it;
    with `city` (the one this project's recipe and seed generate), only the pose is computed."""
    from workbench.render.city_frame import frame_seeds
    from workbench.scene.city import generate_city, sample_camera_poses
    from workbench.scene.city.recipe import CityRecipe, PoseParams
    seeds = frame_seeds(project.seed, 0)
    if city is None:
        recipe = (project.city or CityRecipe()).model_copy(update={"arrangement": seeds.arrangement})
        city = generate_city(recipe)
    pose = sample_camera_poses(city, project.pose or PoseParams(), 1, seeds.pose)[0]
    return city, pose


def _city_job(project: Project, job: int, key, shown_city):
    """The worker's result: the request it answers, the city, its pose and its merged mesh. With
    the city already shown (only the pose changed) the city is not generated again (~90 ms of
    Python holding the GIL on a full city) and the mesh is None."""
    from workbench.scene.city.view import city_polydata
    city, pose = city_and_pose(project, shown_city)
    return job, key, city, pose, (None if shown_city is not None else city_polydata(city))


def _city_key(project: Project):
    return (project.city, project.seed)


def _spin(lo: float, hi: float, decimals: int, suffix: str) -> QDoubleSpinBox:
    box = QDoubleSpinBox()
    box.setRange(lo, hi)
    box.setDecimals(decimals)
    box.setSuffix(suffix)
    box.setKeyboardTracking(False)
    return box


class CityView(QWidget):
    """The city, the camera and its frustum, with pose and seed controls."""

    gizmoDropped = Signal(object)                # the gizmo's centre (emitted on the render thread)

    def __init__(self, document, parent=None):
        super().__init__(parent)
        self.document = document
        self.view = None                         # the 3-D view, made for the first city (_ensure_view)
        self._gl: dict = {}                      # the view's actors: touched only in view.call()
        self.placeholder = QLabel("No city in this project: its scene is a test chart.")
        self.placeholder.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.project: Project | None = None
        self.city = None
        self.pose = None
        self._city_key = None
        self._job_id = 0
        self.gizmoDropped.connect(self._gizmo_moved)

        self.by_class = QCheckBox("Colour by class")
        self.by_class.toggled.connect(lambda _v: self._recolour())
        self.look_through = QCheckBox("Look through camera")
        self.look_through.toggled.connect(lambda _v: self._redraw_camera(reset_view=True))
        self.status = QLabel("")
        self.pose_boxes = {"x": _spin(-1e4, 1e4, 2, " m"), "y": _spin(-1e4, 1e4, 2, " m"),
                           "height": _spin(0.01, 50, 2, " m"), "pan": _spin(-360, 360, 1, "°"),
                           "tilt": _spin(-90, 90, 1, "°"), "roll": _spin(-180, 180, 1, "°")}
        apply_pose = QPushButton("Set pose")
        apply_pose.setToolTip("place the camera at these values (pose mode 'manual')")
        apply_pose.clicked.connect(self.apply_typed_pose)
        self.seed_box = QSpinBox()
        self.seed_box.setRange(0, 2**31 - 1)
        self.seed_box.setToolTip("city seed: streets, buildings and placements")
        regen = QPushButton("Regenerate city")
        regen.clicked.connect(lambda: self.document.edit("city", {"seed": self.seed_box.value()}))

        form = QFormLayout()
        row1, row2 = QHBoxLayout(), QHBoxLayout()
        for k in ("x", "y", "height"):
            row1.addWidget(QLabel(k))
            row1.addWidget(self.pose_boxes[k])
        for k in ("pan", "tilt", "roll"):
            row2.addWidget(QLabel(k))
            row2.addWidget(self.pose_boxes[k])
        row2.addWidget(apply_pose)
        form.addRow("Position", row1)
        form.addRow("Angles", row2)
        row3 = QHBoxLayout()
        row3.addWidget(self.by_class)
        row3.addWidget(self.look_through)
        row3.addStretch(1)
        row3.addWidget(QLabel("seed"))
        row3.addWidget(self.seed_box)
        row3.addWidget(regen)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        lay.addWidget(self.placeholder, 1)
        lay.addLayout(row3)
        lay.addLayout(form)
        lay.addWidget(self.status)

    def _ensure_view(self) -> None:
        """Make the 3-D view in place of the placeholder, for the first city project."""
        if self.view is not None:
            return
        from workbench.gui.vtk_view import OffscreenPlotterView
        self.view = OffscreenPlotterView(parent=self)
        self.view.set_drag_handler(self._drag_gizmo)
        self.view.failed.connect(lambda message: self.status.setText(f"3-D view: {message}"))
        self.layout().replaceWidget(self.placeholder, self.view)
        self.placeholder.hide()

    # -- project → view --------------------------------------------------------------------
    def set_project(self, project: Project) -> None:
        self.project = project
        if project.scene.kind != "city":
            self.status.setText("This project's scene is a test chart; pick a city sample to see a city.")
            if self.city is not None:
                self.city, self._city_key = None, None
                self.view.call(self._clear)
            return
        self._ensure_view()
        self.seed_box.setValue(min((project.city.seed if project.city else 0), 2**31 - 1))
        key = (_city_key(project), project.pose)
        if key == self._city_key:
            return
        self._generate(project, key)

    def _generate(self, project: Project, key) -> None:
        """Generate the city and pose on a worker thread (latest request wins). The worker holds
        no reference to this widget: its signals reach bound methods, which Qt disconnects if the
        widget goes first."""
        from superqt.utils import create_worker
        self._job_id += 1
        self.status.setText("generating the city…")
        same_city = self.city is not None and self._city_key is not None and self._city_key[0] == key[0]
        worker = create_worker(_city_job, project, self._job_id, key, self.city if same_city else None,
                               _start_thread=False, _ignore_errors=True)
        worker.returned.connect(self._city_ready)
        worker.errored.connect(self._city_failed)
        worker.start()

    def _city_failed(self, exc: Exception) -> None:
        self.status.setText(f"city: {type(exc).__name__}: {exc}")

    def _city_ready(self, payload) -> None:
        job, key, city, pose, mesh = payload
        if job != self._job_id:
            return
        same_city = mesh is None and self.city is not None
        self._city_key = key
        self.pose = pose
        p = pose.position_m
        self._show_pose_values(pose)
        if not same_city:
            self.city = city
            self._show_city(mesh)
        else:
            self._redraw_camera()
        self.status.setText(f"{len(city.objects)} objects; camera at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.2f}) m, "
                            f"pan {pose.pan_deg:.1f}°")

    def _show_pose_values(self, pose) -> None:
        """The pose boxes show `pose` (without emitting edits)."""
        p = pose.position_m
        for name, value in zip(("x", "y", "height", "pan", "tilt", "roll"),
                               (p[0], p[1], p[2], pose.pan_deg, pose.tilt_deg, pose.roll_deg)):
            box = self.pose_boxes[name]
            box.blockSignals(True)
            box.setValue(float(value))
            box.blockSignals(False)

    def _hfov_deg(self) -> float:
        from workbench.stages.geometry import project_geometry
        return project_geometry(self.project).hfov_deg

    def _colouring(self) -> str:
        return "class" if self.by_class.isChecked() else "material"

    def _show_city(self, mesh) -> None:
        """Replace the shown city by a prebuilt mesh (city_polydata) and frame the camera."""
        def show(pl, colouring=self._colouring()):
            from workbench.scene.city.view import add_city_to_plotter
            self._clear(pl)
            self._gl["city"] = add_city_to_plotter(pl, mesh=mesh, color_by=colouring)["city"]
        self.view.call(show)
        self._redraw_camera(reset_view=True)

    def _clear(self, pl) -> None:
        """(render thread) Remove the city, the frustum and the gizmo."""
        pl.clear()
        self._gl.clear()

    def _recolour(self) -> None:
        def recolour(_pl, colouring=self._colouring()):
            from workbench.scene.city.view import set_city_colouring
            if "city" in self._gl:
                set_city_colouring(self._gl["city"], colouring)
        if self.view is not None:
            self.view.call(recolour)

    def _redraw_camera(self, reset_view: bool = False) -> None:
        """Show the camera: its frustum and gizmo moved to the pose (created once), or the view
        through it."""
        if self.city is None or self.pose is None:
            return
        self.view.call(lambda pl, pose=self.pose, hfov=self._hfov_deg(), through=self.look_through.isChecked():
                       self._draw_camera(pl, pose, hfov, through, reset_view))

    def _draw_camera(self, pl, pose, hfov: float, through: bool, reset_view: bool) -> None:
        """(render thread) The frustum and gizmo at `pose`, or the view through it."""
        from workbench.scene.city.view import add_camera_frustum, look_through, move_camera_frustum
        if through:
            pl.remove_actor("city_camera")
            pl.remove_actor("camera_gizmo")
            self._gl.pop("frustum", None)
            self._gl.pop("gizmo", None)
            look_through(pl, pose, hfov)
            return
        if "frustum" not in self._gl:
            self._gl["frustum"] = add_camera_frustum(pl, pose, hfov, frustum_length_m=12.0)
        else:
            move_camera_frustum(self._gl["frustum"], pose, hfov, frustum_length_m=12.0)
        if "gizmo" not in self._gl:
            import pyvista as pv
            self._gl["gizmo"] = pl.add_mesh(pv.Sphere(radius=GIZMO_RADIUS_M), color="magenta",
                                            name="camera_gizmo", pickable=True)
        self._gl["gizmo"].SetPosition(*(float(v) for v in pose.position_m))
        if reset_view:
            _overview(pl, pose, self._gl["gizmo"])

    def _drag_gizmo(self, pl, x: int, y: int, phase: str) -> bool:
        """(render thread; the view's drag handler) A press on the visible gizmo claims the drag;
        moves slide the gizmo in the horizontal plane at its height; the release drops it."""
        gizmo = self._gl.get("gizmo")
        if gizmo is None:
            return False
        if phase == "press":
            if visible_actor_at(pl, x, y) is not gizmo:
                return False
            self._gl["drag_from"] = gizmo.GetPosition()
            return True
        at = _on_horizontal_plane(pl, x, y, gizmo.GetPosition()[2])
        if at is not None:
            gizmo.SetPosition(*at)
        if phase == "release":
            dropped, start = gizmo.GetPosition(), self._gl.pop("drag_from")
            if np.hypot(dropped[0] - start[0], dropped[1] - start[1]) > 0:
                self.gizmoDropped.emit(tuple(float(v) for v in dropped))
        return True

    def render(self) -> None:
        if self.view is not None:
            self.view.render()

    # -- view → document -------------------------------------------------------------------
    def _gizmo_moved(self, center) -> None:
        """The camera gizmo was dropped: move the camera there (keeping its height and angles)."""
        x, y = float(center[0]), float(center[1])
        if self.pose is None or np.hypot(x - self.pose.position_m[0], y - self.pose.position_m[1]) < 0.01:
            return                        # placed, not moved
        self.pose_boxes["x"].setValue(x)
        self.pose_boxes["y"].setValue(y)
        self.apply_typed_pose()

    def _exact_pose(self) -> dict[str, float]:
        p = self.pose.position_m
        return dict(zip(("x", "y", "height", "pan", "tilt", "roll"),
                        (p[0], p[1], p[2], self.pose.pan_deg, self.pose.tilt_deg, self.pose.roll_deg)))

    def _untouched(self) -> set[str]:
        """The pose boxes still showing the camera's value (to their displayed precision)."""
        if self.pose is None:
            return set()
        exact = self._exact_pose()
        return {k for k, box in self.pose_boxes.items()
                if abs(box.value() - exact[k]) <= 0.5 * 10.0 ** -box.decimals() + 1e-9}

    def typed_pose(self) -> dict:
        """The pose the boxes describe: a box not edited keeps the camera's exact value (the boxes
        show it rounded to 0.01 m / 0.1°)."""
        untouched = self._untouched()
        exact = self._exact_pose() if self.pose is not None else {}
        b = {k: (exact[k] if k in untouched else box.value()) for k, box in self.pose_boxes.items()}
        return {"mode": "manual", "manual_position_xy_m": (b["x"], b["y"]), "height_m": b["height"],
                "manual_pan_deg": b["pan"], "manual_tilt_deg": b["tilt"], "manual_roll_deg": b["roll"]}

    def apply_typed_pose(self) -> None:
        """Set pose: the typed values become a manual pose; with nothing changed, nothing happens."""
        if self.pose is not None and len(self._untouched()) == len(self.pose_boxes):
            self.status.setText("pose unchanged: type a new value first")
            return
        pose = self.typed_pose()
        try:
            if self.city is not None:             # refused before it becomes an edit (and an undo step)
                from workbench.scene.city.poses import check_camera_spot
                check_camera_spot(self.city, *pose["manual_position_xy_m"])
            self.document.edit("pose", pose)
        except ValueError as exc:
            self.status.setText(f"pose not set: {exc}")
            if self.pose is not None:             # the gizmo and the boxes go back to the camera
                self._show_pose_values(self.pose)
                self._redraw_camera()

    def close_view(self) -> None:
        self._job_id += 1
        if self.view is not None:
            self.view.close_view()


def visible_actor_at(pl, x: int, y: int):
    """(render thread) The actor drawn nearest the viewer at display pixel (x, y) (bottom row 0),
    or None: picked through the depth buffer, so a prop hidden behind another is not found."""
    from vtkmodules.vtkRenderingCore import vtkPropPicker
    picker = vtkPropPicker()
    return picker.GetActor() if picker.Pick(x, y, 0.0, pl.renderer) else None


def _on_horizontal_plane(pl, x: int, y: int, height_m: float):
    """(render thread) Where the view ray through display pixel (x, y) meets the plane z =
    height_m, or None when it does not (in front of the viewer)."""
    ends = []
    for depth in (0.0, 1.0):
        pl.renderer.SetDisplayPoint(float(x), float(y), depth)
        pl.renderer.DisplayToWorld()
        w = pl.renderer.GetWorldPoint()
        ends.append(np.asarray(w[:3]) / w[3])
    d = ends[1] - ends[0]
    if abs(d[2]) < 1e-9:
        return None
    t = (height_m - ends[0][2]) / d[2]
    return tuple(ends[0] + t * d) if t > 0 else None


GIZMO_RADIUS_M = 1.2
OVERVIEW_ELEVATIONS_DEG = (30.0, 45.0, 60.0, 75.0, 89.0)
OVERVIEW_DISTANCE_M = 75.0


def _overview(pl, pose, gizmo=None) -> None:
    """(render thread) A view from behind and above the camera at the lowest of
    OVERVIEW_ELEVATIONS_DEG from which the gizmo is visible (the last when none), looking at a
    point ahead of the camera: the street, the camera and its frustum."""
    from workbench.scene.city.poses import pose_basis
    f, _r, _u = pose_basis(pose)
    ahead = np.array([f[0], f[1], 0.0]) / max(np.hypot(f[0], f[1]), 1e-9)
    p = np.asarray(pose.position_m, dtype=float)
    focus = p + 10.0 * ahead
    pl.camera.focal_point = tuple(focus)
    pl.camera.up = (0.0, 0.0, 1.0)
    pl.camera.view_angle = 45.0
    for elevation in OVERVIEW_ELEVATIONS_DEG:
        e = np.radians(elevation)
        pl.camera.position = tuple(focus + OVERVIEW_DISTANCE_M * (-np.cos(e) * ahead + np.array([0.0, 0.0, np.sin(e)])))
        pl.camera.up = (0.0, 0.0, 1.0)
        pl.reset_camera_clipping_range()
        if gizmo is None:
            return
        pl.renderer.SetWorldPoint(*p, 1.0)
        pl.renderer.WorldToDisplay()
        x, y, _ = pl.renderer.GetDisplayPoint()
        if visible_actor_at(pl, round(x), round(y)) is gizmo:
            return
