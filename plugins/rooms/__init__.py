"""Rooms: what surrounds the robot cell (``[room] backend``)."""
