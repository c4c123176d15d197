"""Off-screen frames of the simulator (``render_mode="rgb_array"``): the camera, translucency, the reference markers.

A headless (``DIRECT``) PyBullet client draws with its TinyRenderer, which differs from the GUI in two ways that
matter here [D]:

* It draws every visual opaque, except that it skips a visual whose alpha is 0. The hull is translucent in the
  URDF (alpha 0.35, the frame plates 0.8) because the arm bay, the shoulders and the circle references lie inside
  its box; drawn opaque it hides them. :func:`render_frame` therefore composes each frame from two passes: one
  with every translucent visual hidden (alpha 0) and one with all of them shown, mixed with the visual's alpha
  where a translucent visual is the nearest surface (the second pass's segmentation mask). One layer is composed:
  where two translucent visuals overlap, the nearer one is mixed over the opaque scene and the farther one is lost.
* It does not draw debug lines (``addUserDebugLine``). The task's reference is drawn with visual-only bodies
  (:class:`ReferenceMarkers`): a visual shape, no collision shape, mass 0 (a fixed base), nothing attached. Such a
  body takes part in no contact, closest-point query or constraint, so the physics, the distances and the
  observations are the same bit for bit with and without rendering (``tests/uvdms_gym/physics/test_render_markers.py``).
  They exist only in a simulator that an ``rgb_array`` environment has rendered (created at its first frame).

What is drawn (:class:`ReferenceScene`, built by the environment in NED): the reference paths as magenta tubes
(:data:`PATH_RGBA`), the current reference points as cyan balls (:data:`POINT_RGBA`), and the transport goal as a
translucent green copy of the object (:data:`GOAL_RGBA`). Obstacles are the simulator's own bodies (red,
:data:`~uvdms_gym.physics.obstacle_bodies.OBSTACLE_RGBA`).

Camera [D] (:func:`camera_matrices`): it turns with the vehicle's heading, looks down by :data:`CAMERA_PITCH_DEG`
from :data:`CAMERA_YAW_OFFSET_DEG` off its heading (the front-right quarter; :data:`FRONT_CAMERA_YAW_OFFSET_DEG`,
nearly in front, for the circle tasks, whose circles face forward), with a vertical field of view of
:data:`CAMERA_FOV_DEG`. It aims at the centre of the box around the body origin and the drawn reference, from
:data:`CAMERA_DISTANCE` or farther if that box (grown by :data:`FRAME_MARGIN`) would not fit: the vehicle and the
whole reference stay in the frame (tested at the default 320 x 240). Without a reference (a bare simulator) it
aims at the body origin from :data:`CAMERA_DISTANCE`. The circles lie within 0.5 m of the origin, so their frames are
taken from :data:`CAMERA_DISTANCE`; the paper's transport path rises 2 m, so its frames are taken from about 4 m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pybullet as pb

from uvdms_gym.physics import frames
from uvdms_gym.physics.obstacle_bodies import axis_quaternion
from uvdms_gym.physics.params import ObjectParams

CAMERA_DISTANCE = 2.5
"""Distance of the camera from the vehicle's body origin, m."""
CAMERA_YAW_OFFSET_DEG = 45.0
"""Default camera yaw (PyBullet's, about the world's up axis) relative to the vehicle's heading, degrees: the camera
stands in the front-right quarter (starboard, ahead), the transport's object and path seen obliquely."""
FRONT_CAMERA_YAW_OFFSET_DEG = 75.0
"""Camera yaw of the circle tasks, degrees: nearly in front (15 degrees to starboard), so that the circles (in the
vehicle's y-z plane) are seen nearly face-on and the arms' crossing (Case 1 and 2) is not seen edge-on."""
CAMERA_PITCH_DEG = -25.0
"""Camera pitch: negative looks down, degrees."""
CAMERA_FOV_DEG = 60.0
"""Vertical field of view, degrees."""
CAMERA_NEAR, CAMERA_FAR = 0.05, 50.0
"""Near and far clipping planes, m."""
FRAME_MARGIN = 0.6
"""What the camera frames reaches this far beyond the box of the body origin and the reference, m (the hull's
corners are 0.6 m from the origin)."""
Z_UP_AXIS = 2
"""PyBullet's index of the world's up axis (z) for ``computeViewMatrixFromYawPitchRoll``."""

