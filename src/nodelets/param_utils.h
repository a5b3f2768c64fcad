// Reading validated private parameters in the nodelets.
#pragma once

#include <algorithm>
#include <string>

#include <ros/console.h>
#include <ros/node_handle.h>

namespace aloam_nodelet
{
/// Clamps `value` into [lo, hi], warning under `name` when it had to.
template <typename T>
T clamped(const std::string& logger, const std::string& name, T value, T lo, T hi)
{
  const T result = std::min(std::max(value, lo), hi);
  if (result != value)
  {
    ROS_WARN_STREAM_NAMED(
        logger, "parameter " << name << " = " << value << " is outside [" << lo << ", " << hi << "]; using " << result);
  }
  return result;
}

/// Reads private parameter `name` (default `fallback`) and clamps it into [lo, hi].
template <typename T>
T boundedParam(const ros::NodeHandle& pnh, const std::string& logger, const std::string& name, T fallback, T lo, T hi)
{
  T value = fallback;
  pnh.param(name, value, fallback);
  return clamped(logger, name, value, lo, hi);
}

}  // namespace aloam_nodelet

#include <boost/any.hpp>

namespace aloam_nodelet
{
/// Warns about every private parameter of a dynamic_reconfigure `ConfigT` that is set outside the
/// range the .cfg declares (the reconfigure server clamps such values silently).
template <typename ConfigT>
void warnOutOfRange(const ros::NodeHandle& pnh, const std::string& logger)
{
  const ConfigT& lo = ConfigT::__getMin__();
  const ConfigT& hi = ConfigT::__getMax__();
  for (const auto& description : ConfigT::__getParamDescriptions__())
  {
    double value = 0.0;
    if (description->type == "str" || description->type == "bool" || !pnh.getParam(description->name, value))
    {
      continue;
    }
    boost::any any_lo, any_hi;
    description->getValue(lo, any_lo);
    description->getValue(hi, any_hi);
    const bool is_int = description->type == "int";
    const double min = is_int ? boost::any_cast<int>(any_lo) : boost::any_cast<double>(any_lo);
    const double max = is_int ? boost::any_cast<int>(any_hi) : boost::any_cast<double>(any_hi);
    if (value < min || value > max)
    {
      ROS_WARN_STREAM_NAMED(logger, "parameter " << description->name << " = " << value << " is outside [" << min
                                                 << ", " << max << "]; clamped");
    }
  }
}

}  // namespace aloam_nodelet
