"""Families of contexts (scene.family_context): scenes drawn from seeds, each family varying one thing the
camera sees; held-out seeds apart from training's; parts beyond the tool's reach, some inside the task ROI
at large errors; places clear of the workcell; the hand-designed policy still inserts in them."""
import numpy as np
import pytest

import scene
import sim

SEEDS = range(40)


@pytest.mark.parametrize("family", scene.FAMILIES)
def test_a_seed_is_one_scene_and_seeds_differ(family):
    scenes = [scene.family_context(family, s) for s in SEEDS]
    assert scenes[0] == scene.family_context(family, 0) and scene.context_of(f"{family}:0") == scenes[0]
    assert len({repr(c) for c in scenes}) == len(scenes)
    assert all("np." not in repr(c) for c in scenes)              # plain floats: a context's repr is a cache key
    field = {"place": "board_xy", "light": "light", "colour": "table_rgba", "parts": "objects"}
    changed = {k for c in scenes for k in field.values() if getattr(c, k) != getattr(scene.CONTEXTS["train"], k)}
    assert changed == (set(field.values()) if family == "mixed" else {field[family]})    # one kind, or all together


def test_held_out_scenes_and_training_scenes_never_meet(monkeypatch):
    seen, real = {}, scene.family_context
    with sim.AssemblyEnv("peg", "light:test", image=False) as held_out, \
            sim.AssemblyEnv("peg", randomize=("light", "colour"), image=False) as randomized:
        for env, kind in ((held_out, "test"), (randomized, "train")):
            monkeypatch.setattr(sim, "family_context", lambda family, seed, task, drawn=seen.setdefault(kind, []):
                                drawn.append((family, seed)) or real(family, seed, task))
            for ep in range(6):
                env.scene_rng = np.random.default_rng([ep, 1])       # as reset(seed=ep) seeds it
                env._episode_context()
    assert all(f == "light" and s >= scene.FAMILY_TEST_SEED0 for f, s in seen["test"])
    assert all(f in ("light", "colour") and s < scene.FAMILY_TEST_SEED0 for f, s in seen["train"])
    assert len(set(seen["test"])) == 6 and len({f for f, _ in seen["train"]}) == 2


@pytest.mark.parametrize("task", ["peg", "gear"])
def test_parts_lie_on_the_board_beyond_the_tools_reach_and_some_inside_the_task_roi(task):
    with sim.AssemblyEnv(task, image=False) as env:
        env.reset(seed=0, options={"error": np.zeros(4)})
        w, R_b = env.world, env.x_g[1] @ sim.R_DOWN
        board = (env.x_g[0] - R_b @ w.goal_in_board(), R_b)
        u0, v0, u1, v1 = env.roi
        inside = 0
        for s in SEEDS:
            for he, xy, _ in scene.family_context("parts", s, task).objects:
                r = np.hypot(*he[:2])
                assert np.all(np.abs(xy) <= scene.BOARD_HALF - r + 1e-9)                       # whole on the board
                assert np.hypot(*xy) >= (scene.BUMP_R_MAX if task == "peg" else scene.GEAR_R_TIP) + r
                if task == "gear":
                    assert np.hypot(xy[0] - scene.GEAR_CENTRES, xy[1]) >= scene.GEAR_R_TIP + r
                # the part's centre seen with the tool 20 mm off toward it in x and y (Eq. 13's largest error)
                e = np.clip(np.asarray(xy), -sim.E_R_FINAL, sim.E_R_FINAL)
                cam_p = env.x_i[0] + R_b @ np.array([*e, 0.0]) + env.x_i[1] @ w.cam_rel[0]
                uv = scene.project((board[0] + R_b @ np.array([*xy, 0.0]))[None], w.camera_matrices(
                    (cam_p, env.x_i[1] @ w.cam_rel[1])), scene.full_projection())[0]
                inside += u0 <= uv[0] <= u1 and v0 <= uv[1] <= v1
        assert 5 <= inside, inside


def test_other_places_stand_clear_of_the_workcell_within_reach_of_the_arm():
    t = np.array(scene.CONTEXTS["train"].board_xy)
    for s in SEEDS:
        c = scene.family_context("place", s)
        assert scene.PLACE_RING[0] <= np.linalg.norm(np.subtract(c.board_xy, t)) <= scene.PLACE_RING[1]
        assert abs(c.board_yaw) <= scene.PLACE_YAW
        corners = np.array(c.board_xy) + np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]]) * scene.BOARD_HALF @ \
            sim.ctl.rot_z(c.board_yaw)[:2, :2].T
        for he, centre, _ in scene.WORKCELL:
            assert not np.any(np.all(np.abs(corners - centre[:2]) < np.array(he[:2]), 1))


def test_lights_and_colours_within_their_ranges():
    for s in SEEDS:
        light = dict(scene.family_context("light", s).light)
        el = np.degrees(np.arcsin(light["lightDirection"][2] / np.linalg.norm(light["lightDirection"])))
        assert 34.9 <= el <= 85.1 and all(0.3 <= c <= 1.0 for c in light["lightColor"])
        assert scene.LIGHT_AMBIENT[0] <= light["lightAmbientCoeff"] <= scene.LIGHT_AMBIENT[1]
        c = scene.family_context("colour", s)
        assert scene.TABLE_VALUE[0] - 1e-3 <= max(c.table_rgba[:3]) <= scene.TABLE_VALUE[1] + 1e-3
        assert scene.BOARD_VALUE[0] - 1e-3 <= max(c.board_rgba[:3]) <= scene.BOARD_VALUE[1] + 1e-3


def test_the_hand_designed_policy_inserts_in_a_held_out_mixed_scene():
    with sim.AssemblyEnv("peg", "mixed:test") as env:
        success, info, _ = sim.run_episode(env, lambda obs: np.zeros(6), seed=3)
        assert success and env.world.context.objects and env.world.context.light