PATH_RGBA = (1.0, 0.0, 1.0, 1.0)
"""Reference paths (the circles, the object's path): magenta."""
POINT_RGBA = (0.0, 0.85, 1.0, 1.0)
"""The current reference points (end effectors' or the object centre's): cyan."""
GOAL_RGBA = (0.1, 0.9, 0.2, 0.55)
"""The object's goal pose: a translucent green copy of the object."""
PATH_RADIUS = 0.008
"""Radius of the path tubes, m (at 320 x 240 a pixel spans about 1.2 cm at the vehicle)."""
PATH_SEGMENT = 0.03
"""Length of one tube segment, m: a path is resampled at this arc-length step."""
POINT_RADIUS = 0.03
"""Radius of a reference point's ball, m (larger than the arm links' 0.025 m, so that it shows around a tracking
end effector)."""
SEGMENTATION_LINK_SHIFT = 24
"""PyBullet's segmentation value with link indices: ``body + ((link + 1) << 24)``."""
_CYLINDER_ALONG_Y = frames.rot_to_quat_xyzw(frames.euler_to_rot(np.array([math.pi / 2, 0.0, 0.0]))).tolist()
"""The object URDF's visual origin (:func:`~uvdms_gym.physics.model.build_object_urdf`): PyBullet's cylinder lies
along its local z, the object's axis is its y."""
_ORIGIN = (0.0, 0.0, 0.0)
_IDENTITY = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class ReferenceScene:
    """What a frame draws of a task's reference, NED/SI (built by the environment for every frame).

    Attributes:
        paths: reference paths, each ``(N, 3)`` NED points of a polyline (a closed one repeats its first point).
        points: the current reference points ``(K, 3)``, NED.
        goal: the object's goal pose ``(position NED (3), R_N,object (3, 3))``, or ``None``.
    """

    paths: tuple[np.ndarray, ...] = ()
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    goal: tuple[np.ndarray, np.ndarray] | None = None

    def static_points(self) -> np.ndarray:
        """``(N, 3)`` NED points of the paths and the goal position (what the camera keeps in view)."""
        goal = () if self.goal is None else (np.asarray(self.goal[0], dtype=float).reshape(1, 3),)
        return np.vstack([np.zeros((0, 3)), *self.paths, *goal])

    def same_static(self, other: ReferenceScene | None) -> bool:
        """Whether ``other`` has the same paths and goal (the points may differ)."""
        if other is None or len(self.paths) != len(other.paths) or (self.goal is None) != (other.goal is None):
            return False
        if not all(np.array_equal(a, b) for a, b in zip(self.paths, other.paths)):
            return False
        return self.goal is None or all(np.array_equal(a, b) for a, b in zip(self.goal, other.goal))


def resample_path(points: np.ndarray, step: float) -> np.ndarray:
    """Points at equal arc-length steps (at most ``step``) along a polyline, both ends included.

    Args:
        points: ``(N, 3)`` polyline.
        step: the largest distance between consecutive output points.

    Returns:
        ``(M, 3)`` points; the first point alone for a path of zero length.
    """
    pts = np.asarray(points, dtype=float)
    arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    if arc[-1] <= 0.0:
        return pts[:1]
    grid = np.linspace(0.0, arc[-1], math.ceil(arc[-1] / step) + 1)
    return np.column_stack([np.interp(grid, arc, pts[:, k]) for k in range(3)])


