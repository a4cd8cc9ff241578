"""ROS 2 message definitions of where a robot is (odometry, ``/tf``, a localiser's pose, a GNSS driver's own fix),
as MCAP schemas carry them: for the demo's drives and the tests that write logs with positions."""

from __future__ import annotations

from .ros2_cdr import HEADER_DEFS, SEP, VECTOR3

QUATERNION = f"""{SEP}
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w"""
_POSE = f"""{SEP}
MSG: geometry_msgs/PoseWithCovariance
geometry_msgs/Pose pose
float64[36] covariance
{SEP}
MSG: geometry_msgs/Pose
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
{SEP}
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
{QUATERNION}"""

ODOMETRY_SCHEMA = f"""std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
{HEADER_DEFS}
{SEP}
MSG: geometry_msgs/TwistWithCovariance
geometry_msgs/Twist twist
float64[36] covariance
{SEP}
MSG: geometry_msgs/Twist
geometry_msgs/Vector3 linear
geometry_msgs/Vector3 angular
{VECTOR3}
{_POSE}"""

TF_SCHEMA = f"""geometry_msgs/TransformStamped[] transforms
{SEP}
MSG: geometry_msgs/TransformStamped
std_msgs/Header header
string child_frame_id
geometry_msgs/Transform transform
{SEP}
MSG: geometry_msgs/Transform
geometry_msgs/Vector3 translation
geometry_msgs/Quaternion rotation
{VECTOR3}
{QUATERNION}
{HEADER_DEFS}"""

AMCL_SCHEMA = f"""std_msgs/Header header
geometry_msgs/PoseWithCovariance pose
{HEADER_DEFS}
{_POSE}"""

# a GNSS receiver's driver publishing its own message (as many do) rather than sensor_msgs/NavSatFix
DRIVER_GNSS_SCHEMA = f"""std_msgs/Header header
uint8 fix_quality
float64 latitude
float64 longitude
float64 altitude
float32 hdop
{HEADER_DEFS}"""

NAVSATFIX_SCHEMA = f"""std_msgs/Header header
sensor_msgs/NavSatStatus status
float64 latitude
float64 longitude
float64 altitude
float64[9] position_covariance
uint8 position_covariance_type
{HEADER_DEFS}
{SEP}
MSG: sensor_msgs/NavSatStatus
int8 status
uint16 service"""
