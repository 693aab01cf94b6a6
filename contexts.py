"""contexts.py: the scenes the policy is tested in (paper Sec. 5.1.4, Fig. 12): the named contexts, and the
families of contexts drawn from seeds (held-out seeds for testing, the others for training's randomization).
Each is a scene.Context, which scene.World builds.

    contexts.context_of("loc-2")                 # a named context
    contexts.family_context("objects", 7, "peg") # one scene of a family, the same for the same seed
    --context light:test                         # a held-out scene of a family each episode (sim.AssemblyEnv)
"""
import numpy as np

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
import control as ctl
from scene import (BRASS, BUMP_R_MAX, CHAMFER, DARK, GEAR_CENTRES, GEAR_R_TIP, GREY, PART_BLUE, PEG_RADIUS,
                   SHAFT_HEIGHT, TOOL_FRICTION, WORKCELL, Context)

# Every context but 'train' is for testing. The four other places of the board on the table (the paper's
# "four different table locations"), 25-30 cm from the training place, each turned; objects of several sizes
# at several distances that stay outside the task ROI at every error up to 20 mm (tests/test_sim.py), small
# parts lying on the board inside it, another light, other colours.
CONTEXTS = {
    "train": Context(),
    "loc-1": Context(board_xy=(0.50, 0.25), board_yaw=0.25),
    "loc-2": Context(board_xy=(0.62, -0.22), board_yaw=0.3),
    "loc-3": Context(board_xy=(0.36, -0.24), board_yaw=-0.2),
    "loc-4": Context(board_xy=(0.68, 0.24), board_yaw=-0.45),
    "bg-objects": Context(objects=(((0.008, 0.008, 0.012), (-0.1, 0.106), (0.8, 0.1, 0.1, 1)),        # a 16 mm part
                                   ((0.015, 0.015, 0.02), (-0.14, -0.07), (0.1, 0.2, 0.8, 1)),        # a 3 cm block
                                   ((0.05, 0.04, 0.06), (-0.19, 0.02), (0.9, 0.85, 0.1, 1)),          # a 12 cm box
                                   ((0.012, 0.02, 0.01), (0.02, 0.1), (0.1, 0.6, 0.2, 1)))),
    "bg-on-board": Context(objects=(((0.0035, 0.0035, 0.0016), (-0.03, 0.03), GREY),                 # an M4 nut
                                    ((0.002, 0.009, 0.002), (0.025, -0.036), DARK),                   # a screw
                                    ((0.006, 0.006, 0.004), (-0.036, -0.026), (0.8, 0.1, 0.1, 1))), on_board=True),
    "bg-light": Context(light=(("lightDirection", (-1.0, -0.6, 0.8)), ("lightColor", (1.0, 0.8, 0.6)),
                               ("lightAmbientCoeff", 0.35), ("lightDiffuseCoeff", 0.55))),
    "bg-colour": Context(table_rgba=(0.2, 0.3, 0.45, 1), board_rgba=(0.75, 0.85, 0.7, 1)),
}


# ---------------------------------------------------------------- families of contexts (drawn from seeds)
# A family varies one kind of thing the camera sees, or all of them together (mixed); family_context draws
# one scene from a seed. Seeds from FAMILY_TEST_SEED0 up are held out for testing ('light:test' draws one
# anew each episode); training's randomization (sim.AssemblyEnv's `randomize`) draws seeds below it.
# The ranges are ours (no source gives a workcell's), each meant as what one workcell sees over a day:
FAMILIES = ("place", "light", "colour", "parts", "objects", "touch", "reach", "calib", "mixed")
# what mixed draws together: what the camera sees, what the tool can touch on the board, the sensors as mounted
MIXED = ("place", "light", "colour", "parts", "objects", "reach", "calib")
# each family's key to its seeds' draws: one added takes the next, so that no earlier family's scenes change
FAMILY_KEYS = ("place", "light", "colour", "parts", "mixed", "objects", "touch", "reach", "calib")
FAMILY_TEST_SEED0 = 10_000
PLACE_RING, PLACE_X, PLACE_Y, PLACE_YAW = (0.12, 0.32), (0.32, 0.70), (-0.32, 0.32), 0.5   # m from training's, m, rad
LIGHT_ELEVATION, LIGHT_AMBIENT, LIGHT_DIFFUSE = (np.radians(35), np.radians(85)), (0.3, 0.8), (0.15, 0.5)
# sRGB of a black body at 2700-7500 K (Mitchell Charity, "What color is a blackbody?", vendian.org, 2001):
# the warm to cold white of lamps and daylight
KELVIN_RGB = {2700: (1.0, 0.655, 0.341), 4000: (1.0, 0.819, 0.638), 5500: (1.0, 0.925, 0.877),
              6500: (1.0, 0.976, 0.976), 7500: (0.918, 0.931, 1.0)}
