// Trajectory files: KITTI odometry poses, KITTI calib.txt / times.txt, and TUM output.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace aloam
{
namespace eval
{
/// A sequence of poses, one per frame (pose of the sensor in the trajectory's reference frame).
/// Poses are stored as read; they are not re-orthonormalised.
using Trajectory = std::vector<Eigen::Isometry3d>;

/// Reads a KITTI pose file: one pose per line, 12 numbers = row-major 3x4 [R|t]. Blank lines are
/// skipped. Throws std::runtime_error (with file name and line number) if the file cannot be opened
/// or a line does not hold exactly 12 finite numbers.
Trajectory readKittiPoses(const std::string& path);

/// Writes a KITTI pose file (12 space-separated numbers per line, %.16e: 17 significant digits, so
/// doubles survive a write -> read round trip bit-exactly). Throws std::runtime_error
/// if the file cannot be written.
void writeKittiPoses(const std::string& path, const Trajectory& poses);

/// Writes a TUM trajectory file: `timestamp tx ty tz qx qy qz qw` per line (qw >= 0). `stamps` must
/// have the same length as `poses` (std::invalid_argument otherwise). Throws std::runtime_error if
/// the file cannot be written.
void writeTumTrajectory(const std::string& path, const Trajectory& poses, const std::vector<double>& stamps);

/// Reads the `Tr:` line (12 numbers, row-major 3x4, velodyne -> camera 0) of a KITTI odometry
/// calib.txt and returns it as a 4x4 transform. Throws std::runtime_error if the file cannot be
/// opened, has no `Tr:` line, or the line is malformed.
Eigen::Isometry3d readKittiCalibTr(const std::string& path);

/// Reads a KITTI times.txt (one timestamp in seconds per line, blank lines skipped). Throws
/// std::runtime_error (with file name and line number) on unreadable files or malformed lines.
std::vector<double> readTimes(const std::string& path);

}  // namespace eval
}  // namespace aloam
