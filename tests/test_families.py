"""Families of contexts (contexts.family_context): scenes drawn from seeds, each family varying one thing the
camera sees; held-out seeds apart from training's; parts beyond the tool's reach, some inside the task ROI
at large errors; places clear of the workcell; the hand-designed policy still inserts in them."""
import numpy as np
import pytest

import contexts
import scene
import sim

SEEDS = range(40)


@pytest.mark.parametrize("family", contexts.FAMILIES)
def test_a_seed_is_one_scene_and_seeds_differ(family):
    scenes = [contexts.family_context(family, s) for s in SEEDS]
    assert scenes[0] == contexts.family_context(family, 0) and contexts.context_of(f"{family}:0") == scenes[0]
    keys = [contexts.context_key(f"{family}:{s}") for s in SEEDS]
    assert len(set(keys)) == len(scenes) and all("np." not in k for k in keys)     # plain floats: a cache's key
    field = {"place": "board_xy", "light": "light", "colour": "table_rgba", "parts": "objects", "objects": "objects",
             "touch": "friction", "reach": "objects", "calib": "camera"}
    changed = {k for c in scenes for k in field.values() if getattr(c, k) != getattr(contexts.CONTEXTS["train"], k)}
    mixed = {field[f] for f in contexts.MIXED}
    assert changed == (mixed if family == "mixed" else {field[family]})    # one kind, or mixed's together


def test_held_out_scenes_and_training_scenes_never_meet(monkeypatch):
    seen, real = {}, contexts.family_context
    with sim.AssemblyEnv("peg", "light:test", image=False) as held_out, \
            sim.AssemblyEnv("peg", randomize=("light", "colour"), image=False) as randomized:
        for env, kind in ((held_out, "test"), (randomized, "train")):
            monkeypatch.setattr(sim, "family_context", lambda family, seed, task, drawn=seen.setdefault(kind, []):
                                drawn.append((family, seed)) or real(family, seed, task))
            for ep in range(6):
                env.scene_rng = np.random.default_rng([ep, 1])       # as reset(seed=ep) seeds it
                env._episode_context()
    assert all(f == "light" and s >= contexts.FAMILY_TEST_SEED0 for f, s in seen["test"])
    assert all(f in ("light", "colour") and s < contexts.FAMILY_TEST_SEED0 for f, s in seen["train"])
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
            for he, xy, _ in contexts.family_context("parts", s, task).objects:
                r = np.hypot(*he[:2])
                assert np.all(np.abs(xy) <= contexts.BOARD_HALF - r + 1e-9)                       # whole on the board
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


def _hits_box(a, b, centre, he):
    """Whether the segment a -> b passes through the box (centre, half extents he), all in one frame (slab test)."""
    d, lo, hi = b - a, 0.0, 1.0
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if abs(a[k] - centre[k]) > he[k]:
                return False
            continue
        t0, t1 = sorted(((centre[k] - he[k] - a[k]) / d[k], (centre[k] + he[k] - a[k]) / d[k]))
        lo, hi = max(lo, t0), min(hi, t1)
    return lo <= hi


