"""code_version: '-dirty' follows the code, not the results folders a running experiment rewrites."""
import subprocess

from workbench.datasets.dataset import code_version


def _git(root, *args):
    subprocess.run(["git", *args], cwd=root, check=True, capture_output=True)


def test_dirty_only_when_code_changes(tmp_path):
    (tmp_path / "workbench").mkdir()
    (tmp_path / "docs").mkdir()
    (tmp_path / "workbench" / "m.py").write_text("x = 1\n")
    (tmp_path / "docs" / "results.json").write_text("{}\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "start")
    clean = code_version(tmp_path)
    assert "+git." in clean and not clean.endswith("-dirty")
    (tmp_path / "docs" / "results.json").write_text('{"runs": []}\n')      # a running experiment's write
    assert code_version(tmp_path) == clean
    (tmp_path / "workbench" / "m.py").write_text("x = 2\n")
    assert code_version(tmp_path) == clean + "-dirty"
