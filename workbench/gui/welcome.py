"""The first page a user sees when the window starts without a project: the sample projects
(with their descriptions), the recent files, and Open…"""
from __future__ import annotations

import json
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QDialog, QDialogButtonBox, QLabel, QListWidget, QListWidgetItem,
                               QPushButton, QVBoxLayout)

from workbench.gui.document import sample_projects


def _description(path: Path) -> str:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return ""
    return str(doc.get("description", "")) if isinstance(doc, dict) else ""


class WelcomeDialog(QDialog):
    """Pick a sample or a recent project; `choice` is the sample name or file path (None: cancelled)."""

    def __init__(self, recent_files: list[str], parent=None):
        super().__init__(parent)
        self.setWindowTitle("Welcome to Camera Workbench")
        self.choice: str | None = None
        layout = QVBoxLayout(self)
        layout.addWidget(QLabel("<b>Start from a sample project</b> — every sample runs headless too "
                                "(<code>workbench simulate NAME</code>)."))
        self.samples = QListWidget()
        for name, path in sample_projects().items():
            item = QListWidgetItem(name)
            item.setToolTip(_description(path))
            item.setData(Qt.ItemDataRole.UserRole, name)
            self.samples.addItem(item)
        self.samples.itemDoubleClicked.connect(self._pick)
        layout.addWidget(self.samples)
        self.recent = QListWidget()
        for f in recent_files:
            item = QListWidgetItem(f)
            item.setData(Qt.ItemDataRole.UserRole, f)
            self.recent.addItem(item)
        self.recent.itemDoubleClicked.connect(self._pick)
        if recent_files:
            layout.addWidget(QLabel("<b>Recent projects</b>"))
            layout.addWidget(self.recent)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Cancel)
        self.open_button = QPushButton("Open selected")
        buttons.addButton(self.open_button, QDialogButtonBox.ButtonRole.AcceptRole)
        self.open_button.clicked.connect(self._open_selected)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)
        if self.samples.count():
            self.samples.setCurrentRow(0)

    def _pick(self, item: QListWidgetItem) -> None:
        self.choice = item.data(Qt.ItemDataRole.UserRole)
        self.accept()

    def _open_selected(self) -> None:
        item = self.recent.currentItem() if self.recent.hasFocus() else self.samples.currentItem()
        if item is not None:
            self._pick(item)