@pytest.mark.parametrize("task", ["peg", "gear"])
def test_workbench_objects_stand_on_the_board_beyond_reach_some_in_the_roi_some_hiding_the_board(task):
    with sim.AssemblyEnv(task, image=False) as env:
        env.reset(seed=0, options={"error": np.zeros(4)})
        w, R_b = env.world, env.x_g[1] @ sim.R_DOWN
        top = env.x_g[0] - R_b @ w.goal_in_board()                              # the board's top at the axis
        u0, v0, u1, v1 = env.roi
        errors = [np.array([sx, sy]) * sim.E_R_FINAL for sx in (-1, 0, 1) for sy in (-1, 0, 1)]
        cams = [R_b.T @ (env.x_i[0] + R_b @ np.array([*e, dz]) + env.x_i[1] @ w.cam_rel[0] - top)
                for e in errors for dz in (0.0, -scene.APPROACH)]          # at X_i, and the tip down on the part
        board = [np.array([r * np.cos(a), r * np.sin(a), 0.0]) for r in (0.0, 0.01, 0.02, 0.03, 0.04)
                 for a in np.arange(8) * np.pi / 4]
        inside = hiding = 0
        for s in SEEDS:
            objects = contexts.family_context("objects", s, task).objects
            assert contexts.OBJECTS_PER_SCENE[0] <= len(objects) <= contexts.OBJECTS_PER_SCENE[1]
            for i, (he, xy, _) in enumerate(objects):
                he, xy = np.array(he), np.array(xy)
                lo, hi = contexts.OBJECT_SIDE
                assert np.all((lo - 1e-4 <= 2 * he[:2]) & (2 * he[:2] <= hi + 1e-4))
                assert contexts.OBJECT_TALL[0] - 1e-4 <= 2 * he[2] <= contexts.OBJECT_TALL[1] + 1e-4
                # whole on the board
                assert np.all(np.abs(xy) + he[:2] <= contexts.BOARD_HALF + 1e-4)
                near = np.hypot(*np.maximum(np.abs(xy) - he[:2], 0))
                reach = scene.BUMP_R_MAX if task == "peg" else (
                    scene.GEAR_R_TIP + sim.E_R_FINAL * np.sqrt(2) if 2 * he[2] > scene.SHAFT_HEIGHT - 0.002
                    else scene.GEAR_R_TIP)
                assert contexts.OBJECT_RING[0] - 1e-4 <= near <= contexts.OBJECT_RING[1] + 1e-4 and near >= reach
                if task == "gear":
                    assert np.hypot(*np.maximum(np.abs(xy - (scene.GEAR_CENTRES, 0)) - he[:2], 0)) >= scene.GEAR_R_TIP
                assert not any(np.all(np.abs(xy - o[1]) < he[:2] + o[0][:2]) for o in objects[:i])   # no overlaps
                e = np.clip(xy, -sim.E_R_FINAL, sim.E_R_FINAL)          # its top seen with the tool 20 mm off toward it
                cam_p = env.x_i[0] + R_b @ np.array([*e, 0.0]) + env.x_i[1] @ w.cam_rel[0]
                uv = scene.project((top + R_b @ np.array([*xy, 2 * he[2]]))[None], w.camera_matrices(
                    (cam_p, env.x_i[1] @ w.cam_rel[1])), scene.full_projection())[0]
                inside += u0 <= uv[0] <= u1 and v0 <= uv[1] <= v1
            # some stand between the camera and the board within 4 cm of the axis, at some error and height
            hiding += any(_hits_box(c, b, np.array([*xy, he[2]]), np.array(he))
                          for c in cams for b in board for he, xy, _ in objects)
        assert inside >= 5 and hiding >= 3, (inside, hiding)


def test_other_places_stand_clear_of_the_workcell_within_reach_of_the_arm():
    t = np.array(contexts.CONTEXTS["train"].board_xy)
    for s in SEEDS:
        c = contexts.family_context("place", s)
        assert contexts.PLACE_RING[0] <= np.linalg.norm(np.subtract(c.board_xy, t)) <= contexts.PLACE_RING[1]
        assert abs(c.board_yaw) <= contexts.PLACE_YAW
        corners = np.array(c.board_xy) + np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]]) * contexts.BOARD_HALF @ \
            sim.ctl.rot_z(c.board_yaw)[:2, :2].T
        for he, centre, _ in scene.WORKCELL:
            assert not np.any(np.all(np.abs(corners - centre[:2]) < np.array(he[:2]), 1))


