"""The 18 distances from PyBullet closest-point queries, the third method cross-checked against the exact one.

Split from :mod:`uvdms_gym.distances` (same row layout and axis/core convention, same :class:`DistanceResult`).
"""

from __future__ import annotations

import numpy as np

from uvdms_gym.distances.exact import _LEFT_FRAMES, _PLATE_ROWS_FRAMES, LINK_FRAMES, N_ROWS, DistanceResult
from uvdms_gym.physics import frames


def pybullet_distances(client, body_id: int, link_index: dict[str, int], params, max_distance: float = 1.0):
    """The 18 distances from PyBullet closest-point queries on a loaded UVDMS multibody.

    The body is the URDF of :func:`uvdms_gym.physics.model.build_urdf` (loaded with ``URDF_USE_INERTIA_FROM_FILE``). One
    ``getClosestPoints(bodyA=b, bodyB=b, linkIndexA=i, linkIndexB=j)`` per candidate pair (42 link-link, 48
    link-plate; queries within one body work, independent of the self-collision flags). PyBullet reports surface
    distances and surface points in its z-up world; they are converted to NED
    (:func:`uvdms_gym.physics.frames.world_to_ned`) and to the axis/core convention: ``d = d_surface + 2 r``
    (link-link),
    ``d_surface + r + t/2`` (link-plate), ``P = P_s + r n_B``, ``E = E_s - rho n_B`` (``n_B`` PyBullet's normal from
    B to A, ``rho`` the obstacle's core offset). URDF capsule ``length`` is the distance between the cap centres
    (measured), so the axis is exactly :func:`uvdms_gym.physics.model.link_segment`. The plates' collision shape is the
    rectangle swept by a ball of radius ``t/2`` (a box plus four edge capsules, see ``model.build_urdf``), so
    ``d_surface + r + t/2`` equals the exact core distance everywhere, including near plate edges.

    Args:
        client: a ``pybullet_utils.bullet_client.BulletClient``, or an ``int`` physics client id.
        body_id: the UVDMS body.
        link_index: PyBullet link index per link name (``"right_link3"``, ``"left_link0"``,
            ``"plate_front"``...).
        params: :class:`uvdms_gym.physics.params.UVDMSParams` (radius, plate thickness).
        max_distance: surface distance beyond which PyBullet reports nothing; a row with no pair within it
            gets ``d = inf`` and NaN points.

    Returns:
        :class:`DistanceResult` with ``method="pybullet"``.
    """
    if isinstance(client, (int, np.integer)):
        import pybullet

        cid = int(client)

        def closest(a, b, i, j):
            return pybullet.getClosestPoints(a, b, max_distance, i, j, physicsClientId=cid)
    else:

        def closest(a, b, i, j):
            return client.getClosestPoints(a, b, max_distance, i, j)

    r = params.arm.link_radius
    plates = [(link_index[f"plate_{pl.name}"], 0.5 * pl.thickness) for pl in params.plates]
    d = np.full(N_ROWS, np.inf)
    pw = np.full((N_ROWS, 3), np.nan)
    ew = np.full((N_ROWS, 3), np.nan)
    idx = np.zeros(N_ROWS, dtype=int)

    def scan(row, link_a, obstacles):
        ia = link_index[link_a]
        for k, (ib, rho) in enumerate(obstacles):
            for cp in closest(body_id, body_id, ia, ib):
                dist = cp[8] + r + rho
                if dist < d[row]:
                    nb = cp[7]
                    d[row] = dist
                    pw[row] = [cp[5][i] + r * nb[i] for i in range(3)]
                    ew[row] = [cp[6][i] - rho * nb[i] for i in range(3)]
                    idx[row] = k

    left = [(link_index[f], r) for f in _LEFT_FRAMES]
    for k in range(6):
        scan(k, f"right_link{k + 1}", left)
        scan(6 + k, f"right_link{k + 1}", plates)
        scan(12 + k, f"left_link{k + 1}", plates)
    obst = tuple(_LEFT_FRAMES[j] for j in idx[:6]) + _PLATE_ROWS_FRAMES
    return DistanceResult(d, frames.world_to_ned(pw), frames.world_to_ned(ew), obst, LINK_FRAMES, idx, "pybullet")


def pybullet_link_indices(client, body_id: int) -> dict[str, int]:
    """Map every link name of a PyBullet body to its link index (the base link gets -1).

    Args:
        client: a ``BulletClient`` or an ``int`` physics client id.
        body_id: the body.
    """
    if isinstance(client, (int, np.integer)):
        import pybullet

        cid = int(client)
        n = pybullet.getNumJoints(body_id, physicsClientId=cid)
        infos = [pybullet.getJointInfo(body_id, i, physicsClientId=cid) for i in range(n)]
        base = pybullet.getBodyInfo(body_id, physicsClientId=cid)[0]
    else:
        n = client.getNumJoints(body_id)
        infos = [client.getJointInfo(body_id, i) for i in range(n)]
        base = client.getBodyInfo(body_id)[0]
    out = {base.decode(): -1}
    out.update({info[12].decode(): info[0] for info in infos})
    return out
