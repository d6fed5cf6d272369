"""The Qt application (PySide6, pyvistaqt, pyqtgraph, superqt): the only package that imports Qt.

Every computation stays in the core; this package shows it and turns user actions into project
edits. Entry point: workbench.gui.app.main (`workbench gui [PROJECT]`)."""
