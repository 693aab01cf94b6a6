"""tools/objects.py's twin render: the image without the objects, and the physics as if it had not been made."""
import numpy as np

import objects
import scene
import sim

STEPS = 6


def test_the_mirror_renders_the_scene_as_if_the_objects_were_gone():
    w = scene.World("peg")
    _, x_i = w.place(objects.issue_scene(np.random.default_rng(3)))
    w.move_to(x_i)
    mirror, full = objects.Mirror(w), (0, 0, scene.CAM_FULL, scene.CAM_FULL)
    state = w.noise_rng.bit_generator.state
    seen = w.render_roi(full, 200)
    w.noise_rng.bit_generator.state = state
    unseen = mirror.render_roi(full, 200)
    w.noise_rng.bit_generator.state = state
    objects.send_away(w)
    gone = w.render_roi(full, 200)
    assert (seen != gone).sum() > 100                          # the objects are in this view
    np.testing.assert_array_equal(unseen, gone)                # with the same noise, to the bit
    mirror.close()


def episode(twin, monkeypatch):
    """A short episode of the hand-designed policy among an issue scene's blocks: its rewards and last pose."""
    monkeypatch.setattr(sim, "MAX_STEPS", STEPS)
    env = sim.AssemblyEnv("peg", e_r=0.02)
    env._episode_context = lambda: objects.issue_scene(np.random.default_rng(3))
    last = {}
    mirror = objects.twin_renders(env, False, last) if twin else None
    obs, _ = env.reset(seed=7)
    rewards, images = [], [obs["image"]]
    for _ in range(STEPS):
        obs, r, term, trunc, info = env.step(np.zeros(6))
        rewards.append(r)
        images.append(obs["image"])
        if term or trunc:
            break
    pose = env.world.tool_pose()[0]
    env.close()
    if mirror:
        mirror.close()
    return rewards, np.array(images), pose, last


def test_an_episode_with_the_twin_render_is_the_plain_one_to_the_bit(monkeypatch):
    plain, twin = episode(False, monkeypatch), episode(True, monkeypatch)
    assert plain[0] == twin[0] and np.array_equal(plain[1], twin[1]) and np.array_equal(plain[2], twin[2])
    assert not np.array_equal(twin[3]["seen"], twin[3]["blind"])      # the blind image did lose the blocks
