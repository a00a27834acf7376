"""Standard ROS 2 message classes, taken from the ``rosbags`` type store.

The classes are the ROS 2 Humble definitions that ``rosbags`` ships (they are
plain dataclasses); visnav never redefines a message by hand. Field names are
ROS's. Quaternions are stored x, y, z, w as in ROS.
"""

from __future__ import annotations

from rosbags.typesys.stores.ros2_humble import (
    builtin_interfaces__msg__Duration as Duration,
)
from rosbags.typesys.stores.ros2_humble import (
    builtin_interfaces__msg__Time as Time,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Point as Point,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Point32 as Point32,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__PointStamped as PointStamped,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Pose as Pose,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__PoseStamped as PoseStamped,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__PoseWithCovariance as PoseWithCovariance,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__PoseWithCovarianceStamped as PoseWithCovarianceStamped,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Quaternion as Quaternion,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Transform as Transform,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__TransformStamped as TransformStamped,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Twist as Twist,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__TwistStamped as TwistStamped,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__TwistWithCovariance as TwistWithCovariance,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Vector3 as Vector3,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Vector3Stamped as Vector3Stamped,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__Wrench as Wrench,
)
from rosbags.typesys.stores.ros2_humble import (
    geometry_msgs__msg__WrenchStamped as WrenchStamped,
)
from rosbags.typesys.stores.ros2_humble import (
    nav_msgs__msg__MapMetaData as MapMetaData,
)
from rosbags.typesys.stores.ros2_humble import (
    nav_msgs__msg__OccupancyGrid as OccupancyGrid,
)
from rosbags.typesys.stores.ros2_humble import (
    nav_msgs__msg__Odometry as Odometry,
)
from rosbags.typesys.stores.ros2_humble import (
    nav_msgs__msg__Path as Path,
)
from rosbags.typesys.stores.ros2_humble import (
    rosgraph_msgs__msg__Clock as Clock,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__CameraInfo as CameraInfo,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__CompressedImage as CompressedImage,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__Image as Image,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__Imu as Imu,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__JointState as JointState,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__LaserScan as LaserScan,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__PointCloud2 as PointCloud2,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__PointField as PointField,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__RegionOfInterest as RegionOfInterest,
)
from rosbags.typesys.stores.ros2_humble import (
    std_msgs__msg__ColorRGBA as ColorRGBA,
)
from rosbags.typesys.stores.ros2_humble import (
    std_msgs__msg__Header as Header,
)
from rosbags.typesys.stores.ros2_humble import (
    std_msgs__msg__String as String,
)
from rosbags.typesys.stores.ros2_humble import (
    tf2_msgs__msg__TFMessage as TFMessage,
)
from rosbags.typesys.stores.ros2_humble import (
    visualization_msgs__msg__Marker as Marker,
)
from rosbags.typesys.stores.ros2_humble import (
    visualization_msgs__msg__MarkerArray as MarkerArray,
)

__all__ = [
    "CameraInfo",
    "Clock",
    "ColorRGBA",
    "CompressedImage",
    "Duration",
    "Header",
    "Image",
    "Imu",
    "JointState",
    "LaserScan",
    "MapMetaData",
    "Marker",
    "MarkerArray",
    "OccupancyGrid",
    "Odometry",
    "Path",
    "Point",
    "Point32",
    "PointCloud2",
    "PointStamped",
    "PointField",
    "Pose",
    "PoseStamped",
    "PoseWithCovariance",
    "PoseWithCovarianceStamped",
    "Quaternion",
    "RegionOfInterest",
    "String",
    "TFMessage",
    "Time",
    "Transform",
    "TransformStamped",
    "Twist",
    "TwistStamped",
    "TwistWithCovariance",
    "Vector3",
    "Vector3Stamped",
    "Wrench",
    "WrenchStamped",
]
