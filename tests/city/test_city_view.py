"""The 3-D view draws the city on an off-screen pyvista plotter (Mesa EGL)."""
import numpy as np
import pytest

from workbench.scene.city import CityRecipe, PoseParams, generate_city, sample_camera_poses
from workbench.scene.city.view import add_city_to_plotter

pv = pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def small_city():
    return generate_city(CityRecipe(blocks_x=1, blocks_y=1, seed=1, n_cars=4, n_pedestrians=4,
                                    n_trees=4, n_lamps=2, n_benches=1, n_mailboxes=1, n_buses=1))


def _shot(city, pose=None, set_view=False):
    p = pv.Plotter(off_screen=True, window_size=(320, 240))
    try:
        actors = add_city_to_plotter(p, city, pose, set_view=set_view)
        if not set_view:
            p.camera_position = [(-60, -60, 80), (60, 60, 0), (0, 0, 1)]
        img = p.screenshot(return_img=True)
    finally:
        p.close()
    return actors, img


def test_overview_is_not_blank(small_city):
    actors, img = _shot(small_city)
    assert set(actors) == {"city"}
    colours = np.unique(img.reshape(-1, img.shape[-1]), axis=0)
    background = np.all(img == img[0, 0], axis=-1).mean()
    assert len(colours) > 20 and background < 0.7


def test_view_through_pose(small_city):
    pose = sample_camera_poses(small_city, PoseParams(), 1, seed=2)[0]
    actors, img = _shot(small_city, pose)
    assert "camera" in actors
    _, img2 = _shot(small_city, pose, set_view=True)
    assert len(np.unique(img2.reshape(-1, img2.shape[-1]), axis=0)) > 20
    # the lower half looks at the road, the upper half mostly at sky or buildings
    assert not np.array_equal(img2[:120], img2[120:])


def test_colour_by_class_is_a_switch_of_the_same_mesh(small_city):
    """Both colourings live on the one city mesh: switching shows each class's colour where its
    cells are, with no new actor."""
    from workbench.scene.city.view import CLASS_COLOURS, city_polydata, set_city_colouring
    mesh = city_polydata(small_city)
    n_faces = sum(len(m.faces) for o in small_city.objects for m in o.meshes)
    assert mesh.n_cells == n_faces
    car = np.round(255 * np.asarray(CLASS_COLOURS["car"])).astype(np.uint8)
    assert (mesh.cell_data["class_rgb"] == car).all(axis=1).any()
    p = pv.Plotter(off_screen=True, window_size=(320, 240))
    try:
        actors = add_city_to_plotter(p, mesh=mesh)
        p.camera_position = [(-60, -60, 80), (60, 60, 0), (0, 0, 1)]
        material = p.screenshot(return_img=True)
        set_city_colouring(actors["city"], "class")
        p.render()
        by_class = p.screenshot(return_img=True)
        assert len(p.renderer.actors) == 1
    finally:
        p.close()
    assert not np.array_equal(material, by_class)
    road = np.round(255 * np.asarray(CLASS_COLOURS["road"])).astype(int)
    assert (np.abs(by_class[..., :3].astype(int) - road).max(axis=-1) < 40).mean() > 0.02     # the grey road
