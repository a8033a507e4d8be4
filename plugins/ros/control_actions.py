"""``control_msgs/FollowJointTrajectory`` for ROS 1, the action MoveIt's controller managers send
trajectories through, made at run time by genpy from its definition (Debian packages no
``control_msgs``). Fields and constants are those of control_msgs 1.5 (ROS 1): genpy's MD5 sums,
which ROS 1 peers compare on connecting, then equal the real package's.

Standalone (genpy and Debian's message packages only): a ROS 1 client in Debian's own Python
imports it by path.
"""

from __future__ import annotations

from typing import Any

SEPARATOR = "=" * 80

#: control_msgs 1.5's definitions (comments left out: they take no part in a type's MD5 sum)
DEFINITIONS = {
    "control_msgs/JointTolerance": "string name\nfloat64 position\nfloat64 velocity\nfloat64 acceleration\n",
    "control_msgs/FollowJointTrajectoryGoal": (
        "trajectory_msgs/JointTrajectory trajectory\n"
        "control_msgs/JointTolerance[] path_tolerance\n"
        "control_msgs/JointTolerance[] goal_tolerance\n"
        "duration goal_time_tolerance\n"
    ),
    "control_msgs/FollowJointTrajectoryResult": (
        "int32 error_code\n"
        "int32 SUCCESSFUL = 0\n"
        "int32 INVALID_GOAL = -1\n"
        "int32 INVALID_JOINTS = -2\n"
        "int32 OLD_HEADER_TIMESTAMP = -3\n"
        "int32 PATH_TOLERANCE_VIOLATED = -4\n"
        "int32 GOAL_TOLERANCE_VIOLATED = -5\n"
        "string error_string\n"
    ),
    "control_msgs/FollowJointTrajectoryFeedback": (
        "Header header\n"
        "string[] joint_names\n"
        "trajectory_msgs/JointTrajectoryPoint desired\n"
        "trajectory_msgs/JointTrajectoryPoint actual\n"
        "trajectory_msgs/JointTrajectoryPoint error\n"
    ),
    "control_msgs/FollowJointTrajectoryActionGoal": (
        "Header header\nactionlib_msgs/GoalID goal_id\ncontrol_msgs/FollowJointTrajectoryGoal goal\n"
    ),
    "control_msgs/FollowJointTrajectoryActionResult": (
        "Header header\nactionlib_msgs/GoalStatus status\ncontrol_msgs/FollowJointTrajectoryResult result\n"
    ),
    "control_msgs/FollowJointTrajectoryActionFeedback": (
        "Header header\nactionlib_msgs/GoalStatus status\ncontrol_msgs/FollowJointTrajectoryFeedback feedback\n"
    ),
    "control_msgs/FollowJointTrajectoryAction": (
        "control_msgs/FollowJointTrajectoryActionGoal action_goal\n"
        "control_msgs/FollowJointTrajectoryActionResult action_result\n"
        "control_msgs/FollowJointTrajectoryActionFeedback action_feedback\n"
    ),
}


def follow_joint_trajectory() -> dict[str, Any]:
    """The action's message classes by short name (``FollowJointTrajectoryAction``,
    ``...Goal``, ``...Result``, ``...Feedback``, ``JointTolerance`` ...)."""
    import genpy.dynamic
    from actionlib_msgs.msg import GoalStatus
    from std_msgs.msg import Header
    from trajectory_msgs.msg import JointTrajectory

    core = "control_msgs/FollowJointTrajectoryAction"
    sections = [DEFINITIONS[core]]
    sections += [f"{SEPARATOR}\nMSG: {name}\n{text}" for name, text in DEFINITIONS.items() if name != core]
    # the installed packages' own definitions of what the action's messages hold
    for cls in (Header, GoalStatus, JointTrajectory):
        sections.append(f"{SEPARATOR}\nMSG: {cls._type}\n{cls._full_text}")
    classes = genpy.dynamic.generate_dynamic(core, "\n".join(sections))
    return {name.split("/")[1]: cls for name, cls in classes.items() if name.startswith("control_msgs/")}