def test_lights_and_colours_within_their_ranges():
    for s in SEEDS:
        light = dict(contexts.family_context("light", s).light)
        el = np.degrees(np.arcsin(light["lightDirection"][2] / np.linalg.norm(light["lightDirection"])))
        assert 34.9 <= el <= 85.1 and all(0.3 <= c <= 1.0 for c in light["lightColor"])
        assert contexts.LIGHT_AMBIENT[0] <= light["lightAmbientCoeff"] <= contexts.LIGHT_AMBIENT[1]
        c = contexts.family_context("colour", s)
        assert contexts.TABLE_VALUE[0] - 1e-3 <= max(c.table_rgba[:3]) <= contexts.TABLE_VALUE[1] + 1e-3
        assert contexts.BOARD_VALUE[0] - 1e-3 <= max(c.board_rgba[:3]) <= contexts.BOARD_VALUE[1] + 1e-3


def test_the_hand_designed_policy_inserts_in_a_held_out_mixed_scene():
    with sim.AssemblyEnv("peg", "mixed:test") as env:
        success, info, _ = sim.run_episode(env, lambda obs: np.zeros(6), seed=3)
        assert success and env.world.context.objects and env.world.context.light


def test_touch_scenes_within_their_ranges_and_the_world_made_of_them():
    for s in SEEDS:
        c = contexts.family_context("touch", s)
        assert contexts.TOUCH_FRICTION[0] <= c.friction <= contexts.TOUCH_FRICTION[1]
        assert contexts.TOUCH_CLEARANCE[0] <= c.clearance <= contexts.TOUCH_CLEARANCE[1]
        assert np.hypot(*c.tilt) <= contexts.TOUCH_TILT + 1e-5
        assert c.board_xy == contexts.CONTEXTS["train"].board_xy and not c.objects   # it changes only what is touched
    assert contexts.context_key("touch:3") != contexts.context_key("train")
    with sim.AssemblyEnv("gear", "touch:test", image=False) as env:      # each episode's own bore and friction
        seen = set()
        for seed in range(2):
            env.reset(seed=seed)
            w, c = env.world, env.world.context
            assert c.friction is not None and w.clearance == c.clearance
            assert w.bc.getDynamicsInfo(w.plate[0], -1)[1] == pytest.approx(c.friction / scene.TOOL_FRICTION)
            seen.add(c.clearance)
        assert len(seen) == 2


def test_the_touch_familys_friction_clearance_and_tilt_are_what_the_part_meets():
    import instruments
    for mu in (0.15, 0.6):               # the training world's pair (0.15, measured), and a dry one
        ctx = scene.Context(friction=mu) if mu != 0.15 else contexts.CONTEXTS["train"]
        assert instruments.sliding_friction(ctx) == pytest.approx(mu, rel=0.05)
    play = instruments.lateral_play("peg", 1e-4, [0.0], directions=4, context=scene.Context(clearance=0.25e-3))
    assert np.all(np.abs(play - 0.25e-3) < 0.02e-3), play
    t = np.radians(1.0)
    w = scene.World("peg", context=scene.Context(tilt=(t, 0.0)))
    (p_g, _), (p_i, _) = w.place(w.context)
    ring = w.bc.getBasePositionAndOrientation(w.parts[0][0])[1]
    w.close()
    # the hole's bottom lies off the vertical through its top by its depth x sin(t), toward +y for a tilt about +x
    np.testing.assert_allclose(p_g[:2] - p_i[:2], [0.0, scene.HOLE_DEPTH * np.sin(t)], atol=1e-9)
    np.testing.assert_allclose(scene.matrix_from_quat(ring), sim.ctl.rotvec_to_matrix(np.array([t, 0, 0])), atol=1e-9)