TABLE_VALUE, BOARD_VALUE, MAX_SATURATION = (0.12, 0.9), (0.25, 0.95), 0.6   # HSV value and saturation ranges; a board
#                                                     # darker than 0.25 would hide the black hole (0.03) in its grey
# Parts lying on the board: (half extents, m) of an M4 nut, an M3 x 18 screw, an M8 washer, a 12 mm block, a
# 5 mm cable tie's cut end; metal greys, black, brass, red and blue plastic.
LOOSE_PARTS = ((0.0035, 0.0035, 0.0016), (0.0015, 0.009, 0.0015), (0.008, 0.008, 0.0008), (0.006, 0.006, 0.004),
               (0.0025, 0.012, 0.0006))
PART_COLOURS = (GREY, (0.7, 0.7, 0.72, 1), DARK, BRASS, (0.8, 0.1, 0.1, 1), PART_BLUE)
PARTS_PER_SCENE, BOARD_HALF = (1, 4), 0.06          # the boards' half side, m (peg plate 0.12 m; gear plate 2 x 0.06)
# What else a workbench holds beside the hole: fixtures, clamps, blocks, trays, the next part (boxes on the board).
# Ours: 1-4 cm across and 0.5-3 cm tall (a small toggle clamp stands about 3 cm: DESTACO 2027-UR, 33.5 mm under
# its arm, rocheclamp.com), their nearest side 3-7 cm from the hole's axis and beyond the tool's reach
# (tool_reach, with OBJECT_GAP to spare); a metal or plastic colour, or any hue as the colour family's boards.
OBJECT_SIDE, OBJECT_TALL, OBJECT_RING, OBJECTS_PER_SCENE = (0.010, 0.040), (0.005, 0.030), (0.030, 0.070), (1, 4)
OBJECT_GAP, OBJECT_VALUE = 0.002, (0.15, 0.9)
# How near the axis the held gear's tips come at 20 mm of error (diagonal), as BUMP_R_MAX is the peg's rim
GEAR_REACH = BUMP_R_MAX - PEG_RADIUS + GEAR_R_TIP
# What the part touches: steel on steel slides at 0.40-0.70 dry and 0.10 lubricated (pickedshares.com's table of
# static and sliding friction values); clearances from a press-near fit to a loose one (ours); a board set down
# up to 1 degree off level (ours): the pair's coefficient (scene.World sets the board's against TOOL_FRICTION).
TOUCH_FRICTION, TOUCH_CLEARANCE, TOUCH_TILT = (0.10, 0.70), (0.05e-3, 0.3e-3), np.radians(1.0)
# What the tool can touch (ours: a workbench's; half extents, m): thin, long things lying on the board (a 1.5 mm wire,
# a 4 mm cable tie 1.2 mm thick, a 5 mm cable; 4-10 cm long, along the board's x or y) and low ones (an M8 washer
# 1.6 mm thick, 17 mm across; a 0.3 mm shim 12-25 mm across), 1-3 of them with their nearest side between the
# hole's rim (or the held gear's tips at no error) and the tool's reach at 20 mm of error, where the part lands
# on them at large errors; and 0-3 blocks of the objects family's larger sizes (2.5-4 cm across, 1.5-3 cm tall),
# together within 1.5 cm beyond the tool's reach (on a board of 12 cm, in its corners).
REACH_THIN = (((0.00075, 0.00075), (0.020, 0.050)),   # ((half height, half width), half length's range)
              ((0.0006, 0.002), (0.020, 0.050)), ((0.0025, 0.0025), (0.020, 0.050)))
