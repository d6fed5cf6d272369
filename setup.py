"""Build step only (metadata is in pyproject.toml): ship resources/ inside the package.

The data tree stays at the top of the repository (resources/); a wheel carries it as package data
in workbench/_resources/, where workbench.resource_dir finds it when there is no source tree.
"""
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithResources(build_py):
    def run(self):
        super().run()
        source = Path(__file__).resolve().parent / "resources"
        target = Path(self.build_lib) / "workbench" / "_resources"
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


setup(cmdclass={"build_py": BuildPyWithResources})
