"""The only module that imports PyBullet: the visible world of the drilling cell.

PyBullet (DIRECT mode, no GUI) holds the UR5 from ``example-robot-data``, the bone block inclined at
β and the drill on the flange. Joint compliance this stiff is unstable as explicit PyBullet springs
above ~0.1 ms steps, so the physics of the cell is the quasi-static model in :mod:`drillgym.envs.cell`; the
world mirrors its state (deflected joint angles, drill pose) for rendering and independent
kinematic cross-checks (PyBullet's own forward kinematics of the same URDF).
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import importlib
import math
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np

from drillgym.envs.robot.ur5 import R_BASE_BASELINK, ur5_urdf_path


def _import_pybullet_quietly() -> ModuleType:
    """Import PyBullet without its "pybullet build time" line, which its C code prints at import.

    Every command imports it (``--help`` included), and a user reading a command's output or its log
    should see the command's lines only.
    """
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no standard streams to silence (a daemon): import as is
        return importlib.import_module("pybullet")
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        module = importlib.import_module("pybullet")
        ctypes.CDLL(None).fflush(None)  # what the C code buffered goes to /dev/null too
    finally:
        for fd, copy in zip((1, 2), saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)
    return module


pb = _import_pybullet_quietly()

UR5_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)


@functools.cache
def pybullet_ur5_urdf(visual_meshes: bool = True) -> str:
    """A copy of the UR5 URDF with ``package://`` mesh paths resolved (PyBullet cannot resolve them).

    ``visual_meshes=False`` draws the links with their collision STL files, which load 3x faster
    but render flat: enough when nothing is rendered.
    """
    src = ur5_urdf_path()
    robots_dir = src.parents[2]  # .../example-robot-data/robots
    text = src.read_text()
    text = text.replace("package://example-robot-data/robots/", f"{robots_dir.as_posix()}/")
    if not visual_meshes:
        text = text.replace("/visual/", "/collision/").replace(".dae", ".stl")
    # Named by the content's digest (not ``hash``, which is salted per process): every process and run shares one
    # file per content, written once, atomically (a concurrent reader never sees half of it).
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    out = Path(tempfile.gettempdir()) / f"drillgym_ur5_{digest}.urdf"
    if not out.exists():
        fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=out.stem, suffix=".part")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, out)
    return str(out)


def quat_xyzw_from_matrix(rot: np.ndarray) -> np.ndarray:
    """PyBullet quaternion (x, y, z, w) of a 3x3 rotation matrix."""
    m = np.asarray(rot, dtype=float)
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2.0
    x = math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2.0
    y = math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2.0
    z = math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2.0
    x = math.copysign(x, m[2, 1] - m[1, 2])
    y = math.copysign(y, m[0, 2] - m[2, 0])
    z = math.copysign(z, m[1, 0] - m[0, 1])
    return np.array([x, y, z, w])


class PyBulletWorld:
    """A PyBullet DIRECT client with the UR5, the bone block and the drill. Frames: UR ``base``."""

    def __init__(self, visual_meshes: bool = True) -> None:
        self.client = pb.connect(pb.DIRECT)
        self.robot = pb.loadURDF(
            pybullet_ur5_urdf(visual_meshes),
            useFixedBase=True,
            flags=pb.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=self.client,
        )
        self.joint_index: dict[str, int] = {}
        self.link_index: dict[str, int] = {}
        for i in range(pb.getNumJoints(self.robot, physicsClientId=self.client)):
            info = pb.getJointInfo(self.robot, i, physicsClientId=self.client)
            self.joint_index[info[1].decode()] = i
            self.link_index[info[12].decode()] = i
        self.joints = [self.joint_index[n] for n in UR5_JOINTS]
        self.bone: int | None = None
        self.spindle: int | None = None
        self.drill: int | None = None
        self.visual_meshes = visual_meshes
        self.floor: int | None = None
        self.stand: int | None = None

    # frames: PyBullet's world is the URDF base_link; UR base = base_link turned by pi about z.
    @staticmethod
    def _to_world(p_base: np.ndarray) -> np.ndarray:
        return R_BASE_BASELINK.T @ np.asarray(p_base, dtype=float)

    @staticmethod
    def _to_base(p_world: np.ndarray) -> np.ndarray:
        return R_BASE_BASELINK @ np.asarray(p_world, dtype=float)

    def set_joint_angles(self, q_rad: np.ndarray) -> None:
        """Put the arm at ``q_rad`` (kinematic reset, no dynamics)."""
        for j, q in zip(self.joints, q_rad, strict=True):
            pb.resetJointState(self.robot, j, float(q), physicsClientId=self.client)

    def link_pose_base(self, link: str) -> np.ndarray:
        """``T_base_link`` (4x4) from PyBullet's own forward kinematics."""
        state = pb.getLinkState(
            self.robot, self.link_index[link], computeForwardKinematics=True, physicsClientId=self.client
        )
        t = np.eye(4)
        rot = np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)
        t[:3, :3] = R_BASE_BASELINK @ rot
        t[:3, 3] = self._to_base(np.array(state[4]))
        return t

    def place_bone(self, T_base_task: np.ndarray, beta_rad: float, size_m: float = 0.06) -> None:
        """A bone block whose top face passes through the entry point, inclined by β about task y.

        The block is created once and moved for later scenarios (no PyBullet shapes pile up).
        """
        half = [size_m / 2, size_m / 3, size_m / 6]
        # Block frame: task frame turned by -beta about y, so its top face is z_task = -x_task tan(beta).
        c, s = math.cos(beta_rad), math.sin(beta_rad)
        r_task_block = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
        r_base_block = T_base_task[:3, :3] @ r_task_block
        centre_base = T_base_task[:3, 3] + r_base_block @ np.array([0.0, 0.0, half[2]])
        position = self._to_world(centre_base).tolist()
        orientation = quat_xyzw_from_matrix(R_BASE_BASELINK.T @ r_base_block).tolist()
        if self.bone is None:
            vis = pb.createVisualShape(
                pb.GEOM_BOX, halfExtents=half, rgbaColor=[0.93, 0.88, 0.75, 1], physicsClientId=self.client
            )
            col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=self.client)
            self.bone = pb.createMultiBody(0, col, vis, position, orientation, physicsClientId=self.client)
        else:
            pb.resetBasePositionAndOrientation(self.bone, position, orientation, physicsClientId=self.client)
        if self.visual_meshes:
            corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.asarray(half)
            lowest_m = float((centre_base + corners @ r_base_block.T)[:, 2].min())
            self._place_stand(centre_base, lowest_m)

    STAND_HALF_HEIGHT_M = 0.15
    """The stand is one fixed box moved so that its top meets the bone; what reaches below the floor is hidden."""

    def _place_stand(self, bone_centre_base: np.ndarray, top_m: float) -> None:
        """Draw the floor (the robot's mounting plane, base z = 0) and a stand up to ``top_m`` under the bone.

        Visual only, made once and moved: the arm is driven kinematically, so nothing collides with them.
        """
        if self.floor is None:
            self.floor = self._box([0.9, 0.9, 0.002], [0.80, 0.80, 0.82, 1.0])
            floor_centre = self._to_world(np.array([-0.3, 0.0, -0.002])).tolist()
            pb.resetBasePositionAndOrientation(self.floor, floor_centre, [0, 0, 0, 1], physicsClientId=self.client)
            self.stand = self._box([0.05, 0.04, self.STAND_HALF_HEIGHT_M], [0.45, 0.47, 0.52, 1.0])
        centre = np.array([bone_centre_base[0], bone_centre_base[1], top_m - self.STAND_HALF_HEIGHT_M])
        pb.resetBasePositionAndOrientation(
            self.stand, self._to_world(centre).tolist(), [0, 0, 0, 1], physicsClientId=self.client
        )

    def _box(self, half_extents_m: list[float], rgba: list[float]) -> int:
        vis = pb.createVisualShape(pb.GEOM_BOX, halfExtents=half_extents_m, rgbaColor=rgba, physicsClientId=self.client)
        return int(pb.createMultiBody(0, -1, vis, physicsClientId=self.client))

    def place_drill(self, T_base_flange: np.ndarray, spindle_m: float, stickout_m: float, diameter_m: float) -> None:
        """Draw the spindle (flange to chuck) and the drill (chuck to tip) along the flange z axis."""
        if self.drill is None:
            self.spindle = self._cylinder(0.02, spindle_m, [0.3, 0.3, 0.32, 1.0])
            self.drill = self._cylinder(diameter_m / 2, stickout_m, [0.85, 0.75, 0.3, 1.0])
        z = T_base_flange[:3, 2]
        quat = quat_xyzw_from_matrix(R_BASE_BASELINK.T @ T_base_flange[:3, :3]).tolist()
        for body, start, length in ((self.spindle, 0.0, spindle_m), (self.drill, spindle_m, stickout_m)):
            centre = T_base_flange[:3, 3] + z * (start + length / 2)
            pb.resetBasePositionAndOrientation(body, self._to_world(centre).tolist(), quat, physicsClientId=self.client)

    def _cylinder(self, radius_m: float, length_m: float, rgba: list[float]) -> int:
        vis = pb.createVisualShape(
            pb.GEOM_CYLINDER, radius=radius_m, length=length_m, rgbaColor=rgba, physicsClientId=self.client
        )
        return int(pb.createMultiBody(0, -1, vis, physicsClientId=self.client))

    CAMERA_DISTANCE_M = 0.85
    CAMERA_YAW_DEG, CAMERA_PITCH_DEG = 35.0, -20.0

    def render(self, target_base: np.ndarray, width: int = 320, height: int = 240) -> np.ndarray:
        """An RGB image (H, W, 3) uint8 of the whole arm and the drill at ``target_base`` (m, base); headless.

        The camera looks at a point 0.6 of the way from the robot's base to the target, 0.2 m up, so the arm
        is not cropped and the drill stays in view.
        """
        target = self._to_world(0.6 * np.asarray(target_base, dtype=float) + np.array([0.0, 0.0, 0.2]))
        view = pb.computeViewMatrixFromYawPitchRoll(
            target.tolist(),
            self.CAMERA_DISTANCE_M,
            self.CAMERA_YAW_DEG,
            self.CAMERA_PITCH_DEG,
            0.0,
            2,
            physicsClientId=self.client,
        )
        proj = pb.computeProjectionMatrixFOV(50.0, width / height, 0.01, 5.0, physicsClientId=self.client)
        img = pb.getCameraImage(width, height, view, proj, renderer=pb.ER_TINY_RENDERER, physicsClientId=self.client)
        rgba = np.reshape(np.asarray(img[2], dtype=np.uint8), (height, width, 4))
        return rgba[:, :, :3].copy()

    def torque_mode(self, time_step_s: float = 1e-3) -> Callable[[], None]:
        """Switch the arm to torque control (velocity motors off, zero torque) with ``time_step_s`` steps.

        Returns a function that advances PyBullet's dynamics by one step: the reference cost for
        ``drillgym bench-speed`` (a bare PyBullet step of the same UR5; the cell itself never steps it).
        """
        pb.setTimeStep(time_step_s, physicsClientId=self.client)
        zero = [0.0] * len(self.joints)
        pb.setJointMotorControlArray(
            self.robot, self.joints, pb.VELOCITY_CONTROL, forces=zero, physicsClientId=self.client
        )
        pb.setJointMotorControlArray(
            self.robot, self.joints, pb.TORQUE_CONTROL, forces=zero, physicsClientId=self.client
        )
        return functools.partial(pb.stepSimulation, physicsClientId=self.client)

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        if self.client >= 0 and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = -1
