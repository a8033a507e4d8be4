"""The robot: its URDF, kinematics, trajectory time-parametrisation, segment checks and setpoints."""
