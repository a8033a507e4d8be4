"""Importing Debian's rospy into agrisim's environment.

Debian ships ROS 1 for its own ``/usr/bin/python3`` only (``/usr/lib/python3/dist-packages``),
not as wheels. Its packages are pure Python, so a virtual environment of the same Python version
can import them with that folder at the end of ``sys.path``: every package the environment has
itself still wins.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path
from types import ModuleType

from agrisim.errors import UserError

DIST_PACKAGES = Path("/usr/lib/python3/dist-packages")
#: what ``make ros`` installs (scripts/ros-deps.sh)
DEBIAN_PACKAGES = (
    "ros-core python3-actionlib python3-sensor-msgs python3-tf2-msgs python3-trajectory-msgs python3-std-srvs"
)


def import_rospy() -> ModuleType:
    """``rospy``, from this environment or Debian's; a clear refusal if neither has it."""
    try:
        return importlib.import_module("rospy")
    except ImportError:
        pass
    if not (DIST_PACKAGES / "rospy").is_dir():
        raise UserError(f"ROS 1 is not installed: apt-get install {DEBIAN_PACKAGES} (or make ros)")
    debian = _debian_python_version()
    if debian is not None and debian != sys.version_info[:2]:
        raise UserError(
            f"Debian's rospy is for Python {debian[0]}.{debian[1]}, this is {sys.version_info[0]}.{sys.version_info[1]}: "
            "run agrisim from a Python of Debian's version for ROS 1"
        )
    if str(DIST_PACKAGES) not in sys.path:
        sys.path.append(str(DIST_PACKAGES))
    try:
        return importlib.import_module("rospy")
    except ImportError as exc:
        raise UserError(f"Debian's rospy does not import here ({exc}): apt-get install {DEBIAN_PACKAGES}") from None


def _debian_python_version() -> tuple[int, int] | None:
    try:
        out = subprocess.run(
            ["/usr/bin/python3", "-c", "import sys; print(*sys.version_info[:2])"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.split()
        return int(out[0]), int(out[1])
    except (OSError, subprocess.SubprocessError, ValueError, IndexError):
        return None
