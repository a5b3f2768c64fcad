// An arctangent for the per-point azimuths of a sweep.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

namespace aloam
{
/// atan2(y, x) to within 4e-8 rad (a float angle near pi resolves 2.4e-7), a few times faster than
/// std::atan2: an odd polynomial for atan on [0, 1] (degree 15, fitted to minimise the largest error),
/// then the octant. The origin, infinities and NaN go to std::atan2.
inline double fastAtan2(double y, double x)
{
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const double ax = std::fabs(x), ay = std::fabs(y);
  if (!(ax < kInfinity && ay < kInfinity) || (ax == 0.0 && ay == 0.0))  // also NaN
  {
    return std::atan2(y, x);
  }
  const double hi = std::max(ax, ay), lo = std::min(ax, ay);
  const double t = lo / hi, u = t * t;
  double a =
      t * (0.9999993356270397 +
           u * (-0.33329860993705185 +
                u * (0.1994656818526034 +
                     u * (-0.13908642809940483 +
                          u * (0.0964223243173023 +
                               u * (-0.05591281889783742 + u * (0.02186330612463354 + u * -0.004054665083692316)))))));
  if (ay > ax)
  {
    a = M_PI_2 - a;
  }
  if (x < 0.0)
  {
    a = M_PI - a;
  }
  return std::signbit(y) ? -a : a;
}

}  // namespace aloam