class ReferenceMarkers:
    """The visual-only bodies that draw a :class:`ReferenceScene` in one PyBullet client.

    Args:
        client: the simulator's ``BulletClient``.
        obj: the object's dimensions (the goal is drawn as a copy of it).
    """

    def __init__(self, client, obj: ObjectParams) -> None:
        self._client = client
        self._obj = obj
        self._scene: ReferenceScene | None = None
        self._static_ids: list[int] = []
        self._point_ids: list[int] = []
        self._keep_in_view: np.ndarray | None = None

    @property
    def keep_in_view(self) -> np.ndarray | None:
        """The drawn scene's :meth:`ReferenceScene.static_points` (``None`` before the first :meth:`show`)."""
        return self._keep_in_view

    @property
    def body_ids(self) -> tuple[int, ...]:
        """PyBullet ids of every marker body."""
        return (*self._static_ids, *self._point_ids)

    def show(self, scene: ReferenceScene) -> None:
        """Draw ``scene``: rebuild the paths and the goal when they changed, move the points."""
        if not scene.same_static(self._scene):
            self._remove(self._static_ids)
            self._static_ids = [*self._path_bodies(scene.paths), *self._goal_bodies(scene.goal)]
            self._keep_in_view = scene.static_points()
        points = np.asarray(scene.points, dtype=float).reshape(-1, 3)
        if len(points) != len(self._point_ids):
            self._remove(self._point_ids)
            self._point_ids = [self._body(self._sphere(POINT_RADIUS, POINT_RGBA)) for _ in points]
        for body, p in zip(self._point_ids, frames.ned_to_world(points).tolist()):
            self._client.resetBasePositionAndOrientation(body, p, _IDENTITY)
        self._scene = scene

    def _remove(self, ids: list[int]) -> None:
        for body in ids:
            self._client.removeBody(body)
        ids.clear()

    def _body(self, visual: int, position: Sequence[float] = _ORIGIN, quat: Sequence[float] = _IDENTITY) -> int:
        """A visual-only body: no collision shape, mass 0 (fixed)."""
        return self._client.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=visual,
            basePosition=list(position),
            baseOrientation=list(quat),
        )

    def _sphere(self, radius: float, rgba: Sequence[float]) -> int:
        return self._client.createVisualShape(pb.GEOM_SPHERE, radius=radius, rgbaColor=list(rgba))

    def _path_bodies(self, paths: Sequence[np.ndarray]) -> list[int]:
        """One tube segment (a capsule of :data:`PATH_RADIUS`) per resampled step of each path."""
        ids = []
        for path in paths:
            pts = resample_path(path, PATH_SEGMENT)
            if len(pts) < 2:
                continue
            steps = np.diff(pts, axis=0)  # chords of equal arc-length steps (shorter only across a corner)
            lengths = np.linalg.norm(steps, axis=1)
            visual = self._client.createVisualShape(
                pb.GEOM_CAPSULE, radius=PATH_RADIUS, length=float(lengths.max()), rgbaColor=list(PATH_RGBA)
            )
            for a, d in zip(pts[:-1][lengths > 0.0], steps[lengths > 0.0]):
                ids.append(self._body(visual, frames.ned_to_world(a + 0.5 * d).tolist(), axis_quaternion(d)))
        return ids

    def _goal_bodies(self, goal: tuple[np.ndarray, np.ndarray] | None) -> list[int]:
        """A copy of the object (its cylinder, no collision) at the goal pose."""
        if goal is None:
            return []
        p, r_no = goal
        visual = self._client.createVisualShape(
            pb.GEOM_CYLINDER,
            radius=self._obj.radius,
            length=self._obj.length,
            rgbaColor=list(GOAL_RGBA),
            visualFrameOrientation=_CYLINDER_ALONG_Y,
        )
        quat = frames.rot_to_quat_xyzw(frames.body_rot_ned_to_world(np.asarray(r_no, dtype=float)))
        return [self._body(visual, frames.ned_to_world(p).tolist(), quat.tolist())]


