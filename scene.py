"""scene.py: the PyBullet workcell that sim.py's task runs in (paper Sec. 5.1.1, Fig. 6; contexts: Sec. 5.1.4).

A UR5 (assets/ur5.urdf, built from its DH parameters) with a 6-axis force/torque sensor on the fixed
joint between flange and tool, an eye-in-hand camera, and one of two task boards built from boxes so
that the clearances are exact:
    peg   a 16 mm round peg into a 16-gon hole, 0.1 mm diametral clearance, 25 mm deep,
          0.5 mm x 45 deg entry chamfer, on a board with a printed board's bumps around the hole
    gear  a 12-tooth gear slides 15 mm down a 10 mm shaft (0.1 mm clearance) while meshing with a
          fixed mating gear, so x, y and the rotation about z must align (about 0.03 rad)
The play the part meets is the clearance at every yaw (tests/instruments.py measures it). The sensors
are a real robot's: the wrist wrench has the FT 300's noise and a drifting bias, the image shot noise.
Every physical magnitude below says where it comes from.

Frames and units: metres, radians, newtons. World z is up; the table top is z = 0. A tool pose X is
the tool tip (the peg tip, the gear's lower face) with the tool's z axis pointing down. Quaternions
are pybullet's (x, y, z, w).
"""
import contextlib
import os
import socket
import sys
import tempfile
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np

