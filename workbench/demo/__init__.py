"""Demo data: synthetic quadruped walks written as ROS 2 MCAP (with their own CDR writer), and labels seeded from a
session's reference truth."""

from .pose_schemas import AMCL_SCHEMA, DRIVER_GNSS_SCHEMA, ODOMETRY_SCHEMA, TF_SCHEMA
from .ros2_cdr import COMPRESSED_IMAGE_SCHEMA, IMU_SCHEMA, WRENCH_STAMPED_SCHEMA
from .ros2_cdr import encode as encode_stamped_floats
from .run_conditions import RunConditions
from .seed_labels import seed_labels
from .walk_files import generate_demo_logs, write_walk
from .walks import FOOT_HZ, IMU_HZ, TERRAINS, Walk, generate_walk

__all__ = [
    "AMCL_SCHEMA",
    "COMPRESSED_IMAGE_SCHEMA",
    "DRIVER_GNSS_SCHEMA",
    "FOOT_HZ",
    "IMU_HZ",
    "IMU_SCHEMA",
    "ODOMETRY_SCHEMA",
    "TERRAINS",
    "TF_SCHEMA",
    "WRENCH_STAMPED_SCHEMA",
    "RunConditions",
    "Walk",
    "encode_stamped_floats",
    "generate_demo_logs",
    "generate_walk",
    "seed_labels",
    "write_walk",
]
