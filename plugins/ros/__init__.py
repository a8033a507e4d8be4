"""The ROS bridges of ``agrisim ros``: ``ros1`` through Debian's rospy, ``ros2`` through
Cyclone DDS with ROS 2's names and encoding. Topics, for each arm ``A``:

- ``/joint_states`` (every arm, joints named ``A/<joint>``), ``/A/joint_states`` (the arm's,
  its URDF's names), ``/tf`` (the arms' moving joints), ``/tf_static`` (latched: ``world`` ->
  each arm's base and every fixed joint), at ``rate`` Hz;
- ``/A/camera/image_raw`` (``rgb8``), ``/A/camera/depth`` (``32FC1``, metres, REP 118: +Inf
  where nothing was hit), ``/A/camera/labels`` (``mono8``), ``/A/camera/instances``
  (``mono16``, where the plant numbers its leaves) and ``/A/camera/camera_info``, in
  ``A/camera_optical_frame``, latched, one each per view;
- ``/agrisim/events`` (``std_msgs/String``): one line per command done or refused;
- in: ``/A/arm_controller/command`` (ROS 1) or ``/A/arm_controller/joint_trajectory`` (ROS 2)
  (``trajectory_msgs/JointTrajectory``, as a ros_control trajectory controller takes it); on
  ROS 1 also the action ``/A/arm_controller/follow_joint_trajectory``
  (``control_msgs/FollowJointTrajectory``, MoveIt's); the service ``/A/capture`` (``std_srvs/Trigger``): a view
  now, the frame's name in the answer.
"""

from __future__ import annotations

from pydantic import Field

from agrisim import BackendSpec, hookimpl
from agrisim.kinds import lazy
from agrisim.options import Options


class BridgeOptions(Options):
    """Options of both ROS bridges."""

    rate: float = Field(50.0, gt=0, le=1000)
    """Hz of ``/joint_states`` and ``/tf``."""


@hookimpl
def agrisim_bridges() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="ros1",
            factory=lazy("agrisim.plugins.ros.ros1:Ros1Bridge"),
            description="ROS 1 (Noetic-era messages) through Debian's rospy; needs a roscore",
            options_model=BridgeOptions,
            limits="Debian's ROS 1 packages (make ros) in a Python of the same version as Debian's",
            preflight=lazy("agrisim.plugins.ros.ros1:preflight"),
        ),
        BackendSpec(
            name="ros2",
            factory=lazy("agrisim.plugins.ros.ros2:Ros2Bridge"),
            description="ROS 2 over Cyclone DDS (rmw_cyclonedds' names, QoS and CDR); no ROS 2 install needed",
            options_model=BridgeOptions,
            limits="tested against Cyclone DDS clients only; no ROS 2 node graph (ros2 node list) is announced",
            preflight=lazy("agrisim.plugins.ros.ros2:preflight"),
        ),
    ]
