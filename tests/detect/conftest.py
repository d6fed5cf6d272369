"""A small synthetic data set shared by the detection tests (rendered once per session)."""
import pytest


@pytest.fixture(scope="session")
def synthetic_dir(tmp_path_factory):
    from workbench.detect.synthetic import make_synthetic_dataset
    folder = tmp_path_factory.mktemp("synthetic_set")
    make_synthetic_dataset(folder, frames=14)
    return folder


@pytest.fixture
def copy(synthetic_dir, tmp_path):
    """A copy of the synthetic set to damage."""
    import shutil
    dst = tmp_path / "set"
    shutil.copytree(synthetic_dir, dst)
    return dst
