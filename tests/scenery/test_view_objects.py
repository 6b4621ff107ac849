"""A single view's objects over a plain backdrop: seeded at the smoke's depth as bodies round in plan
(fluidnexus/scenery/view_objects.py), so a camera turned about them sees them in their place."""
import numpy as np
import pytest

from fluidnexus.camera import Camera

from .static_scenes import BALL_CENTER, BALL_RADIUS, HI, LO, ball_mask, camera, render

WHITE = np.float32(1.0)
# a camera 90 degrees round from the input sees the ball in its place: measured 13.9 dB on its pixels and a ring of
# four around them (48 px, 60 iterations, float32), against 9.1 dB for the white that a layer placing nothing shows
TURNED_GAIN_DB = 3.0


def _plate(cam):
    return np.where(ball_mask(cam)[..., None], render(cam), WHITE).astype(np.float32)


def test_a_patch_becomes_a_body_round_in_plan():
    """A disk of object pixels seeded about an anchor: the seeds fill the ball of the disk's radius around the
    anchor (each within a pixel's footprint of it, reaching its front and back), in the pixels' colour; a budget
    thins them, a speck is noise, and an anchor behind the camera seeds nothing."""
    from fluidnexus.scenery.view_objects import object_seeds

    cam = Camera.look_at(40, 40, 44.0, (0.0, 0.5, 3.0), (0.0, 0.5, 0.0))
    rows, cols = np.mgrid[0:40, 0:40]
    disk = (cols + 0.5 - 20) ** 2 + (rows + 0.5 - 20) ** 2 <= 8 ** 2
    plate = np.where(disk[..., None], np.float32([0.2, 0.5, 0.9]), WHITE)
    anchor, sure, white = np.array([0.0, 0.5, 0.0]), np.ones((40, 40)), np.ones(3)
    points, colors, spacing = object_seeds(cam, plate, sure, white, anchor, 0.03, budget=10000)
    metres_per_px = 3.0 / 44.0
    radius = 8 * metres_per_px
    assert np.linalg.norm(points - anchor, axis=1).max() <= radius + metres_per_px
    assert points[:, 2].max() > radius - 2 * metres_per_px and points[:, 2].min() < -radius + 2 * metres_per_px
    assert len(points) > 0.6 * (4 / 3 * np.pi * 8 ** 3)  # filled: about one seed per pixel-sized cube of the ball
    np.testing.assert_allclose(colors, np.tile([0.2, 0.5, 0.9], (len(colors), 1)))
    np.testing.assert_allclose(spacing, metres_per_px)
    few = object_seeds(cam, plate, sure, white, anchor, 0.03, budget=100)[0]
    assert 0 < len(few) <= 100
    speck = np.where(((cols == 5) & (rows == 5))[..., None], np.float32(0.0), WHITE)
    assert len(object_seeds(cam, speck, sure, white, anchor, 0.03, budget=100)[0]) == 0
    assert len(object_seeds(cam, plate, sure, white, np.array([0.0, 0.5, 4.0]), 0.03, budget=100)[0]) == 0


def test_one_view_places_its_object_at_the_anchor(ti_engine):
    """One view of a ball over white, the anchor at the ball's centre: a camera 90 degrees round sees the ball in
    its place, far better than the white a layer placing nothing shows (without an anchor:
    test_static_layer.py, test_one_view_over_a_plain_backdrop_places_nothing)."""
    from fluidnexus.metrics import psnr
    from fluidnexus.scenery.static_layer import StaticConfig, fit_static, render_static

    cam, turned = camera(0, size=48), camera(90, size=48)
    plate, truth = _plate(cam), _plate(turned)
    sure = [np.ones(plate.shape[:2], np.float32)]
    layer = fit_static([cam], [plate], sure, LO, HI, StaticConfig(iterations=60), backdrop=(1.0, 1.0, 1.0),
                       anchor=BALL_CENTER)
    assert len(layer) > 0 and np.allclose(layer.info["objects_at"], BALL_CENTER, atol=1e-6)
    assert np.linalg.norm(layer.means - BALL_CENTER, axis=1).max() < 2.0 * BALL_RADIUS
    near = np.zeros(truth.shape[:2], bool)  # the ball's pixels in the turned view and a ring of four around them
    rows, cols = np.nonzero(ball_mask(turned))
    near[max(rows.min() - 4, 0):rows.max() + 5, max(cols.min() - 4, 0):cols.max() + 5] = True
    image = render_static(layer, turned)[0].numpy()
    white = np.ones_like(truth)
    assert psnr(image[near][None], truth[near][None]) >= psnr(white[near][None], truth[near][None]) + TURNED_GAIN_DB
    assert psnr(render_static(layer, cam)[0].numpy(), plate) >= 28.0


