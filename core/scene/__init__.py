"""The scene model: meshes, labels, lights, the robot cell and the camera."""