@contextlib.contextmanager
def quiet_c_output():
    """Silence what Bullet's C++ prints straight to the file descriptors (its banner on import,
    URDF importer warnings), so that a user's error message is the one line they see."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved + [null]:
            os.close(fd)


with quiet_c_output():
    import pybullet as p
    from pybullet_utils import bullet_client

import tacrl_flat  # noqa: F401  (first: where another package shadows one of our modules, one line says so)
import control as ctl
from shapes import board_bumps, chamfer_boxes, gear_teeth, plate_boxes, quat_from_matrix, ring_boxes, to_world


def assets_dir():
    """assets/ (ur5.urdf): beside the modules in a checkout or an editable install; where pip put pyproject's
    data-files (<prefix>/share/tacrl/assets) after `pip install .`, which installs the modules alone beside them."""
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "assets")
    if os.path.isdir(here):
        return here
    try:
        urdf = [f for f in metadata.files("tacrl") or () if f.name == "ur5.urdf"]
    except metadata.PackageNotFoundError:
        urdf = []
    return os.path.normpath(os.path.dirname(str(urdf[0].locate()))) if urdf else here


ASSETS = assets_dir()

# ---------------------------------------------------------------- the clock, the sensors, the parts (paper Sec. 5.1.1)
POLICY_HZ, CONTROL_HZ, PHYSICS_HZ = 5, 120, 240
CONTROL_PER_POLICY = CONTROL_HZ // POLICY_HZ        # 24 controller ticks per action
PHYSICS_PER_CONTROL = PHYSICS_HZ // CONTROL_HZ      # 2 physics steps per controller tick
IMG = 80                                            # the policy's image is IMG x IMG gray
LUMA = (0.299, 0.587, 0.114)                        # Rec. 601: the gray camera's weights of R, G, B
# The wrist sensor saturates at its measuring range: Robotiq FT 300, a sensor made for UR arms,
# +-300 N and +-30 N m (Robotiq's FT 300 instruction manual, 2018-12-18 edition, specifications;
# assets.robotiq.com/website-assets/support_documents/document/FT_Sensor_Instruction_Manual_PDF_20181218.pdf.
# Its 16-bit data stream carries F x 100 and M x 1000, so it cannot report more than 327 N and
# 32.7 N m). Contact forces here stay far below.
FT_RANGE = np.array([300.0] * 3 + [30.0] * 3, np.float32)
# Its signal noise, per reading (one reading a 120 Hz tick; the FT 300 streams at 100 Hz): 0.1 N, and
# 0.005 / 0.005 / 0.003 N m (the same manual's specifications, "signal noise"; taken as 1 sigma).
FT_NOISE = np.array([0.1, 0.1, 0.1, 0.005, 0.005, 0.003])
# Its zero drifts. The manual gives no drift rate; it recommends contact thresholds of 1 N and 0.02 /
# 0.02 / 0.01 N m as what a reading must exceed to mean contact. We let the bias, zeroed at each
# episode's start as a robot zeroes its sensor before an insertion, random-walk so that its 3 sigma
# reaches those thresholds at the end of an episode (24 s): a slowly drifting bias of 0.33 N sigma.
# No other data sheet we found gives one. The one published measurement: a UR e-series wrist sensor,
# zeroed, the arm still, read (0.27, 1.38, 4.02) N off zero 5 min later
# (github.com/UniversalRobots/Universal_Robots_ROS_Driver/issues/633), 2.1 x this rate as a random
# walk. What the rate decides is in results/drift/: little for trained policies, a lot for the hand-designed one.
FT_DRIFT = np.array([1.0, 1.0, 1.0, 0.02, 0.02, 0.01]) / 3 / np.sqrt(24.0)   # per sqrt(s)
# The camera's shot noise: a pixel that reads y (0-255) collected y * E_PER_DN photo-electrons, so it
# reads y +- sqrt(y / E_PER_DN). A shot-noise-limited pixel's best SNR is sqrt(full well): the Micron
# MT9T001 (3.2 um pixels, in USB2 board cameras) gives 43 dB (its data sheet, as tabulated in
# kscitech.com/Webcam, 2006), so 10^(43/10) = 20,000 e- at full scale: +-1.3 DN at mid gray (the paper
# names no camera).
E_PER_DN = 20000.0 / 255.0
APPROACH = 0.030                                    # X_i: tip this far above the top of the task's part, m
CLEAR = 0.010                                       # ... and at least this far above it at the largest z error
JOINT_TORQUE_CAP = [10.0, 10.0, 10.0, 2.0, 2.0, 2.0]  # N m: the motors' limits (UR5 rated: 150 / 28)


# Bullet lets a pressed contact sink CONTACT_SLOP into the wall (its default, measured: a box pushed
# against a wall rests 0.00998 mm inside it, whatever the force), so a part pushed to either side
# travels 2 x CONTACT_SLOP more than the geometry allows. Holes and bores are made that much tighter,
# so that the play the part meets is the nominal clearance (tests/instruments.py measures it).
CONTACT_SLOP = 1e-5
# Friction: Bullet multiplies the two bodies' lateralFriction. The tool and the gear's shaft keep URDF's default
# (a lateralFriction given with collisionMargin in one changeDynamics call is ignored); every other body has
# BOARD_FRICTION: the peg slides on the board at 0.15, the gear's bore on the shaft at 0.25 (measured:
# tests/instruments.sliding_friction)
TOOL_FRICTION, BOARD_FRICTION = 0.5, 0.3
PEG_RADIUS = 0.008
PEG_LENGTH = 0.050
PEG_BLADES = 20                                     # boxes that make the round peg's collision shape (tool_xml)
PEG_CAP = 0.0003                                    # the peg's lowest 0.3 mm: a square cap (tool_xml)
HOLE_DEPTH = 0.025
CHAMFER = 0.0005                                    # 0.5 mm x 45 deg entry chamfer
BOARD_THICK = 0.030
# The 3D-printed board's uneven top near the hole (the paper blames its two-step baseline's failures on
# "the bumps ... uneven surfaces"): BUMPS smooth blobs, each a sphere's cap BUMP_H high and 2 x BUMP_A
# across, where the peg's rim can meet them (within BUMP_R_MAX of the hole's axis: 20 mm of error,
# diagonal, plus the peg's radius). Heights of one FDM layer (0.1-0.3 mm; 0.2 mm is the common
# default) and widths of a few 0.4-0.45 mm extrusion lines; the same for every episode of a board
# (BOARD_SEED), as a physical board is.
BUMPS, BUMP_H, BUMP_A, BUMP_R_MAX, BOARD_SEED = 24, (1e-4, 2e-4), (8e-4, 1.5e-3), 0.036, 0
SHAFT_RADIUS = 0.005
SHAFT_HEIGHT = 0.015
GEAR_THICK = 0.015
GEAR_TEETH = 12
GEAR_R_ROOT, GEAR_R_TIP = 0.011, 0.022
TOOTH_WIDTH = 0.0041                                # sets the yaw tolerance: about 0.03 rad
GEAR_CENTRES = 0.040                                # distance shaft to mating gear, m
HOLDER_LENGTH = 0.040

ROBOT_HOME = [np.pi, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0]
R_DOWN = np.diag([1.0, -1.0, -1.0])                  # tool z down, tool x along world x

# full camera view: 800 x 800 px (the paper's ROI-800*800), 90 deg, a wide-angle USB camera's (at 60 deg it
# showed the board and little else: README difference 14); ROIs are windows of it
CAM_FULL, CAM_FOV, CAM_NEAR, CAM_FAR = 800, 90.0, 0.01, 2.0
VIDEO_W, VIDEO_H = 640, 480                          # px of the external view that videos show (VGA, ~0.1 s a frame)

WHITE, GREY, DARK, BLACK = (0.92, 0.92, 0.9, 1), (0.55, 0.55, 0.55, 1), (0.2, 0.2, 0.22, 1), (0.03, 0.03, 0.03, 1)
WOOD, ORANGE, BRASS, TEAL = (0.62, 0.48, 0.34, 1), (0.95, 0.5, 0.1, 1), (0.8, 0.65, 0.2, 1), (0.1, 0.5, 0.55, 1)


# ---------------------------------------------------------------- the workcell and its contexts (Sec. 5.1.4, Fig. 12)
# The workcell, fixed on the table in every context, as boxes (half extents, centre; m): a low fence
# (the paper's "edge of the tray", Fig. 1) around the training place, a floor-tape line, and spare
# workpieces; what the full view shows around the board differs from place to place.
FENCE, TAPE = (0.25, 0.3, 0.38, 1), (0.9, 0.78, 0.1, 1)
PART_BLUE, PART_GREY = (0.2, 0.35, 0.7, 1), (0.45, 0.45, 0.48, 1)
WORKCELL = [((0.004, 0.124, 0.010), (0.386, 0.0, 0.010), FENCE), ((0.004, 0.124, 0.010), (0.614, 0.0, 0.010), FENCE),
            ((0.114, 0.004, 0.010), (0.5, 0.12, 0.010), FENCE), ((0.114, 0.004, 0.010), (0.5, -0.12, 0.010), FENCE),
            ((0.010, 0.45, 0.0005), (0.26, 0.0, 0.0005), TAPE),
            ((0.03, 0.03, 0.02), (0.35, 0.31, 0.02), PART_BLUE),
            ((0.025, 0.04, 0.015), (0.47, -0.34, 0.015), PART_GREY),
            ((0.04, 0.025, 0.03), (0.62, 0.37, 0.03), ORANGE), ((0.02, 0.02, 0.05), (0.20, -0.22, 0.05), TEAL)]


@dataclass(frozen=True)
class Context:
    """Where the board stands (its hole or shaft axis, its yaw) and what surrounds it. objects: boxes
    (half extents, (dx, dy) in the board's frame, rgba) standing on the table (or, with on_board, on the
    board's top); light: getCameraImage's light arguments as (name, value) pairs, () for TinyRenderer's own.
    What the part touches (the touch family; None and (0, 0): the world's own): friction, the coefficient of the
    part sliding on the board, hole or shaft; clearance, diametral, m; tilt, the board's about its x and y, rad.
    The sensors as mounted (the calib family; () where as calibrated): camera, the camera's true mount against the
    model's (dx, dy, dz m and rx, ry, rz rad in the camera's axes, the focal length's relative error, the principal
    point's offset du, dv in px of the 800 px view); ft_mount, the wrist sensor's turn on its mount (rotation
    vector, rad). These five stay out of the repr, so that the other contexts' keys (context_key) stay as they were."""
    board_xy: tuple = (0.50, 0.0)
    board_yaw: float = 0.0
    table_rgba: tuple = WOOD
    board_rgba: tuple = WHITE
    objects: tuple = ()
    on_board: bool = False
    light: tuple = ()
    friction: float = field(default=None, repr=False)
    clearance: float = field(default=None, repr=False)
    tilt: tuple = field(default=(0.0, 0.0), repr=False)
    camera: tuple = field(default=(), repr=False)
    ft_mount: tuple = field(default=(), repr=False)


# ---------------------------------------------------------------- geometry helpers
def matrix_from_quat(q):
    return np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3)


# ---------------------------------------------------------------- the tool, written into the URDF
def _urdf_box(he, pos, R, rgba):
    rpy = p.getEulerFromQuaternion(quat_from_matrix(R))
    o = f'<origin xyz="{pos[0]:.7f} {pos[1]:.7f} {pos[2]:.7f}" rpy="{rpy[0]:.7f} {rpy[1]:.7f} {rpy[2]:.7f}"/>'
    g = f'<geometry><box size="{2 * he[0]:.7f} {2 * he[1]:.7f} {2 * he[2]:.7f}"/></geometry>'
    return (f'<visual>{o}{g}<material name="c{hash(rgba) & 0xffff}"><color rgba="{" ".join(map(str, rgba))}"/>'
            f'</material></visual><collision>{o}{g}</collision>')


def _urdf_cylinder(r, z0, z1, rgba):
    o = f'<origin xyz="0 0 {(z0 + z1) / 2:.7f}"/>'
    g = f'<geometry><cylinder radius="{r:.7f}" length="{z1 - z0:.7f}"/></geometry>'
    return (f'<visual>{o}{g}<material name="c{hash(rgba) & 0xffff}"><color rgba="{" ".join(map(str, rgba))}"/>'
            f'</material></visual><collision>{o}{g}</collision>')


def tool_xml(task, clearance):
    """The tool link's contents (tool frame: z down along the tool, origin at the sensor face).
    Returns (xml, tip_offset): the tool tip sits at (0, 0, tip_offset) in the tool frame."""
    inertial = ('<inertial><origin xyz="0 0 0"/><mass value="0.1"/>'
                '<inertia ixx="5e-5" iyy="5e-5" izz="5e-5" ixy="0" ixz="0" iyz="0"/></inertial>')
    if task == "peg":
        # Collision: PEG_BLADES thin boxes (blades) through the axis, turned by pi / PEG_BLADES: their
        # 2 x PEG_BLADES flat ends approximate the round peg. Bullet's cylinders keep a ~1 mm rounded
        # margin when loaded from URDF (changeDynamics does not reach into the link's compound), which
        # would hide a 0.1 mm clearance; boxes are exact. Each end spans +-alpha = pi / (4 PEG_BLADES)
        # about its axis, so the peg's extent in any direction (its support function) lies within
        # 1 - cos(alpha) = 0.08 % of its corner radius; the corners sit at PEG_RADIUS * alpha / sin(alpha)
        # so that the extent's mean over directions is PEG_RADIUS. The lateral play then equals the
        # nominal clearance within -0.004..+0.008 mm at every yaw (tests/test_sim.py measures it; the
        # rest of the spread comes from the 16-gon hole's corners).
        alpha = np.pi / (4 * PEG_BLADES)
        r_c = PEG_RADIUS * alpha / np.sin(alpha)
        half_w, half_l = r_c * np.sin(alpha), r_c * np.cos(alpha)
        o = f'<origin xyz="0 0 {PEG_LENGTH / 2:.7f}"/>'
        vis = (f'<visual>{o}<geometry><cylinder radius="{PEG_RADIUS:.7f}" length="{PEG_LENGTH:.7f}"/></geometry>'
               f'<material name="peg"><color rgba="{" ".join(map(str, ORANGE))}"/></material></visual>')
        # The blades stop PEG_CAP above the tip; the tip itself is one square box inscribed in the
        # circle, so that on a flat surface one shape touches instead of the blades (fewer contact
        # points for the solver: the peg resting on the board cost 2/3 of the step time).
        blade = PEG_LENGTH - PEG_CAP
        cols = "".join(
            f'<collision><origin xyz="0 0 {blade / 2:.7f}" rpy="0 0 {k * np.pi / PEG_BLADES:.7f}"/><geometry>'
            f'<box size="{2 * half_l:.7f} {2 * half_w:.7f} {blade:.7f}"/></geometry></collision>\n'
            for k in range(PEG_BLADES))
        a = (PEG_RADIUS - PEG_CAP - 5e-5) / np.sqrt(2)    # corners inside the 45 deg cone of the blade tips
        cols += (f'<collision><origin xyz="0 0 {PEG_LENGTH - 0.0005:.7f}" rpy="0 0 {np.pi / 4:.7f}"/><geometry>'
                 f'<box size="{2 * a:.7f} {2 * a:.7f} 0.001"/></geometry></collision>')
        return inertial + vis + cols, PEG_LENGTH
    # gear: a holder, then the gear (bore ring + teeth) from z0 to z1, tip = the gear's lower face.
    # The tool frame's z points down, so its x-y plane is mirrored against the board's: the teeth
    # are symmetric about the x axis and the mirror does not matter.
    z0, z1 = HOLDER_LENGTH, HOLDER_LENGTH + GEAR_THICK
    parts = [_urdf_cylinder(0.008, 0.0, z0, DARK)]
    r_bore = SHAFT_RADIUS + clearance / 2 - CONTACT_SLOP      # inscribed radius of the 12-gon bore
    ring = ring_boxes(r_bore, GEAR_R_ROOT + 0.002 - r_bore, z0, z1, 12)
    parts += [_urdf_box(he, pos, R, BRASS) for he, pos, R in ring]
    parts += [_urdf_box(he, pos, R, BRASS) for he, pos, R in
              gear_teeth(GEAR_R_ROOT, GEAR_R_TIP, TOOTH_WIDTH, GEAR_TEETH, z0, z1)]
    return inertial + "\n".join(parts), z1


def robot_urdf(task, clearance):
    """assets/ur5.urdf with the task's tool written into its `tool` link, as a new temporary file of
    the caller's; returns (path, tip_offset)."""
    with open(os.path.join(ASSETS, "ur5.urdf")) as f:
        text = f.read()
    xml, tip = tool_xml(task, clearance)
    fd, path = tempfile.mkstemp(prefix=f"tacrl_ur5_{task}_", suffix=".urdf")
    with os.fdopen(fd, "w") as f:
        f.write(text.replace("<!-- TOOL -->", xml))
    return path, tip


def display_problem():
    """Why PyBullet's window (gui=True) cannot open here, or None. Without an X server, pybullet's GUI
    thread ends the process or, with its output silenced, hangs it: better to know first."""
    if not sys.platform.startswith("linux"):
        return None
    display = os.environ.get("DISPLAY", "")
    if not display:
        return "there is no display (DISPLAY is not set)"
    host, _, number = display.rpartition(":")
    number = number.split(".")[0]
    if not number.isdigit():
        return f"DISPLAY={display!r} is not a display"
    if host in ("", "unix"):
        if not os.path.exists(f"/tmp/.X11-unix/X{number}"):
            return f"no X server listens at DISPLAY={display!r}"
        return None
    try:
        socket.create_connection((host, 6000 + int(number)), timeout=2).close()
    except OSError:
        return f"no X server answers at DISPLAY={display!r}"
    return None


# ---------------------------------------------------------------- the world
class World:
    """The PyBullet scene of one context: table and workcell, UR5 with tool, sensor and camera, one task
    board, the context's objects. One DIRECT (or GUI) client of its own; every call names it. `rebuild`
    empties the simulation and builds the scene again: PyBullet keeps history across resetJointState and
    resetBase... (contact caches, solver warm starts: bullet3 issues 2442, 4387), so an episode run after
    others would differ from the same episode in a fresh world; after a rebuild it does not."""

    ft_turn = None          # the wrist sensor's turn on its mount (3, 3), where the context has one (_build)

    def __init__(self, task="peg", clearance=1e-4, gui=False, ft_noise=True, image_noise=True, context=None):
        self.task, self.gui, self.base_clearance = task, gui, clearance
        self.context = context or Context()
        self.ft_noise, self.image_noise = ft_noise, image_noise
        self.noise_rng = np.random.default_rng(0)      # the sensors' noise; the env seeds it each episode
        self.f_drift = np.zeros(6)
        if gui and display_problem():            # else pybullet ends or hangs the process
            raise RuntimeError(f"PyBullet's window cannot open: {display_problem()}")
        with quiet_c_output():
            self.bc = bullet_client.BulletClient(p.GUI if gui else p.DIRECT)
        self.urdf, self.clearance = None, None
        self._build()

    def rebuild(self, ctx=None):
        """Empty the simulation and build the scene again, for context ctx (default: the same one)."""
        self.context = ctx or self.context
        self.bc.resetSimulation()
        self._build()

    def _build(self):
        bc, clearance = self.bc, self.context.clearance or self.base_clearance
        if clearance != self.clearance:          # the robot's file holds the gear's bore: a new one for a new clearance
            if self.urdf:
                os.remove(self.urdf)
            self.urdf, self.tip_offset = robot_urdf(self.task, clearance)      # a temporary file, removed by close
            self.clearance = clearance
        bc.setTimeStep(1.0 / PHYSICS_HZ)
        # The arm runs gravity-compensated, as a UR's own controller does, so its motors can be
        # torque-limited: full-strength velocity motors pressed 300 N spikes into the board and
        # bounced the admittance loop. With no free bodies in the scene nothing else needs gravity.
        bc.setGravity(0, 0, 0)
        # Contacts break after 1 mm, not Bullet's 20 mm, at which a cached point of a blade on the chamfer outlived
        # the blade sliding past it and held a centred peg 1 mm into the hole (README difference 12)
        bc.setPhysicsEngineParameter(numSolverIterations=50, enableFileCaching=0, contactBreakingThreshold=0.001,
                                     contactSlop=CONTACT_SLOP)
        if self.gui:
            bc.configureDebugVisualizer(p.COV_ENABLE_GUI, 0)
        ctx = self.context
        # table (top at z = 0) and the workcell on it
        self.table = self._compound([((0.6, 0.6, 0.02), (0.45, 0.0, -0.02), np.eye(3), ctx.table_rgba)])[0]
        self.workcell = self._compound([(he, c, np.eye(3), rgba) for he, c, rgba in WORKCELL])
        # robot with the task's tool
        with quiet_c_output():
            self.robot = bc.loadURDF(self.urdf, useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE)
        names = {bc.getJointInfo(self.robot, j)[12].decode(): j for j in range(bc.getNumJoints(self.robot))}
        self.arm = list(range(6))
        self.ft_joint, self.tool_link, self.cam_link = names["tool"], names["tool"], names["camera"]
        self.max_force = JOINT_TORQUE_CAP
        bc.enableJointForceTorqueSensor(self.robot, self.ft_joint, True)
        bc.changeDynamics(self.robot, self.tool_link, collisionMargin=0.0)   # (keeps TOOL_FRICTION: see BOARD_FRICTION)
        for j in self.arm:   # no default motors fighting ours
            bc.setJointMotorControl2(self.robot, j, p.VELOCITY_CONTROL, targetVelocity=0, force=self.max_force[j])
        self.plate, self.parts = self._build_board()
        if ctx.friction is not None:             # the pair's coefficient: Bullet multiplies the two bodies'
            for b in self.plate + [b for b, _ in self.parts]:
                bc.changeDynamics(b, -1, lateralFriction=ctx.friction / TOOL_FRICTION)
        self.objects = self._build_objects()
        # the camera's pose relative to the tip (one rigid body), from the arm as loaded: from the arm where an episode
        # left it, it would vary by 1e-7 m and make an episode depend on the episodes before it
        x0, s = self.tool_pose(), bc.getLinkState(self.robot, self.cam_link, computeForwardKinematics=True)
        self.cam_rel = (x0[1].T @ (np.array(s[4]) - x0[0]), x0[1].T @ matrix_from_quat(s[5]))
        self.f_bias = np.zeros(6)
        self.goal_yaw = 0.0
        self.ft_turn = ctl.rotvec_to_matrix(np.array(ctx.ft_mount)).T if ctx.ft_mount else None

    # -- scene construction -------------------------------------------------------------
    def _compound(self, parts, geom=p.GEOM_BOX):
        """Static bodies from [(size, pos, R, rgba)] shapes of one kind (boxes: size = half extents; spheres:
        size = radius), 16 shapes a body: pybullet 3.2.7 segfaults in createVisualShapeArray past 16
        shapes. Returns the list of body ids."""
        bc, bodies = self.bc, []
        for k in range(0, len(parts), 16):
            chunk = parts[k:k + 16]
            sizes = [pt[0] for pt in chunk]
            size = {"halfExtents": [list(x) for x in sizes]} if geom == p.GEOM_BOX else {"radii": sizes}
            pos = [list(pt[1]) for pt in chunk]
            orn = [quat_from_matrix(pt[2]) for pt in chunk]
            col = bc.createCollisionShapeArray([geom] * len(chunk), **size,
                                               collisionFramePositions=pos, collisionFrameOrientations=orn)
            vis = bc.createVisualShapeArray([geom] * len(chunk), **size, rgbaColors=[list(pt[3]) for pt in chunk],
                                            visualFramePositions=pos, visualFrameOrientations=orn)
            body = bc.createMultiBody(0, col, vis, [0, 0, 0])
            bc.changeDynamics(body, -1, lateralFriction=BOARD_FRICTION)
            bodies.append(body)
        return bodies

    def _build_board(self):
        """The task board in its own frame: origin on the board's top surface at the hole (shaft)
        axis, z up; X_g is expressed in this frame (goal_in_board). Returns (plate bodies, other
        bodies as [(body, z offset of its base)])."""
        t, board = BOARD_THICK, self.context.board_rgba
        if self.task == "peg":
            r_h = PEG_RADIUS + self.clearance / 2 - CONTACT_SLOP     # inscribed radius of the 16-gon hole
            plate = [(he, pos, R, board) for he, pos, R in plate_boxes(0.012, 0.12, -t, 0.0)]
            parts = [(he, pos, R, BLACK) for he, pos, R in ring_boxes(r_h, 0.012, -HOLE_DEPTH, -CHAMFER, 16)]
            shade = tuple(0.6 * c for c in board[:3]) + (1,)        # the chamfer: the board's plastic, darker
            parts += [(he, pos, R, shade) for he, pos, R in chamfer_boxes(r_h, CHAMFER, 16)]
            # the top ring reaches under the plate (its 20 mm outer radius against the 12 mm half-side
            # opening): coplanar tops, so it takes the plate's colour, or TinyRenderer z-fights them
            # into view-dependent stripes
            top_ring = ring_boxes(r_h + CHAMFER, 0.012 - CHAMFER, -CHAMFER, 0.0, 16)
            parts += [(he, pos, R, board) for he, pos, R in top_ring]
            parts.append(((0.02, 0.02, (t - HOLE_DEPTH) / 2), (0, 0, -(t + HOLE_DEPTH) / 2), np.eye(3), BLACK))
            bumps = board_bumps(r_h + CHAMFER + 3e-4, BUMPS, BUMP_H, BUMP_A, BUMP_R_MAX, BOARD_SEED)
            bumps = self._compound([(rho, c, np.eye(3), board) for rho, c in bumps], p.GEOM_SPHERE)   # plate's colour
            return self._compound(plate) + bumps, [(b, 0.0) for b in self._compound(parts)]
        # gear board: plate, fixed mating gear (hub + teeth, a gap facing the shaft), shaft body
        plate = [((0.06, 0.06, t / 2), (0, 0, -t / 2), np.eye(3), board)]
        c = GEAR_CENTRES
        teeth = gear_teeth(GEAR_R_ROOT, GEAR_R_TIP, TOOTH_WIDTH, GEAR_TEETH, 0.0, GEAR_THICK, phase=np.pi / GEAR_TEETH)
        parts = [(he, (pos[0] + c, pos[1], pos[2]), R, TEAL) for he, pos, R in teeth]
        hub = (GEAR_R_ROOT * 0.95, GEAR_R_ROOT * 0.95, GEAR_THICK / 2)
        parts.append((hub, (c, 0, GEAR_THICK / 2), np.eye(3), TEAL))
        bc = self.bc
        col = bc.createCollisionShape(p.GEOM_CYLINDER, radius=SHAFT_RADIUS, height=SHAFT_HEIGHT)
        vis = bc.createVisualShape(p.GEOM_CYLINDER, radius=SHAFT_RADIUS, length=SHAFT_HEIGHT, rgbaColor=DARK)
        shaft = bc.createMultiBody(0, col, vis, [0, 0, SHAFT_HEIGHT / 2])
        bc.changeDynamics(shaft, -1, collisionMargin=0.0)      # keeps URDF's 0.5, as the tool (see _build)
        return self._compound(plate), [(b, 0.0) for b in self._compound(parts)] + [(shaft, SHAFT_HEIGHT / 2)]

    def _build_objects(self):
        """The context's objects, where its board stands (a moved board leaves them in place)."""
        ctx = self.context
        if not ctx.objects:
            return []
        R_b = ctl.rot_z(ctx.board_yaw)
        base = np.array([*ctx.board_xy, BOARD_THICK if ctx.on_board else 0.0])
        return self._compound([(he, base + R_b @ np.array([dx, dy, he[2]]), R_b, rgba)
                               for he, (dx, dy), rgba in ctx.objects])

    # -- placement ------------------------------------------------------------------------
    def part_top(self):
        """Height above the board top of what the tool meets first: the board itself for the peg; the shaft
        (and the mating gear beside it) for the gear. X_i is the env's approach above it, so that even the largest
        z error starts the tool CLEAR of it (the solver's push-out throws a tool spawned into the shaft)."""
        return 0.0 if self.task == "peg" else max(SHAFT_HEIGHT, GEAR_THICK)

    def goal_in_board(self):
        """X_g in the board frame: the fully inserted tip position (hole bottom / shaft shoulder)."""
        return np.array([0.0, 0.0, -HOLE_DEPTH if self.task == "peg" else 0.0])

    def place(self, ctx, shift=np.zeros(4), approach=APPROACH):
        """Put the board where context `ctx` says, moved by shift = (dx, dy, dz, dyaw); returns the
        true goal X_g and pre-assembly point X_i (the tip `approach` above the part) as poses (p, R). A
        context other than the world's rebuilds the scene for it first."""
        bc = self.bc
        if ctx != self.context:
            self.rebuild(ctx)
        yaw = ctx.board_yaw + shift[3]
        R_b = ctl.rot_z(yaw) @ ctl.rotvec_to_matrix(np.array([*ctx.tilt, 0.0]))   # tilted about the axis's top
        top = np.array([ctx.board_xy[0] + shift[0], ctx.board_xy[1] + shift[1], BOARD_THICK + shift[2]])
        q = quat_from_matrix(R_b)
        for body, dz in [(b, 0.0) for b in self.plate] + self.parts:
            bc.resetBasePositionAndOrientation(body, (top + R_b @ [0, 0, dz]).tolist(), q)
        R_g = ctl.rot_z(yaw) @ R_DOWN            # the goal's orientation as the robot knows it: level
        p_g = top + R_b @ self.goal_in_board()
        p_i = top + np.array([0.0, 0.0, self.part_top() + approach])
        self.goal_yaw = yaw
        return (p_g, R_g), (p_i, R_g)

    # -- robot state ------------------------------------------------------------------------
    def tool_pose(self):
        """Tip pose X = (p, R) in world; tool z axis along the tool, pointing down."""
        s = self.bc.getLinkState(self.robot, self.tool_link, computeForwardKinematics=True)
        R = matrix_from_quat(s[5])
        return np.array(s[4]) + R[:, 2] * self.tip_offset, R

    def joint_positions(self):
        return np.array([s[0] for s in self.bc.getJointStates(self.robot, self.arm)])

    def jacobian(self, q):
        """6 x 6 geometric Jacobian at the tool tip (world axes). The tool link's centre of mass is
        its frame origin, so the local position is just the tip offset."""
        lin, ang = self.bc.calculateJacobian(self.robot, self.tool_link, [0, 0, self.tip_offset], q.tolist(),
                                             [0.0] * 6, [0.0] * 6)
        return np.vstack([np.array(lin), np.array(ang)])

    def raw_wrench(self):
        """Reaction of the fixed sensor joint: the wrench the tool exerts on the flange, at the sensor
        origin, in the tool frame (pybullet's joint frame for a fixed joint whose child frame is the
        tool link). Includes the tool's weight, removed by `tare`."""
        return np.array(self.bc.getJointState(self.robot, self.ft_joint)[2])

    def tare(self):
        """Zero the sensor (from a settled reading, as the sensor's own zeroing averages): the drift starts anew."""
        self.f_bias = self.raw_wrench()
        self.f_drift = np.zeros(6)

    def wrench_tool(self, raw):
        """One sensor reading: the wrench the environment exerts on the tool (F of Eq. 4), with the sensor's
        noise and drifting bias (in its own frame), moved to the tool tip, tool frame. The controller
        and the policy both see this reading."""
        w = -(raw - self.f_bias)
        if self.ft_turn is not None:            # a sensor turned on its mount reads the wrench in its own axes
            w = np.concatenate([self.ft_turn @ w[:3], self.ft_turn @ w[3:]])
        if self.ft_noise:
            self.f_drift += self.noise_rng.standard_normal(6) * FT_DRIFT * np.sqrt(1.0 / CONTROL_HZ)
            w = w + self.f_drift + self.noise_rng.standard_normal(6) * FT_NOISE
        f, tau = w[:3], w[3:]
        # tau_tip = tau - r x f with r = (0, 0, tip_offset) from the sensor origin to the tip
        # (written out: np.cross costs more than the rest of the tick's arithmetic)
        d = self.tip_offset
        w_tip = np.array([f[0], f[1], f[2], tau[0] + d * f[1], tau[1] - d * f[0], tau[2]])
        return np.clip(w_tip, -FT_RANGE, FT_RANGE)                     # the sensor's measuring range

    def move_to(self, x):
        """Teleport the arm so that the tip is at pose x (IK from the home pose, so deterministic)."""
        bc = self.bc
        p_t, R = x
        target = p_t - R[:, 2] * self.tip_offset
        q = list(ROBOT_HOME)
        for _ in range(3):
            for j, v in zip(self.arm, q):
                bc.resetJointState(self.robot, j, v, 0.0)
            q = bc.calculateInverseKinematics(self.robot, self.tool_link, target.tolist(), quat_from_matrix(R),
                                              maxNumIterations=200, residualThreshold=1e-9)[:6]
        for j, v in zip(self.arm, q):
            bc.resetJointState(self.robot, j, v, 0.0)

    def command(self, qdot):
        self.bc.setJointMotorControlArray(self.robot, self.arm, p.VELOCITY_CONTROL, targetVelocities=qdot.tolist(),
                                          forces=self.max_force)

    def tick(self, controller, t, f_tool, f_d):
        """One 120 Hz tick of the hybrid policy's controller (Eq. 6, a control.HybridPolicy): read the
        pose, feed the last wrench (tool frame, turned to world axes) and F_d to the admittance law,
        command the joint velocities, step physics. Returns the new wrench reading (tool frame, at the tip)."""
        x = self.tool_pose()
        qdot = controller(t, x, to_world(x[1], f_tool), f_d, self.jacobian(self.joint_positions()))
        self.command(qdot)
        return self.wrench_tool(self.step_physics(PHYSICS_PER_CONTROL))

    def step_physics(self, n):
        """n physics steps; returns the mean sensor reading over them (the sensor jitters step to step)."""
        acc = np.zeros(6)
        for _ in range(n):
            self.bc.stepSimulation()
            acc += self.raw_wrench()
        return acc / n

    # -- camera ----------------------------------------------------------------------------
    def camera_matrices(self, cam_pose=None):
        """View matrix (4, 4) of the eye-in-hand camera (optical axis = camera z, image up =
        camera -x) and the projection of the full 800 x 800 view; both as numpy, column vectors."""
        if cam_pose is None:
            s = self.bc.getLinkState(self.robot, self.cam_link, computeForwardKinematics=True)
            cam_pose = (np.array(s[4]), matrix_from_quat(s[5]))
        eye, R = cam_pose
        view = np.array(self.bc.computeViewMatrix(eye.tolist(), (eye + R[:, 2]).tolist(), (-R[:, 0]).tolist()))
        return view.reshape(4, 4).T

    def render_roi(self, roi, size=IMG):
        """Gray image (size, size) uint8 of the window roi = (u0, v0, u1, v1) of the full 800 x 800
        view, rendered directly (an off-centre frustum) rather than rendered large and cropped: the
        cost of TinyRenderer grows with the pixel count. The camera as mounted (the context's `camera`)
        renders it: roi is in the pixels of the true camera's image."""
        u0, v0, u1, v1 = roi
        h = CAM_NEAR * np.tan(np.radians(CAM_FOV / 2))
        left, right = (2 * u0 / CAM_FULL - 1) * h, (2 * u1 / CAM_FULL - 1) * h
        top, bottom = (1 - 2 * v0 / CAM_FULL) * h, (1 - 2 * v1 / CAM_FULL) * h
        if self.context.camera:            # intrinsics as mounted: focal length (1 + df) f, principal point + (du, dv)
            df, du, dv = self.context.camera[6:]
            s = h / (CAM_FULL / 2) / (1 + df)                  # m at the near plane per px
            left, right = (u0 - CAM_FULL / 2 - du) * s, (u1 - CAM_FULL / 2 - du) * s
            top, bottom = (CAM_FULL / 2 + dv - v0) * s, (CAM_FULL / 2 + dv - v1) * s
        proj = self.bc.computeProjectionMatrix(left, right, bottom, top, CAM_NEAR, CAM_FAR)
        view = self.camera_matrices(self.mounted_camera() if self.context.camera else None)
        img = self.bc.getCameraImage(size, size, view.T.flatten().tolist(), proj, renderer=p.ER_TINY_RENDERER,
                                     flags=p.ER_NO_SEGMENTATION_MASK, **dict(self.context.light))[2]
        rgb = np.asarray(img, np.uint8).reshape(size, size, 4)[:, :, :3].astype(np.float32)
        gray = rgb @ np.array(LUMA, np.float32)
        if self.image_noise:            # shot noise (E_PER_DN), then the 8-bit quantization
            gray = gray + np.sqrt(gray / E_PER_DN) * self.noise_rng.standard_normal(gray.shape).astype(np.float32)
            return np.clip(np.rint(gray), 0, 255).astype(np.uint8)
        return gray.astype(np.uint8)

    def mounted_camera(self):
        """The camera's true pose (eye, R) in world: the link's, the model's, moved by the context's mount error."""
        s = self.bc.getLinkState(self.robot, self.cam_link, computeForwardKinematics=True)
        eye, R = np.array(s[4]), matrix_from_quat(s[5])
        d = np.array(self.context.camera[:6])
        return eye + R @ d[:3], R @ ctl.rotvec_to_matrix(d[3:])

    def render_external(self):
        """An external RGB view (VIDEO_H, VIDEO_W, 3) uint8 of the task, for videos and rgb_array renders."""
        w, h = VIDEO_W, VIDEO_H
        tgt = self.bc.getBasePositionAndOrientation(self.plate[0])[0]
        view = self.bc.computeViewMatrixFromYawPitchRoll(tgt, 0.35, 50, -25, 0, 2)
        proj = self.bc.computeProjectionMatrixFOV(50, w / h, 0.01, 3)
        img = self.bc.getCameraImage(w, h, view, proj, renderer=p.ER_TINY_RENDERER, **dict(self.context.light))[2]
        return np.asarray(img, np.uint8).reshape(h, w, 4)[:, :, :3]

    def close(self):
        self.bc.disconnect()
        os.remove(self.urdf)



# ---------------------------------------------------------------- the camera's projection
def task_features(task):
    """3-D points (board frame) of the features the policy needs to see: the hole's rim, or the
    shaft's top and the mating gear's teeth near the mesh point."""
    a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    if task == "peg":
        r = PEG_RADIUS + CHAMFER
        return np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)], 1)
    shaft = np.stack([SHAFT_RADIUS * np.cos(a), SHAFT_RADIUS * np.sin(a), np.full_like(a, SHAFT_HEIGHT)], 1)
    mesh = np.array([[GEAR_CENTRES - GEAR_R_TIP * np.cos(b), GEAR_R_TIP * np.sin(b), GEAR_THICK] for b in (-0.6, 0.6)])
    return np.vstack([shaft, mesh])


def project(points, view, proj):
    """World points (n, 3) -> pixel coordinates (n, 2) (u right, v down) in the full 800 x 800 view."""
    ph = np.hstack([points, np.ones((len(points), 1))]) @ (proj @ view).T
    ndc = ph[:, :2] / ph[:, 3:4]
    return np.stack([(ndc[:, 0] + 1) / 2 * CAM_FULL, (1 - ndc[:, 1]) / 2 * CAM_FULL], 1)


def full_projection():
    h = CAM_NEAR * np.tan(np.radians(CAM_FOV / 2))
    return np.array(p.computeProjectionMatrix(-h, h, -h, h, CAM_NEAR, CAM_FAR)).reshape(4, 4).T

