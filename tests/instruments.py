"""Instruments of the tests: drive the tool with the admittance controller and a chosen stiffness
(probe), and measure the part's lateral play in its hole or on its shaft physically (lateral_play)."""
import os
import tempfile

import numpy as np

import control as ctl
from scene import CONTROL_HZ, Context, HOLE_DEPTH, R_DOWN, SHAFT_HEIGHT, World, p, quat_from_matrix, tool_xml
from sim import F_MAX6, MASS, ZETA


def probe(world, x_start, x_target, f_d=np.zeros(6), ex=(1e-5, 1e-5, 0.05, 0.02, 0.02, 0.001), seconds=6.0,
          duration=3.0):
    """Drive the tip from x_start toward x_target with the admittance controller and a given
    exploration range per axis (by default stiff in x, y and yaw, soft in z), holding F_d.
    For the geometry tests: a stiff lateral hold shows the clearance itself, not the chamfer's
    self-centring. Returns the final tip pose, the mean tool-frame wrench of the last 1 s and the
    mean total contact normal force on the robot over that second (pybullet's contact points)."""
    world.move_to(x_start)
    world.command(np.zeros(6))
    world.step_physics(4)
    world.move_to(x_start)
    world.tare()
    controller = ctl.HybridPolicy(x_start, x_target, np.asarray(ex, float), F_MAX6, MASS, duration, ZETA,
                                  1.0 / CONTROL_HZ)
    f_tool, n, hist, normal = np.zeros(6), int(seconds * CONTROL_HZ), [], []
    for i in range(n):
        f_tool = world.tick(controller, i / CONTROL_HZ, f_tool, f_d)
        hist.append(f_tool)
        normal.append(sum(c[9] for c in world.bc.getContactPoints(world.robot)))
    return world.tool_pose(), np.mean(hist[-CONTROL_HZ:], 0), float(np.mean(normal[-CONTROL_HZ:]))


def lateral_play(task, clearance, yaws, directions=8, depth=0.010, force=0.2, steps=120, context=Context()):
    """The part's lateral play, measured physically: the tool's collision shape alone as a free body
    (1 kg, an inertia that keeps it upright), `depth` into the hole (peg) or onto the shaft (gear), at
    each relative yaw (rad) pushed with `force` N toward each of `directions` directions (no friction)
    until it rests on the wall. A context's own clearance (the touch family's) stands in for `clearance`.
    Returns the diametral play (m) per yaw and direction pair, shape
    (len(yaws), directions // 2): the travel toward phi plus the travel toward phi + pi."""
    w = World(task, clearance, ft_noise=False, image_noise=False, context=context)
    bc = w.bc
    (p_g, _), _ = w.place(context)
    bc.removeBody(w.robot)
    walls = [b for b, _ in w.parts] if task == "peg" else [w.parts[-1][0]]     # the hole, or the shaft
    for b, _ in w.parts:
        if b in walls:
            bc.changeDynamics(b, -1, lateralFriction=0.0)
        else:
            bc.removeBody(b)
    xml, tip = tool_xml(task, w.clearance)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(f'<robot name="part"><link name="tool">{xml}</link></robot>')
    part = bc.loadURDF(f.name)
    os.remove(f.name)
    bc.changeDynamics(part, -1, mass=1.0, localInertiaDiagonal=[1e3] * 3, collisionMargin=0.0, lateralFriction=0.0)
    top = p_g[2] + (HOLE_DEPTH if task == "peg" else SHAFT_HEIGHT)   # the board's top, or the shaft's
    travel = np.zeros((len(yaws), directions))
    for i, yaw in enumerate(yaws):
        R = ctl.rot_z(w.goal_yaw + yaw) @ R_DOWN
        start = np.array([p_g[0], p_g[1], top - depth]) - R[:, 2] * tip
        for j in range(directions):
            u = np.array([np.cos(2 * np.pi * j / directions), np.sin(2 * np.pi * j / directions), 0.0])
            bc.resetBasePositionAndOrientation(part, start.tolist(), quat_from_matrix(R))
            bc.resetBaseVelocity(part, [0, 0, 0], [0, 0, 0])
            for _ in range(steps):
                bc.applyExternalForce(part, -1, (force * u).tolist(), [0, 0, 0], p.WORLD_FRAME)
                bc.stepSimulation()
            travel[i, j] = (np.array(bc.getBasePositionAndOrientation(part)[0]) - start) @ u
    w.close()
    return travel[:, :directions // 2] + travel[:, directions // 2:]




def sliding_friction(context, speed=0.005):
    """The coefficient of the peg sliding on the board, measured: the tip pressed on the board's top 45 mm beside
    the hole (clear of its bumps) by a soft z, dragged along x; |F_x| / |F_z| of the wrist sensor over the last
    second of the drag."""
    w = World("peg", 1e-4, ft_noise=False, image_noise=False, context=context)
    (p_g, R_g), _ = w.place(context)
    top = p_g[2] + HOLE_DEPTH
    start = (np.array([p_g[0] - 0.015, p_g[1] + 0.045, top + 0.002]), R_g)
    target = (np.array([p_g[0] - 0.015 + 6 * speed, p_g[1] + 0.045, top - 0.02]), R_g)
    _, f, _ = probe(w, start, target, ex=(1e-3, 1e-5, 0.05, 0.02, 0.02, 0.001), seconds=4.0, duration=6.0)
    w.close()
    return abs(f[0]) / abs(f[2])