@pytest.mark.parametrize("task", ["peg", "gear"])
def test_what_the_tool_can_touch_lies_within_its_reach_clear_of_the_hole_and_of_each_other(task):
    r0, r1 = contexts.reach_ring(task)
    blocks = 0
    for s in SEEDS:
        objects = contexts.family_context("reach", s, task).objects
        low = [o for o in objects if o[0][2] <= 0.0025 + 1e-9]            # wires, ties, cables, washers, shims
        assert contexts.REACH_PER_SCENE[0] <= len(low) <= contexts.REACH_PER_SCENE[1]
        for i, (he, xy, _) in enumerate(objects):
            he, xy = np.array(he), np.array(xy)
            assert np.all(np.abs(xy) + he[:2] <= contexts.BOARD_HALF + 1e-4)                    # whole on the board
            near = np.hypot(*np.maximum(np.abs(xy) - he[:2], 0))
            tall = he[2] > 0.0025 + 1e-9
            assert (near >= contexts.tool_reach(task, 2 * he[2])) if tall else (r0 - 1e-4 <= near <= r1 + 1e-4)
            if task == "gear":
                assert np.hypot(*np.maximum(np.abs(xy - (scene.GEAR_CENTRES, 0)) - he[:2], 0)) >= scene.GEAR_R_TIP
            assert not any(np.all(np.abs(xy - o[1]) < he[:2] + o[0][:2]) for o in objects[:i])   # no overlaps
        blocks += len(objects) - len(low)
    assert r0 > scene.PEG_RADIUS + scene.CHAMFER if task == "peg" else r0 > scene.GEAR_R_TIP
    assert blocks >= (10 if task == "peg" else 0)       # several blocks together (the gear's board has little room)


def test_the_part_lands_on_what_lies_within_reach():
    # a 5 mm cable 12-40 mm from the hole's axis along y; the error puts the estimated hole over it: the hand-designed
    # policy sets the peg down on the cable, which pushes back while the tip is still above it
    cable = ((0.0025, 0.014, 0.0025), (0.0, 0.026), scene.DARK)
    with sim.AssemblyEnv("peg", scene.Context(objects=(cable,), on_board=True), e_r=0.02, image=False,
                         ft_noise=False) as env:
        seen = []
        sim.run_episode(env, lambda obs: np.zeros(6), seed=0, options={"error": np.array([0.0, 0.026, 0.0, 0.0])},
                        on_step=lambda o, r, info: seen.append((env.world.tool_pose()[0][2], info["f_world"][2])))
        top = env.world.bc.getAABB(env.world.objects[0])[1][2]
    assert any(z > top - 5e-4 and f > 1.0 for z, f in seen), seen[:40]


def test_calibration_scenes_move_only_what_the_sensors_deliver():
    for s in SEEDS:
        c = contexts.family_context("calib", s)
        assert np.all(np.abs(c.camera[:3]) <= contexts.CALIB_SHIFT) and np.all(np.abs(c.camera[3:6]) <= contexts.CALIB_TURN)
        assert abs(c.camera[6]) <= contexts.CALIB_FOCAL and np.all(np.abs(c.camera[7:]) <= contexts.CALIB_CENTRE)
        assert np.all(np.abs(c.ft_mount) <= np.array(contexts.CALIB_FT_TURN) + 1e-6)
        assert c.board_xy == contexts.CONTEXTS["train"].board_xy and not c.objects
    images, rois = {}, {}
    for name, ctx in (("model", contexts.CONTEXTS["train"]), ("zero", scene.Context(camera=(0.0,) * 9)),
                      ("mounted", contexts.family_context("calib", 3))):
        with sim.AssemblyEnv("peg", ctx, image_noise=False, ft_noise=False) as env:
            obs, _ = env.reset(seed=0, options={"error": np.zeros(4)})
            images[name], rois[name] = obs["image"].astype(int), env.roi
    assert rois["mounted"] == rois["model"]                 # the ROI is the calibrated model's (Eq. 11)
    assert np.array_equal(images["zero"], images["model"])  # a mount as calibrated renders as the model
    assert np.abs(images["mounted"] - images["model"]).mean() > 1.0       # the image is the true mount's
    w = scene.World("peg", ft_noise=False, context=scene.Context(ft_mount=(0.0, 0.0, np.pi / 2)))
    raw = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])                # a sensor turned 90 deg about its axis
    np.testing.assert_allclose(w.wrench_tool(-raw)[:3], [2.0, -1.0, 3.0], atol=1e-9)
    w.close()