REACH_LOW = ((0.0008, (0.0085, 0.0085)), (0.00015, (0.006, 0.0125)))     # (half height, half side's range)
REACH_PER_SCENE, REACH_BLOCKS, REACH_BLOCK_SIDE, REACH_BLOCK_TALL = (1, 3), (0, 3), (0.025, 0.040), (0.015, 0.030)
REACH_GAP = 0.001                                  # clear of the hole's chamfer (or the gear's tips at no error)
# The sensors as mounted, not as calibrated (ours, as a bumped mount gives): the camera's mount off its hand-eye
# calibration by up to 1 mm along and 0.5 deg about each of its axes (a careful calibration of a UR5's camera
# leaves 0.28 mm and 0.25 deg: Sui et al., "On flange-based 3D hand-eye calibration", arXiv 2407.16041, 2024);
# its focal length off by up to 1 % and its principal point by up to 4 px of the 800 px view (a lens's
# calibration and its focus ring, ours); the wrist sensor turned on its mount by up to 1 deg about its axis and
# 0.3 deg about the others (ours). The ROI (Eq. 11), the controller and every projection use the calibrated
# model; only the rendered image and the measured wrench see these (scene.World).
CALIB_SHIFT, CALIB_TURN, CALIB_FOCAL, CALIB_CENTRE = 0.001, np.radians(0.5), 0.01, 4.0
CALIB_FT_TURN = (np.radians(0.3), np.radians(0.3), np.radians(1.0))


def family_context(family, seed, task="peg"):
    """One scene of `family` (FAMILIES), drawn from `seed`: the same seed gives the same scene. Parts and objects
    lie on the board beyond the tool's reach (tool_reach: at every error up to 20 mm the peg's rim, BUMP_R_MAX,
    or the held gear), so those families change what the camera sees, not what the tool touches; at large errors
    some of them lie inside the task ROI, and objects can hide part of the board. The touch family changes only
    what the part touches: the friction, the clearance and the board's tilt."""
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r} ({', '.join(FAMILIES)})")
    rng = np.random.default_rng([seed, FAMILY_KEYS.index(family)])
    kinds = MIXED if family == "mixed" else (family,)
    c = {}
    if "place" in kinds:
        c.update(_draw_place(rng))
    if "light" in kinds:
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(*LIGHT_ELEVATION)
        c["light"] = (("lightDirection", _floats([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])),
                      ("lightColor", _kelvin_rgb(rng.uniform(2700, 7500))),
                      ("lightAmbientCoeff", round(rng.uniform(*LIGHT_AMBIENT), 3)),
                      ("lightDiffuseCoeff", round(rng.uniform(*LIGHT_DIFFUSE), 3)))
    if "colour" in kinds:
        c["table_rgba"], c["board_rgba"] = _draw_colour(rng, TABLE_VALUE), _draw_colour(rng, BOARD_VALUE)
    if "parts" in kinds:
        c["objects"], c["on_board"] = _draw_parts(rng, task), True
    if "objects" in kinds:
        c["objects"], c["on_board"] = _draw_objects(rng, task, c.get("objects", ())), True
    if "touch" in kinds:
        a, t = rng.uniform(0, 2 * np.pi), rng.uniform(0, TOUCH_TILT)       # tilted by t about a horizontal axis
        c.update(friction=round(rng.uniform(*TOUCH_FRICTION), 3), clearance=round(rng.uniform(*TOUCH_CLEARANCE), 7),
                 tilt=_floats([t * np.cos(a), t * np.sin(a)], 5))
    if "reach" in kinds:
        c["objects"], c["on_board"] = _draw_reach(rng, task, c.get("objects", ())), True
    if "calib" in kinds:
        c["camera"] = _floats([*rng.uniform(-CALIB_SHIFT, CALIB_SHIFT, 3), *rng.uniform(-CALIB_TURN, CALIB_TURN, 3),
                               rng.uniform(-CALIB_FOCAL, CALIB_FOCAL), *rng.uniform(-CALIB_CENTRE, CALIB_CENTRE, 2)], 6)
        c["ft_mount"] = _floats(rng.uniform(np.negative(CALIB_FT_TURN), CALIB_FT_TURN), 6)
    return Context(**c)


