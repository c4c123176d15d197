"""Contact counts of a simulator: robot link pairs, and robot parts against outer obstacles (:class:`ContactMonitor`).

Without simulated self-collision the links pass through each other and a contact is *reported*: each pair is one
``getClosestPoints`` query with a zero distance threshold (about 2 µs a pair). With it
(``UVDMSSim(self_collision=True)``), the pairs are read from the contact manifold PyBullet builds during each
physics step; after a reset, before any step, one ``performCollisionDetection`` builds it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import pybullet as pb
from pybullet_utils.bullet_client import BulletClient

from uvdms_gym.physics.body import LoadedBody
from uvdms_gym.physics.params import ARM_SIDES, UVDMSParams

_closest_points = pb.getClosestPoints
_contact_points = pb.getContactPoints
_perform_collision_detection = pb.performCollisionDetection


class ContactMonitor:
    """Counts touching pairs of one simulator's bodies.

    Args:
        client: the simulator's ``BulletClient``.
        robot: the UVDMS multibody (its id, link indices, and joints: none for the bare vehicle).
        params: the physical parameters (the plates and the number of arm links).
        self_collision: whether contacts between robot links are simulated (read from the contact manifold).

    Attributes:
        needs_pass: the contact manifold is stale (set after a reset; a physics step builds it and clears this).
    """

    def __init__(self, client: BulletClient, robot: LoadedBody, params: UVDMSParams, *, self_collision: bool) -> None:
        self._cid: int = client._client
        self._body = robot.body
        self._link_index = robot.link_index
        self._params = params
        self._arms = bool(robot.joints)
        self._self_collision = self_collision
        self._pairs: set[tuple[int, int]] = set()
        self.needs_pass = True

    def _monitored(self) -> set[tuple[int, int]]:
        """Right-arm vs left-arm links and arm links 1-6 vs frame plates (link-index pairs, built once)."""
        if not self._pairs:
            li = self._link_index
            plates = [li[f"plate_{pl.name}"] for pl in self._params.plates]
            n = self._params.arm.n_links if self._arms else 0
            monitored = {(li[f"right_link{i}"], li[f"left_link{j}"]) for i in range(n) for j in range(n)}
            monitored |= {(li[f"{s}_link{i}"], p) for s in ARM_SIDES for i in range(1, n) for p in plates}
            self._pairs = monitored
        return self._pairs

    def count(self, pairs: Sequence[tuple[str, str]] | None = None) -> int:
        """Number of touching robot-part pairs (PyBullet's closest-point or contact report).

        Args:
            pairs: link-name pairs to check (e.g. the pairs whose exact distance is near contact); default: all
                monitored pairs, i.e. right-arm vs left-arm links and arm links 1-6 vs frame plates (97 pairs,
                the pairs the 18 distances of docs/MODEL.md section 4 watch).
        """
        li, b, cid = self._link_index, self._body, self._cid
        if pairs is None:
            idx = self._monitored()
        else:
            try:
                idx = {(li[a], li[c]) for a, c in pairs}
            except KeyError as exc:
                raise ValueError(f"unknown link name {exc.args[0]!r} in pairs") from None
        if not self._self_collision:
            return sum(1 for a, c in idx if _closest_points(b, b, 0.0, a, c, physicsClientId=cid))
        if self.needs_pass:
            _perform_collision_detection(cid)
            self.needs_pass = False
        both = idx | {(c, a) for a, c in idx}
        touching = {(cp[3], cp[4]) for cp in _contact_points(b, b, physicsClientId=cid) if cp[8] <= 0.0} & both
        return len({tuple(sorted(pair)) for pair in touching})

    def count_obstacles(
        self, pairs: Sequence[tuple[str, int]], obstacle_ids: Sequence[int], object_id: Callable[[], int]
    ) -> int:
        """Number of touching (robot part, obstacle) pairs (one zero-distance ``getClosestPoints`` each).

        Args:
            pairs: ``(part, k)``: a link name (``"vehicle"``: the hull) or ``"object"``, and an obstacle's index.
            obstacle_ids: PyBullet body ids of the obstacles.
            object_id: returns the gripped object's id (called only for ``"object"`` parts; raises without one).
        """
        cid, n = self._cid, 0
        for part, k in pairs:
            body, link = (object_id(), -1) if part == "object" else (self._body, self._link_index[part])
            n += bool(_closest_points(body, obstacle_ids[k], 0.0, link, -1, physicsClientId=cid))
        return n
