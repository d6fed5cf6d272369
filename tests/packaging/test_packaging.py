"""The installable application: wheel with its data, entry points, version, desktop integration."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import workbench

ROOT = Path(__file__).resolve().parents[2]


def _run(cmd, **kw):
    kw.setdefault("env", CLEAN_ENV)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, **kw)


# Without PYTHONPATH, so nothing of this checkout leaks into the fresh environment.
CLEAN_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


@pytest.mark.slow
def test_wheel_installs_and_runs_outside_the_source_tree(tmp_path):
    """Build the wheel, install it into a fresh venv outside the checkout, run two commands there.

    The fresh venv borrows the third-party packages of the running interpreter through a .pth
    path line (not a site dir, so this checkout's editable-install hook is not loaded): the
    workbench itself and its data come from the wheel alone."""
    dist = tmp_path / "dist"
    built = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                  "-w", str(dist), str(ROOT)])
    assert built.returncode == 0, built.stderr[-2000:]
    wheel = next(dist.glob("camera_workbench-*.whl"))
    venv = tmp_path / "venv"
    assert _run([sys.executable, "-m", "venv", "--without-pip", str(venv)]).returncode == 0
    vpy = venv / "bin" / "python"
    site = Path(_run([str(vpy), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    installed = _run([sys.executable, "-m", "pip", "--python", str(vpy), "install", "--no-deps",
                      "--no-index", str(wheel)])
    assert installed.returncode == 0, installed.stderr[-2000:]
    # After the install, so pip does not see this checkout's editable install as "already there".
    (site / "zz_borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")

    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {**CLEAN_ENV, "WORKBENCH_LOG_DIR": str(tmp_path / "logs")}
    where = _run([str(vpy), "-c", "import workbench, workbench.resource_dir as r; "
                  "print(workbench.__file__); print(r.RESOURCES)"], cwd=work, env=env)
    assert where.returncode == 0, where.stderr
    module_file, resources = where.stdout.split()
    assert str(ROOT) not in module_file and str(ROOT) not in resources
    assert resources.endswith(os.path.join("workbench", "_resources"))

    exe = venv / "bin" / "workbench"
    version = _run([str(exe), "--version"], cwd=work, env=env)
    assert version.stdout.strip() == f"workbench {workbench.__version__}"
    sim = _run([str(exe), "simulate", "paper_camera", "--out", str(work / "out")], cwd=work, env=env)
    assert sim.returncode == 0, sim.stderr[-2000:]
    assert (work / "out" / "report.json").is_file()
    lens = _run([str(exe), "lens", "info", "dgauss.50mm"], cwd=work, env=env)
    assert lens.returncode == 0, lens.stderr[-2000:]
    assert "50.3" in lens.stdout            # EFL 50.358 mm of the shipped double Gauss


def test_sdist_manifest_ships_the_data_tree():
    manifest = (ROOT / "MANIFEST.in").read_text()
    assert "graft resources" in manifest


@pytest.mark.skipif(shutil.which("desktop-file-validate") is None,
                    reason="desktop-file-validate (Debian's desktop-file-utils) is not installed")
def test_desktop_entry_is_valid():
    result = _run(["desktop-file-validate", str(ROOT / "packaging" / "desktop" / "camera-workbench.desktop")])
    assert result.returncode == 0 and result.stdout.strip() == "", result.stdout + result.stderr


@pytest.mark.skipif(shutil.which("update-mime-database") is None, reason="shared-mime-info is not installed")
def test_desktop_install_registers_the_project_file_type(tmp_path):
    env = {**CLEAN_ENV, "XDG_DATA_HOME": str(tmp_path / "share"), "HOME": str(tmp_path)}
    result = _run(["bash", str(ROOT / "packaging" / "install-desktop.sh")], env=env)
    assert result.returncode == 0, result.stderr
    share = tmp_path / "share"
    assert (share / "applications" / "camera-workbench.desktop").is_file()
    assert (share / "icons" / "hicolor" / "scalable" / "apps" / "camera-workbench.svg").is_file()
    assert "*.cwproj" in (share / "mime" / "globs2").read_text()
    assert (share / "mime" / "application" / "x-camera-workbench-project.xml").is_file()


def test_log_file_is_written_where_asked(tmp_path):
    result = _run([sys.executable, "-m", "workbench.cli", "lens", "info", "dgauss.50mm"],
                  env={**os.environ, "WORKBENCH_LOG_DIR": str(tmp_path / "logs")})
    assert result.returncode == 0, result.stderr
    assert "lens info dgauss.50mm" in (tmp_path / "logs" / "workbench.log").read_text()


def test_project_file_type_extension_round_trips(tmp_path):
    from workbench.project import load_project, save_project
    project = load_project("paper_camera")
    path = tmp_path / "camera.cwproj"
    save_project(project, path)
    assert load_project(path) == project
    assert "camera-workbench-project" in path.read_text()[:256]      # the MIME magic's match