def _draw_place(rng):
    """Another place and turn of the board on the table, clear of the workcell's boxes by 1 cm."""
    t, g = np.array(Context().board_xy), np.linspace(-BOARD_HALF, BOARD_HALF, 7)
    grid = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)                    # the board's footprint, its frame
    while True:
        xy = rng.uniform((PLACE_X[0], PLACE_Y[0]), (PLACE_X[1], PLACE_Y[1]))
        yaw = rng.uniform(-PLACE_YAW, PLACE_YAW)
        if not PLACE_RING[0] <= np.linalg.norm(xy - t) <= PLACE_RING[1]:
            continue
        pts = xy + grid @ ctl.rot_z(yaw)[:2, :2].T
        if not any(np.all(np.abs(pts - np.array(c[:2])) < np.array(he[:2]) + 0.01, 1).any() for he, c, _ in WORKCELL):
            return {"board_xy": _floats(xy), "board_yaw": round(float(yaw), 4)}


def _floats(x, digits=3):                  # plain, rounded floats: a Context's repr is a cache key (report.py)
    return tuple(round(float(v), digits) for v in x)


def _kelvin_rgb(kelvin):
    ks = sorted(KELVIN_RGB)
    return _floats([np.interp(kelvin, ks, [KELVIN_RGB[k][i] for k in ks]) for i in range(3)])


def _draw_colour(rng, value):
    """An rgba of any hue, saturation up to MAX_SATURATION and HSV value within `value`."""
    h, s, v = rng.uniform(0, 1), rng.uniform(0, MAX_SATURATION), rng.uniform(*value)
    k = (np.array([5.0, 3.0, 1.0]) + 6 * h) % 6                                           # HSV -> RGB
    rgb = v - v * s * np.clip(np.minimum(k, 4 - k), 0, 1)
    return (*_floats(rgb), 1)


def _draw_parts(rng, task):
    """PARTS_PER_SCENE parts at random spots of the board (its frame), beyond the tool's reach and off the
    mating gear, each whole on the board."""
    out, n = [], rng.integers(PARTS_PER_SCENE[0], PARTS_PER_SCENE[1] + 1)
    gear = GEAR_R_TIP + 0.002                                             # a gear's tips and 2 mm
    reach = BUMP_R_MAX if task == "peg" else gear
    while len(out) < n:
        he = LOOSE_PARTS[rng.integers(len(LOOSE_PARTS))]
        r = np.hypot(he[0], he[1])                                        # the part's footprint radius
        xy = rng.uniform(-BOARD_HALF + r, BOARD_HALF - r, 2)
        if np.linalg.norm(xy) < reach + r or (task == "gear" and np.hypot(xy[0] - GEAR_CENTRES, xy[1]) < gear + r):
            continue
        if any(np.hypot(*np.subtract(xy, o[1])) < r + np.hypot(*o[0][:2]) for o in out):   # parts do not overlap
            continue
        out.append((he, _floats(xy, 4), PART_COLOURS[rng.integers(len(PART_COLOURS))]))
    return tuple(out)


def tool_reach(task, top):
    """How near the hole's (shaft's) axis the tool comes, m, at errors up to 20 mm, over a thing `top` m tall on
    the board: the peg's rim at every height (beyond it the sensor, 35 mm in radius, and the camera stay over 3 cm
    even at full insertion); the held gear's tips over what stands as high as the shaft's top (GEAR_REACH), below it
    only over the shaft (the gear meets nothing lower until aligned)."""
    if task == "peg":
        return BUMP_R_MAX
    return GEAR_REACH if top > SHAFT_HEIGHT - OBJECT_GAP else GEAR_R_TIP


def box_gap(p, xy, he):
    """The distance (m) from point p to a box centred at xy with half extents he, in the board's plane."""
    return np.hypot(*np.maximum(np.abs(np.subtract(p, xy)) - he[:2], 0.0))