def camera_matrices(
    client,
    eta: np.ndarray,
    width: int,
    height: int,
    keep_in_view: np.ndarray | None = None,
    yaw_offset_deg: float = CAMERA_YAW_OFFSET_DEG,
) -> tuple[Sequence[float], Sequence[float]]:
    """PyBullet's view and projection matrices of the camera that follows the vehicle (module docstring).

    The camera aims at the centre of the box around the body origin and ``keep_in_view``, from
    :data:`CAMERA_DISTANCE` or farther: far enough that a ball around that box, :data:`FRAME_MARGIN` larger, fits
    the field of view. Without ``keep_in_view`` it aims at the body origin from :data:`CAMERA_DISTANCE`.

    Args:
        client: the ``BulletClient``.
        eta: the vehicle's pose (NED, ZYX Euler).
        width: image width, pixels.
        height: image height, pixels.
        keep_in_view: ``(N, 3)`` NED points to frame with the vehicle (the reference's paths and goal).
        yaw_offset_deg: the camera's yaw relative to the vehicle's heading, degrees.

    Returns:
        ``(view, projection)``.
    """
    pts = eta[None, :3] if keep_in_view is None else np.vstack([eta[None, :3], keep_in_view])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    half_v = math.radians(CAMERA_FOV_DEG) / 2.0
    half_fov = min(half_v, math.atan(math.tan(half_v) * width / height))
    radius = 0.5 * float(np.linalg.norm(hi - lo)) + FRAME_MARGIN
    distance = max(CAMERA_DISTANCE, radius / math.sin(half_fov))
    target = frames.ned_to_world(0.5 * (lo + hi)).tolist()
    yaw = yaw_offset_deg + math.degrees(-eta[5])  # NED yaw turns about the down axis, PyBullet's about up
    view = client.computeViewMatrixFromYawPitchRoll(target, distance, yaw, CAMERA_PITCH_DEG, 0.0, Z_UP_AXIS)
    proj = client.computeProjectionMatrixFOV(CAMERA_FOV_DEG, width / height, CAMERA_NEAR, CAMERA_FAR)
    return view, proj


def translucent_visuals(client) -> list[tuple[int, int, tuple[float, ...]]]:
    """Every visual with an alpha strictly between 0 and 1: ``(body, link, rgba)``."""
    out = []
    for i in range(client.getNumBodies()):
        body = client.getBodyUniqueId(i)
        for shape in client.getVisualShapeData(body):
            rgba = tuple(shape[7])
            if 0.0 < rgba[3] < 1.0:
                out.append((body, shape[1], rgba))
    return out


def _camera_pass(client, size: tuple[int, int], view, proj, segmentation: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """One TinyRenderer pass: the ``(H, W, 3)`` image (float) and, if asked, the ``(H, W)`` segmentation mask."""
    width, height = size
    flags = pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX if segmentation else pb.ER_NO_SEGMENTATION_MASK
    img = client.getCameraImage(width, height, view, proj, renderer=pb.ER_TINY_RENDERER, flags=flags)
    rgb = np.reshape(np.asarray(img[2], dtype=np.uint8), (height, width, 4))[:, :, :3].astype(float)
    return rgb, np.reshape(np.asarray(img[4]), (height, width)) if segmentation else None


def render_frame(client, view, proj, width: int, height: int) -> np.ndarray:
    """An ``(height, width, 3)`` uint8 image with the translucent visuals composed (module docstring)."""
    size = (int(width), int(height))
    translucent = translucent_visuals(client)
    shown, seg = _camera_pass(client, size, view, proj, segmentation=bool(translucent))
    if seg is None:
        return np.ascontiguousarray(shown.astype(np.uint8))
    for body, link, rgba in translucent:
        client.changeVisualShape(body, link, rgbaColor=[*rgba[:3], 0.0])
    try:
        hidden, _ = _camera_pass(client, size, view, proj, segmentation=False)
    finally:
        for body, link, rgba in translucent:
            client.changeVisualShape(body, link, rgbaColor=list(rgba))
    alpha = np.zeros(seg.shape)
    for body, link, rgba in translucent:
        alpha[seg == body + ((link + 1) << SEGMENTATION_LINK_SHIFT)] = rgba[3]
    out = hidden + alpha[:, :, None] * (shown - hidden)
    return np.ascontiguousarray(np.rint(out).astype(np.uint8))
