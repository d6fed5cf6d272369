"""The 3-D city view (pyvistaqt): the project's city, the camera with its view frustum, a gizmo
to drag the camera, typed pose values, colour by class, and "look through camera".

Generating the city (seed, arrangement) and merging it into one mesh run on a superqt worker
thread; the mesh comes back to the GUI thread, which alone adds it to VTK (and alone drops the
last reference to this widget). A camera move only moves the frustum's points and the gizmo, and
"Colour by class" switches the mesh's colour array, so neither rebuilds the city on the GUI
thread. Pose edits go through the document (one undoable edit). The GL view itself is made for
the first city project: a chart project's window has none (see _ensure_plotter)."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QCheckBox, QDoubleSpinBox, QFormLayout, QHBoxLayout, QLabel,
                               QPushButton, QSpinBox, QVBoxLayout, QWidget)

from workbench.project import Project


def city_and_pose(project: Project):
    """The city and camera pose of the project's frame 0, as the pipeline's scene stage renders it."""
    from workbench.render.city_frame import frame_seeds
    from workbench.scene.city import generate_city, sample_camera_poses
    from workbench.scene.city.recipe import CityRecipe, PoseParams
    seeds = frame_seeds(project.seed, 0)
    recipe = (project.city or CityRecipe()).model_copy(update={"arrangement": seeds.arrangement})
    city = generate_city(recipe)
    pose = sample_camera_poses(city, project.pose or PoseParams(), 1, seeds.pose)[0]
    return city, pose


def _city_job(project: Project, job: int, key, same_city):
    """The worker's result: the request it answers, the city, its pose and its merged mesh
    (None when the city is the one already shown: only the pose changed)."""
    from workbench.scene.city.view import city_polydata
    city, pose = city_and_pose(project)
    return job, key, city, pose, (None if same_city else city_polydata(city))


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

    def __init__(self, document, parent=None):
        super().__init__(parent)
        self.document = document
        self.plotter = None                      # the GL view, made for the first city (_ensure_plotter)
        self.placeholder = QLabel("No city in this project: its scene is a test chart.")
        self.placeholder.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.project: Project | None = None
        self.city = None
        self.pose = None
        self._city_key = None
        self._city_actor = None
        self._frustum = None
        self._job_id = 0
        self._gizmo = None

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

    def _ensure_plotter(self) -> None:
        """Make the GL view (pyvistaqt's QOpenGLWidget) in place of the placeholder. Only a city
        needs it, and while a window holds a GL widget Qt composites the whole window through
        OpenGL on every repaint (~10 ms a repaint at 1600×1000 on a software renderer), so a
        chart project's window never has one."""
        if self.plotter is not None:
            return
        from pyvistaqt import QtInteractor
        self.plotter = QtInteractor(self, off_screen=False, auto_update=False)
        self.plotter.set_background("#dfe8f0", top="#7fa7cf")
        self.layout().replaceWidget(self.placeholder, self.plotter.interactor)
        self.placeholder.hide()

    # -- project → view --------------------------------------------------------------------
    def set_project(self, project: Project) -> None:
        self.project = project
        if project.scene.kind != "city":
            self.status.setText("This project's scene is a test chart; pick a city sample to see a city.")
            if self.city is not None:
                self.plotter.clear()
                self.city, self._city_key, self._city_actor, self._frustum = None, None, None, None
                self.plotter.render()
            return
        self._ensure_plotter()
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
        same_city = self._city_key is not None and self._city_key[0] == key[0]
        worker = create_worker(_city_job, project, self._job_id, key, same_city, _start_thread=False,
                               _ignore_errors=True)
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
        for name, value in zip(("x", "y", "height", "pan", "tilt", "roll"),
                               (p[0], p[1], p[2], pose.pan_deg, pose.tilt_deg, pose.roll_deg)):
            box = self.pose_boxes[name]
            box.blockSignals(True)
            box.setValue(float(value))
            box.blockSignals(False)
        if not same_city:
            self.city = city
            self._show_city(mesh)
        else:
            self._redraw_camera()
        self.status.setText(f"{len(city.objects)} objects; camera at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.2f}) m, "
                            f"pan {pose.pan_deg:.1f}°")

    def _hfov_deg(self) -> float:
        from workbench.stages.geometry import project_geometry
        return project_geometry(self.project).hfov_deg

    def _colouring(self) -> str:
        return "class" if self.by_class.isChecked() else "material"

    def _show_city(self, mesh) -> None:
        """Replace the shown city by a prebuilt mesh (city_polydata) and frame the camera."""
        from workbench.scene.city.view import add_city_to_plotter
        self._remove_gizmo()
        self.plotter.clear()
        self._frustum = None
        self._city_actor = add_city_to_plotter(self.plotter, mesh=mesh, color_by=self._colouring())["city"]
        self._redraw_camera(reset_view=True)

    def _recolour(self) -> None:
        from workbench.scene.city.view import set_city_colouring
        if self._city_actor is not None:
            set_city_colouring(self._city_actor, self._colouring())
            self.render()

    def _redraw_camera(self, reset_view: bool = False) -> None:
        """Show the camera: its frustum and gizmo moved to the pose (created once), or the view
        through it."""
        if self.city is None or self.pose is None:
            return
        from workbench.scene.city.view import add_camera_frustum, look_through, move_camera_frustum
        hfov = self._hfov_deg()
        if self.look_through.isChecked():
            self.plotter.remove_actor("city_camera")
            self._frustum = None
            self._remove_gizmo()
            look_through(self.plotter, self.pose, hfov)
        else:
            if self._frustum is None:
                self._frustum = add_camera_frustum(self.plotter, self.pose, hfov, frustum_length_m=12.0)
            else:
                move_camera_frustum(self._frustum, self.pose, hfov, frustum_length_m=12.0)
            self._place_gizmo()
            if reset_view:
                self._overview()
        self.render()

    def _overview(self) -> None:
        """An oblique view from behind and above the camera, showing the city around it."""
        from workbench.scene.city.poses import pose_basis
        f, _r, _u = pose_basis(self.pose)
        p = np.asarray(self.pose.position_m, dtype=float)
        self.plotter.camera.focal_point = tuple(p + 25 * f)
        self.plotter.camera.position = tuple(p - 45 * f + np.array([0.0, 0.0, 35.0]))
        self.plotter.camera.up = (0.0, 0.0, 1.0)
        self.plotter.camera.view_angle = 45.0
        self.plotter.reset_camera_clipping_range()

    def _place_gizmo(self) -> None:
        if self._gizmo is not None:                # move the one there is
            self._gizmo.SetCenter(*(float(v) for v in self.pose.position_m))
            return
        self._gizmo = self.plotter.add_sphere_widget(
            self._gizmo_moved, center=tuple(self.pose.position_m), radius=1.2, color="magenta",
            style="surface", interaction_event="end")

    def _remove_gizmo(self) -> None:
        if self._gizmo is not None:
            self.plotter.clear_sphere_widgets()
            self._gizmo = None

    def render(self) -> None:
        if self.plotter is not None:
            self.plotter.render()

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
        try:
            self.document.edit("pose", self.typed_pose())
        except ValueError as exc:
            self.status.setText(f"pose not set: {exc}")

    def close_view(self) -> None:
        self._job_id += 1
        if self.plotter is not None:
            self.plotter.close()