def overlaps(xy, he, others, gap=0.0):
    """Whether a box (centre xy, half extents he) comes within `gap` of any of `others`, (he, xy, rgba) each."""
    return any(np.all(np.abs(np.subtract(xy, o[1])) < np.add(he[:2], o[0][:2]) + gap) for o in others)


def _on_board(rng, he):
    """A centre (board frame) that keeps a box of half extents he whole on the board."""
    return rng.uniform(-BOARD_HALF + np.array(he[:2]), BOARD_HALF - np.array(he[:2]))


def _fits(xy, he, task, others, ring):
    """Whether a box (centre xy, half extents he) has its nearest side within ring (m from the axis), lies off the
    mating gear and clear of `others` by OBJECT_GAP."""
    if not ring[0] <= box_gap((0.0, 0.0), xy, he) <= ring[1] or overlaps(xy, he, others, OBJECT_GAP):
        return False
    return task != "gear" or box_gap((GEAR_CENTRES, 0.0), xy, he) >= GEAR_R_TIP + OBJECT_GAP


def _draw_objects(rng, task, others=()):
    """OBJECTS_PER_SCENE workbench objects (boxes, the board's frame) on the board, beyond the tool's reach, off
    the mating gear and clear of `others` (the scene's parts), added to them."""
    out = list(others)
    n = len(out) + rng.integers(OBJECTS_PER_SCENE[0], OBJECTS_PER_SCENE[1] + 1)
    while len(out) < n:
        he = (*(rng.uniform(*OBJECT_SIDE, 2) / 2), rng.uniform(*OBJECT_TALL) / 2)
        xy = _on_board(rng, he)
        near = max(OBJECT_RING[0], tool_reach(task, 2 * he[2]) + OBJECT_GAP)     # beyond the tool's reach
        if not _fits(xy, he, task, out, (near, OBJECT_RING[1])):
            continue
        rgba = PART_COLOURS[rng.integers(len(PART_COLOURS))] if rng.random() < 0.5 else _draw_colour(rng, OBJECT_VALUE)
        out.append((_floats(he, 4), _floats(xy, 4), rgba))
    return tuple(out)


def reach_ring(task):
    """The ring (m from the hole's or shaft's axis) where what the tool can touch lies: from the peg's chamfer (the
    held gear's tips, the gear then sits down over the shaft) to where the part's rim reaches at 20 mm of error."""
    if task == "peg":
        return PEG_RADIUS + CHAMFER + REACH_GAP, BUMP_R_MAX
    return GEAR_R_TIP + REACH_GAP, GEAR_REACH


def _draw_reach(rng, task, others=()):
    """REACH_PER_SCENE thin or low things within the tool's reach (reach_ring), then REACH_BLOCKS of the objects
    family's largest blocks just beyond it, each whole on the board, off the mating gear and clear of `others`."""
    out = list(others)
    n = len(out) + rng.integers(REACH_PER_SCENE[0], REACH_PER_SCENE[1] + 1)
    while len(out) < n:
        if rng.random() < 0.5:                                             # thin and long, along x or y
            (h, w), length = REACH_THIN[rng.integers(len(REACH_THIN))]
            half = (rng.uniform(*length), w) if rng.random() < 0.5 else (w, rng.uniform(*length))
        else:                                                              # low: a washer or a shim
            h, side = REACH_LOW[rng.integers(len(REACH_LOW))]
            half = (rng.uniform(*side),) * 2
        he = (*half, h)
        xy = _on_board(rng, he)
        if not _fits(xy, he, task, out, reach_ring(task)):
            continue
        out.append((_floats(he, 5), _floats(xy, 4), PART_COLOURS[rng.integers(len(PART_COLOURS))]))
    n = len(out) + rng.integers(REACH_BLOCKS[0], REACH_BLOCKS[1] + 1)
    near = tool_reach(task, REACH_BLOCK_TALL[1]) + OBJECT_GAP
    for _ in range(200 * (n - len(out))):                                  # (a board may have no room left)
        if len(out) == n:
            break
        he = (*(rng.uniform(*REACH_BLOCK_SIDE, 2) / 2), rng.uniform(*REACH_BLOCK_TALL) / 2)
        xy = _on_board(rng, he)
        if not _fits(xy, he, task, out, (near, near + 0.015)):
            continue
        out.append((_floats(he, 4), _floats(xy, 4), _draw_colour(rng, OBJECT_VALUE)))
    return tuple(out)


