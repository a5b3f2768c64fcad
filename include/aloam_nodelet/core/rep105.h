// REP 105 frames from the sensor poses LOAM computes. LOAM's poses are the sensor's, in a world that is the
// sensor at the first sweep; REP 105 wants base_link's, in odom and map frames that are base_link at the
// first sweep. With the fixed extrinsic B = base_link <- sensor, every such pose P becomes B P B^-1.
#pragma once

#include "aloam_nodelet/core/pose.h"

namespace aloam
{
/// `sensor_pose` (a pose of the sensor, or a transform between two worlds that are sensor poses) expressed for
/// base_link: odom <- base_link from odometry's world <- sensor, map <- odom from mapping's correction.
inline Pose toBaseFrame(const Pose& base_from_sensor, const Pose& sensor_pose)
{
  return base_from_sensor * sensor_pose * base_from_sensor.inverse();
}

}  // namespace aloam