def test_the_anchor_is_the_declared_source_else_synths_foot():
    """Where recon puts a single view's objects: the declared source's centre wins; else the plume's foot that
    synth recorded in a novel view's provenance; else nowhere."""
    from types import SimpleNamespace

    from fluidnexus.scene import Source
    from fluidnexus.scenery.world import view_anchor

    foot = SimpleNamespace(provenance={"synth": {"plume_foot": {"center": [0.1, 0.0, 0.2]}}})
    plain = SimpleNamespace(provenance=None)
    declared = Source((0.3, 0.1, -0.2), 0.05)
    assert np.allclose(view_anchor(SimpleNamespace(source=declared, views=[plain, foot])), [0.3, 0.1, -0.2])
    assert np.allclose(view_anchor(SimpleNamespace(source=None, views=[plain, foot])), [0.1, 0.0, 0.2])
    assert view_anchor(SimpleNamespace(source=None, views=[plain])) is None


def test_a_patch_stands_for_a_ball_in_the_flow():
    """The ball a patch stands for: centred on its axis at the anchor's depth, as large as the patch's area says;
    as a found obstacle it is a sphere-like solid whose signed distance is the ball's."""
    from fluidnexus.engine.obstacle import SphereObstacle
    from fluidnexus.scenery.found_obstacles import SOLID, ball_obstacle
    from fluidnexus.scenery.view_objects import object_balls

    cam = Camera.look_at(40, 40, 44.0, (0.0, 0.5, 3.0), (0.0, 0.5, 0.0))
    rows, cols = np.mgrid[0:40, 0:40]
    disk = (cols + 0.5 - 20) ** 2 + (rows + 0.5 - 20) ** 2 <= 8 ** 2
    small = (np.abs(cols + 0.5 - 33) <= 2) & (np.abs(rows + 0.5 - 8) <= 2)
    plate = np.where((disk | small)[..., None], np.float32([0.2, 0.5, 0.9]), WHITE)
    anchor = np.array([0.1, 0.3, 0.0])  # only its depth matters
    balls = object_balls(cam, plate, np.ones((40, 40)), np.ones(3), anchor, 0.03)
    metres_per_px = 3.0 / 44.0
    assert len(balls) == 2 and balls[0][1] > balls[1][1]
    (center, radius), _ = balls
    np.testing.assert_allclose(center, [0.0, 0.5, 0.0], atol=0.5 * metres_per_px)
    assert abs(radius - 8 * metres_per_px) <= 0.3 * metres_per_px
    body = ball_obstacle(center, radius, (-1.0, 0.0, -1.0), (1.0, 1.0, 1.0))
    assert body.kind == SOLID and body.sphere_like() and isinstance(body.engine_body(), SphereObstacle)
    np.testing.assert_allclose(np.linalg.norm(body.points - center, axis=1), radius)
    index = np.round((center - np.asarray(body.origin)) / body.spacing).astype(int)
    assert body.phi[tuple(index)] == pytest.approx(-radius, abs=body.spacing)
    assert body.phi.max() > 0 and body.volume == pytest.approx(4 / 3 * np.pi * radius ** 3)