def drawn_family(name):
    """(family, first seed) of --context FAMILY:test (a held-out scene each episode, the env's to draw: seeds from
    FAMILY_TEST_SEED0) or FAMILY:train (a scene of training's side each episode: the stop rule's validation), else
    None."""
    if isinstance(name, Context):
        return None
    family, _, which = name.partition(":")
    first = {"test": FAMILY_TEST_SEED0, "train": 0}.get(which)
    return (family, first) if first is not None and family in FAMILIES else None


def held_out_family(name):
    """The family of --context FAMILY:test (a held-out scene each episode, the env's to draw), else None."""
    drawn = drawn_family(name)
    return drawn[0] if drawn and drawn[1] == FAMILY_TEST_SEED0 else None


def context_of(name, task="peg"):
    """--context's value -> a Context: a name in CONTEXTS, or FAMILY:SEED (one scene of a family); a Context is
    itself. ValueError for anything else; FAMILY:test (a held-out scene each episode) is the env's to draw."""
    if isinstance(name, Context):
        return name
    if name in CONTEXTS:
        return CONTEXTS[name]
    family, _, seed = name.partition(":")
    drawn = drawn_family(name)
    if drawn:                                       # the first scene the env draws from: held-out or training's side
        return family_context(family, drawn[1], task)
    if family in FAMILIES and seed.isdigit():
        return family_context(family, int(seed), task)
    raise ValueError(f"unknown context {name!r} ({', '.join(CONTEXTS)}, or FAMILY:SEED, FAMILY:test or FAMILY:train "
                     f"with FAMILY one of {', '.join(FAMILIES)})")


def context_key(name, task="peg"):
    """What --context `name` stands for, as text: a cache's key (a context or a family redefined is evaluated again)."""
    if drawn_family(name):
        objects = (OBJECT_SIDE, OBJECT_TALL, OBJECT_RING, OBJECTS_PER_SCENE, OBJECT_GAP, OBJECT_VALUE, GEAR_REACH)
        reach = (REACH_THIN, REACH_LOW, REACH_PER_SCENE, REACH_BLOCKS, REACH_BLOCK_SIDE, REACH_BLOCK_TALL, REACH_GAP)
        calib = (CALIB_SHIFT, CALIB_TURN, CALIB_FOCAL, CALIB_CENTRE, CALIB_FT_TURN)
        added = {"objects": objects, "mixed": objects + ("mixed", MIXED) + reach + calib,   # (the older families'
                 "touch": (TOUCH_FRICTION, TOUCH_CLEARANCE, TOUCH_TILT, TOOL_FRICTION),    # keys stay as they were)
                 "reach": objects + reach, "calib": calib}
        return repr((name, task, FAMILY_TEST_SEED0, PLACE_RING, PLACE_X, PLACE_Y, PLACE_YAW, LIGHT_ELEVATION,
                     LIGHT_AMBIENT, LIGHT_DIFFUSE, KELVIN_RGB, TABLE_VALUE, BOARD_VALUE, MAX_SATURATION, LOOSE_PARTS,
                     PART_COLOURS, PARTS_PER_SCENE, BOARD_HALF) + added.get(drawn_family(name)[0], ()))
    c = context_of(name, task)
    touch, mount = (c.friction, c.clearance, c.tilt), (c.camera, c.ft_mount)
    return (repr(c) + (f" touch={touch}" if touch != (None, None, (0.0, 0.0)) else "")
            + (f" mount={mount}" if mount != ((), ()) else ""))


class ContextNames:
    """The values --context takes, as argparse's choices: CONTEXTS's names, FAMILY:SEED and FAMILY:test."""
    def __contains__(self, name):
        try:
            return bool(context_of(name))
        except (ValueError, TypeError):
            return False

    def __iter__(self):
        yield from CONTEXTS
        yield from (f"{f}:SEED|test|train" for f in FAMILIES)
