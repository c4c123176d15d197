"""The physical system: parameters, frames, the robot model, kinematics, nominal dynamics, hydrodynamics, simulator.

* :mod:`~uvdms_gym.physics.params`: every physical number (typed frozen dataclasses) and the thresholds ``D1``, ``D2``;
* :mod:`~uvdms_gym.physics.frames`: NED/FRD <-> PyBullet world, Euler/quaternion/rotation helpers;
* :mod:`~uvdms_gym.physics.model`: the URDF generated from the parameters, the Pinocchio model, link segments;
* :mod:`~uvdms_gym.physics.kinematics`: ``KinematicModel`` (poses, Jacobians, mass matrix);
* :mod:`~uvdms_gym.physics.nominal`: the controller-side (nominal) dynamics;
* :mod:`~uvdms_gym.physics.hydro`: hydrodynamic forces as pure functions;
* :mod:`~uvdms_gym.physics.sim`: ``UVDMSSim``, the PyBullet simulator.
"""
