#include "aloam_nodelet/sim/loops.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <utility>
#include <variant>

#include "aloam_nodelet/sim/trajectories.h"
#include "deterministic_rng.h"

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kCollinear = 1e-9;      // rad; smaller corner angles make no turn
constexpr double kMaxCornerAngle = 3.1;  // rad; sharper corners (U-turns) are refused
constexpr double kLegTolerance = 1e-9;   // m
constexpr int kTurnNodes = 1024;         // table of positions along a turn
constexpr int kTurnSubsteps = 8;         // Simpson sub-intervals per table interval (even)
constexpr unsigned kSeedMix = 2654435761U;
constexpr unsigned kEdgeMix = 40503U;
constexpr unsigned kCarStream = 0x9E3779B9U;
// Parked cars (like Scene::urbanStreet's).
constexpr double kCarSlot = 6.5;
constexpr double kCarLengthMin = 4.0;
constexpr double kCarLengthMax = 4.9;
constexpr double kCarWidthMin = 1.7;
constexpr double kCarWidthMax = 1.95;
constexpr double kCarClearance = 0.25;
constexpr double kCarBodyMin = 0.7;
constexpr double kCarBodyMax = 0.95;
constexpr double kCarCabinMin = 0.45;
constexpr double kCarCabinMax = 0.65;
constexpr double kCarCabinLength = 0.55;
constexpr double kCarCabinWidth = 0.9;
constexpr double kCarCabinShift = 0.08;
constexpr double kCarKerbGap = 0.3;
constexpr double kCarJitter = 0.5;
constexpr double kCarYawJitter = 0.05;
// Ring floor.
constexpr double kFloorDoorHeight = 2.1;
constexpr double kFloorNicheWidth = 1.5;
constexpr double kFloorNicheDepth = 0.6;
constexpr double kFloorRoomWidthMin = 2.5;
constexpr double kFloorRoomWidthMax = 4.0;
constexpr double kFloorMinRoomDepth = 1.2;
constexpr double kFloorWallEndGap = 0.5;  // plain wall kept at both ends of a wall's feature range
constexpr double kFloorMargin = 2.0;      // floor and ceiling beyond the outer walls
constexpr double kLightHalf[3] = { 0.3, 0.15, 0.05 };

double smoothstep(double u)
{
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3.0 - 2.0 * u);
}

Eigen::Vector2d unit(double heading)
{
  return Eigen::Vector2d(std::cos(heading), std::sin(heading));
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b)
{
  return a.x() * b.y() - a.y() * b.x();
}

unsigned mixSeed(unsigned seed, unsigned a, unsigned b)
{
  return seed * kSeedMix + (a + 1U) * kEdgeMix + (b + 1U) * 977U;
}
}  // namespace

// ---------------------------------------------------------------------------------------------
// RoundedPath

RoundedPath::RoundedPath(const std::vector<Eigen::Vector2d>& waypoints, bool closed, double corner_length_m)
  : closed_(closed)
{
  const std::size_t n = waypoints.size();
  if (n < 2 || (closed && n < 3) || !(corner_length_m > 0.0))
  {
    throw std::invalid_argument("RoundedPath: need two waypoints (three if closed) and a positive corner length");
  }
  const std::size_t legs = closed ? n : n - 1;
  std::vector<Eigen::Vector2d> dirs(legs);
  std::vector<double> lengths(legs);
  for (std::size_t i = 0; i < legs; ++i)
  {
    const Eigen::Vector2d d = waypoints[(i + 1) % n] - waypoints[i];
    lengths[i] = d.norm();
    if (!(lengths[i] > 0.0))
    {
      throw std::invalid_argument("RoundedPath: repeated waypoint");
    }
    dirs[i] = d / lengths[i];
  }
  // Corner i sits at waypoint i between leg i - 1 and leg i; the turn starts `before` metres ahead of the
  // waypoint on the incoming leg and ends `after` metres past it on the outgoing one.
  std::vector<double> angle(n, 0.0), before(n, 0.0), after(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
  {
    if (!closed && (i == 0 || i == n - 1))
    {
      continue;
    }
    const Eigen::Vector2d& in = dirs[(i + legs - 1) % legs];
    const Eigen::Vector2d& out = dirs[i % legs];
    const double phi = std::atan2(cross(in, out), in.dot(out));
    if (std::abs(phi) < kCollinear)
    {
      continue;
    }
    if (std::abs(phi) > kMaxCornerAngle)
    {
      throw std::invalid_argument("RoundedPath: U-turn at a waypoint");
    }
    // The turn's displacement, in the incoming leg's frame, is before * (1, 0) + after * (cos phi, sin phi).
    const Eigen::Vector2d shift = turnDisplacement(phi, corner_length_m);
    angle[i] = phi;
    after[i] = shift.y() / std::sin(phi);
    before[i] = shift.x() - after[i] * std::cos(phi);
  }
  double heading = std::atan2(dirs[0].y(), dirs[0].x());
  double s = 0.0;
  for (std::size_t i = 0; i < legs; ++i)
  {
    const std::size_t end_corner = (i + 1) % n;
    const double straight = lengths[i] - after[i] - before[end_corner];
    if (straight < -kLegTolerance)
    {
      throw std::invalid_argument("RoundedPath: a leg is too short for the turns at its ends");
    }
    Piece line;
    line.s0 = s;
    line.length = std::max(0.0, straight);
    line.heading0 = heading;
    line.start = waypoints[i] + after[i] * dirs[i];
    s += line.length;
    pieces_.push_back(line);
    if (angle[end_corner] == 0.0)
    {
      continue;
    }
    Piece turn;
    turn.s0 = s;
    turn.length = corner_length_m;
    turn.heading0 = heading;
    turn.turn = angle[end_corner];
    turn.start = waypoints[end_corner] - before[end_corner] * dirs[i];
    turn.table.reserve(kTurnNodes + 1);
    turn.table.push_back(Eigen::Vector2d::Zero());
    const double node = corner_length_m / kTurnNodes;
    const double h = node / kTurnSubsteps;
    for (int k = 0; k < kTurnNodes; ++k)
    {
      Eigen::Vector2d sum = Eigen::Vector2d::Zero();
      for (int j = 0; j <= kTurnSubsteps; ++j)
      {
        const double weight = (j == 0 || j == kTurnSubsteps) ? 1.0 : (j % 2 == 1 ? 4.0 : 2.0);
        const double u = (k * node + j * h) / corner_length_m;
        sum += weight * unit(heading + turn.turn * smoothstep(u));
      }
      turn.table.push_back(turn.table.back() + sum * h / 3.0);
    }
    s += corner_length_m;
    heading += turn.turn;
    net_turn_ += turn.turn;
    pieces_.push_back(std::move(turn));
  }
  length_ = s;
  if (!(length_ > 0.0))
  {
    throw std::invalid_argument("RoundedPath: zero length");
  }
}

const RoundedPath::Piece& RoundedPath::pieceAt(double s, double* local, double* laps) const
{
  *laps = 0.0;
  if (closed_)
  {
    *laps = std::floor(s / length_);
    s -= *laps * length_;
  }
  // The last piece whose start is at or before s (open paths extend their first and last pieces).
  auto it =
      std::upper_bound(pieces_.begin(), pieces_.end(), s, [](double value, const Piece& p) { return value < p.s0; });
  const Piece& piece = it == pieces_.begin() ? pieces_.front() : *(it - 1);
  *local = s - piece.s0;
  return piece;
}

Eigen::Vector2d RoundedPath::position(double s) const
{
  double local = 0.0;
  double laps = 0.0;
  const Piece& p = pieceAt(s, &local, &laps);
  if (p.turn == 0.0 || local <= 0.0)
  {
    return p.start + local * unit(p.heading0);
  }
  if (local >= p.length)
  {
    return p.start + p.table.back() + (local - p.length) * unit(p.heading0 + p.turn);
  }
  const double u = local / p.length * kTurnNodes;
  const int i = std::min(static_cast<int>(u), kTurnNodes - 1);
  const double f = u - i;
  return p.start + (1.0 - f) * p.table[static_cast<std::size_t>(i)] + f * p.table[static_cast<std::size_t>(i) + 1];
}

double RoundedPath::heading(double s) const
{
  double local = 0.0;
  double laps = 0.0;
  const Piece& p = pieceAt(s, &local, &laps);
  const double turned = p.turn == 0.0 ? 0.0 : p.turn * smoothstep(local / p.length);
  return p.heading0 + turned + laps * net_turn_;
}

double RoundedPath::curvature(double s) const
{
  double local = 0.0;
  double laps = 0.0;
  const Piece& p = pieceAt(s, &local, &laps);
  if (p.turn == 0.0 || local <= 0.0 || local >= p.length)
  {
    return 0.0;
  }
  const double u = local / p.length;
  return p.turn * 6.0 * u * (1.0 - u) / p.length;
}

PoseFunction pathFollow(const PathFollowOptions& options)
{
  const auto path = std::make_shared<const RoundedPath>(options.waypoints, options.closed, options.corner_length_m);
  return [options, path](double t)
  {
    const double s = options.start_distance_m + options.speed * t;
    const double heading = path->heading(s);
    const Eigen::Vector2d xy =
        path->position(s) + options.lateral_offset_m * Eigen::Vector2d(-std::sin(heading), std::cos(heading));
    return swayedPose(xy, heading, t,
                      WalkSway{ options.height_m, options.bob_amplitude_m, options.bob_frequency_hz,
                                options.roll_amplitude_rad, options.yaw_sway_rad });
  };
}

// ---------------------------------------------------------------------------------------------
// City grid

namespace
{
/// A span of blocks along one axis (kerb to kerb) and whether a street runs along each of its ends.
struct Span
{
  double lo = 0.0;
  double hi = 0.0;
  bool street_lo = true;
  bool street_hi = true;
};

std::vector<Span> blockSpans(const std::vector<double>& streets, double half_width, double outer)
{
  std::vector<Span> spans;
  if (outer > 0.0)
  {
    spans.push_back({ streets.front() - half_width - outer, streets.front() - half_width, false, true });
  }
  for (std::size_t i = 0; i + 1 < streets.size(); ++i)
  {
    spans.push_back({ streets[i] + half_width, streets[i + 1] - half_width, true, true });
  }
  if (outer > 0.0)
  {
    spans.push_back({ streets.back() + half_width, streets.back() + half_width + outer, true, false });
  }
  return spans;
}

/// Maps the frame of a straight street (u along it, v to the left from its centerline) onto a block edge
/// that starts at kerb corner `start` and runs along `dir`, with the block on its left.
struct EdgeFrame
{
  Eigen::Vector2d start;
  Eigen::Vector2d dir;
  double half_width;

  Eigen::Vector2d map(double u, double v) const
  {
    const Eigen::Vector2d normal(-dir.y(), dir.x());
    return start + u * dir + (v - half_width) * normal;
  }
  double yaw() const { return std::atan2(dir.y(), dir.x()); }
};

std::optional<Shape> mapShape(const Shape& shape, const EdgeFrame& frame)
{
  if (const auto* box = std::get_if<OrientedBox>(&shape))
  {
    const Eigen::Vector2d c = frame.map(box->center().x(), box->center().y());
    return OrientedBox(Eigen::Vector3d(c.x(), c.y(), box->center().z()), box->halfExtents(), box->yaw() + frame.yaw());
  }
  if (const auto* cylinder = std::get_if<VerticalCylinder>(&shape))
  {
    const Eigen::Vector2d c = frame.map(cylinder->centerX(), cylinder->centerY());
    return VerticalCylinder(c.x(), c.y(), cylinder->radius(), cylinder->zMin(), cylinder->zMax());
  }
  if (const auto* sphere = std::get_if<Sphere>(&shape))
  {
    const Eigen::Vector2d c = frame.map(sphere->center().x(), sphere->center().y());
    return Sphere(Eigen::Vector3d(c.x(), c.y(), sphere->center().z()), sphere->radius());
  }
  return std::nullopt;  // the street's own ground plane
}

double shapeV(const Shape& shape)
{
  if (const auto* box = std::get_if<OrientedBox>(&shape))
  {
    return box->center().y();
  }
  if (const auto* cylinder = std::get_if<VerticalCylinder>(&shape))
  {
    return cylinder->centerY();
  }
  if (const auto* sphere = std::get_if<Sphere>(&shape))
  {
    return sphere->center().y();
  }
  return 0.0;
}

/// The frontage of one block edge: the left side (v > 0) of an urban street as long as the edge, and
/// parked cars along its kerb away from the corners.
void addFrontage(std::vector<Primitive>* out, unsigned seed, const EdgeFrame& frame, double length,
                 const CityGridOptions& o)
{
  UrbanStreetOptions street = o.facade;
  street.length_m = length;
  street.end_margin_m = 0.0;
  street.ground_margin_m = 1.0;
  street.street_width_min_m = o.street_width_m;
  street.street_width_max_m = o.street_width_m;
  street.car_probability = 0.0;
  const Scene side = Scene::urbanStreet(seed, street);
  for (const Primitive& p : side.primitives())
  {
    if (shapeV(p.shape) <= 0.0)
    {
      continue;
    }
    if (const auto mapped = mapShape(p.shape, frame))
    {
      out->emplace_back(*mapped, p.surface_class, p.reflectivity);
    }
  }
  DeterministicRng rng(seed ^ kCarStream);
  const double reflectivity = defaultReflectivity(SurfaceClass::Vehicle);
  for (double slot = CityGridOptions::kNoParkingM; slot + kCarSlot <= length - CityGridOptions::kNoParkingM;
       slot += kCarSlot)
  {
    if (!rng.bernoulli(o.facade.car_probability))
    {
      continue;
    }
    const double len = rng.uniform(kCarLengthMin, kCarLengthMax);
    const double width = rng.uniform(kCarWidthMin, kCarWidthMax);
    const double body = rng.uniform(kCarBodyMin, kCarBodyMax);
    const double cabin = rng.uniform(kCarCabinMin, kCarCabinMax);
    const double yaw = rng.uniform(-kCarYawJitter, kCarYawJitter);
    const double u = slot + 0.5 * kCarSlot + rng.uniform(-kCarJitter, kCarJitter);
    const double v = frame.half_width - kCarKerbGap - 0.5 * width;
    const Eigen::Vector2d c = frame.map(u, v);
    out->emplace_back(OrientedBox(Eigen::Vector3d(c.x(), c.y(), kCarClearance + 0.5 * body),
                                  Eigen::Vector3d(0.5 * len, 0.5 * width, 0.5 * body), yaw + frame.yaw()),
                      SurfaceClass::Vehicle, reflectivity);
    const Eigen::Vector2d cc =
        frame.map(u - kCarCabinShift * len * std::cos(yaw), v - kCarCabinShift * len * std::sin(yaw));
    out->emplace_back(
        OrientedBox(Eigen::Vector3d(cc.x(), cc.y(), kCarClearance + body + 0.5 * cabin),
                    Eigen::Vector3d(0.5 * kCarCabinLength * len, 0.5 * kCarCabinWidth * width, 0.5 * cabin),
                    yaw + frame.yaw()),
        SurfaceClass::Vehicle, reflectivity);
  }
}
}  // namespace

Scene cityGridScene(unsigned seed, const CityGridOptions& o)
{
  if (o.street_x.size() < 2 || o.street_y.size() < 2 || !std::is_sorted(o.street_x.begin(), o.street_x.end()) ||
      !std::is_sorted(o.street_y.begin(), o.street_y.end()) || !(o.street_width_m > 0.0))
  {
    throw std::invalid_argument("cityGridScene: need two ascending streets each way and a positive width");
  }
  const double hw = 0.5 * o.street_width_m;
  const std::vector<Span> xs = blockSpans(o.street_x, hw, o.outer_block_m);
  const std::vector<Span> ys = blockSpans(o.street_y, hw, o.outer_block_m);
  for (const std::vector<Span>* spans : { &xs, &ys })
  {
    for (const Span& span : *spans)
    {
      if (!(span.hi - span.lo > 1.0))
      {
        throw std::invalid_argument("cityGridScene: streets too close for a block between them");
      }
    }
  }
  std::vector<Primitive> primitives;
  const double reach = hw + std::max(0.0, o.outer_block_m) + o.ground_margin_m;
  primitives.emplace_back(PlanePatch::horizontal(0.0, o.street_x.front() - reach, o.street_x.back() + reach,
                                                 o.street_y.front() - reach, o.street_y.back() + reach),
                          SurfaceClass::Ground);
  for (std::size_t j = 0; j < ys.size(); ++j)
  {
    for (std::size_t i = 0; i < xs.size(); ++i)
    {
      const Span& x = xs[i];
      const Span& y = ys[j];
      // Counterclockwise round the block (the block on the left): south, east, north, west.
      const EdgeFrame edges[4] = {
        { Eigen::Vector2d(x.lo, y.lo), Eigen::Vector2d(1.0, 0.0), hw },
        { Eigen::Vector2d(x.hi, y.lo), Eigen::Vector2d(0.0, 1.0), hw },
        { Eigen::Vector2d(x.hi, y.hi), Eigen::Vector2d(-1.0, 0.0), hw },
        { Eigen::Vector2d(x.lo, y.hi), Eigen::Vector2d(0.0, -1.0), hw },
      };
      const double lengths[4] = { x.hi - x.lo, y.hi - y.lo, x.hi - x.lo, y.hi - y.lo };
      const bool streets[4] = { y.street_lo, x.street_hi, y.street_hi, x.street_lo };
      const unsigned block = o.identical_blocks ? 0U : static_cast<unsigned>(j * xs.size() + i);
      for (unsigned e = 0; e < 4; ++e)
      {
        if (streets[e])
        {
          addFrontage(&primitives, mixSeed(seed, block, e), edges[e], lengths[e], o);
        }
      }
    }
  }
  return Scene(std::move(primitives));
}

// ---------------------------------------------------------------------------------------------
// Ring floor

namespace
{
/// A solid wall band behind a corridor face: u runs along the face, depth d from the face into the solid
/// (0 <= d <= depth); features are carved only within [feature_u0, feature_u1].
struct WallBand
{
  bool along_y = false;
  double face = 0.0;
  double into = 1.0;  // sign of the direction from the face into the solid
  double u0 = 0.0;
  double u1 = 0.0;
  double depth = 1.0;
  double feature_u0 = 0.0;
  double feature_u1 = 0.0;
  double room_depth = 0.0;  // rooms only if at least kFloorMinRoomDepth
};

class FloorBuilder
{
public:
  FloorBuilder(Scene* scene, const RingFloorOptions& o) : scene_(scene), o_(o) {}

  /// Solid of the band over [a, b] along it, [d0, d1] deep, [z0, z1] high.
  void box(const WallBand& w, double a, double b, double d0, double d1, double z0, double z1)
  {
    if (b - a <= 1e-9 || d1 - d0 <= 1e-9 || z1 - z0 <= 1e-9)
    {
      return;
    }
    const double u = 0.5 * (a + b);
    const double v = w.face + w.into * 0.5 * (d0 + d1);
    const double hu = 0.5 * (b - a);
    const double hv = 0.5 * (d1 - d0);
    const Eigen::Vector3d center =
        w.along_y ? Eigen::Vector3d(v, u, 0.5 * (z0 + z1)) : Eigen::Vector3d(u, v, 0.5 * (z0 + z1));
    const Eigen::Vector3d half =
        w.along_y ? Eigen::Vector3d(hv, hu, 0.5 * (z1 - z0)) : Eigen::Vector3d(hu, hv, 0.5 * (z1 - z0));
    scene_->add(OrientedBox(center, half), SurfaceClass::Building);
  }

  void band(const WallBand& w, DeterministicRng& rng)
  {
    const double h = o_.height_m;
    const double t = o_.wall_thickness_m;
    double solid_from = w.u0;
    double cursor = w.feature_u0 + kFloorWallEndGap;
    while (true)
    {
      const double r = rng.uniform01();
      const bool room = r < o_.room_probability && w.room_depth >= kFloorMinRoomDepth;
      const bool niche = !room && r < o_.room_probability + o_.niche_probability;
      const double width =
          room ? rng.uniform(kFloorRoomWidthMin, kFloorRoomWidthMax) : (niche ? kFloorNicheWidth : o_.door_width_m);
      const double a = cursor + o_.feature_spacing_m * rng.uniform(0.25, 0.75);
      const double b = a + width;
      if (b > w.feature_u1 - kFloorWallEndGap)
      {
        break;
      }
      box(w, solid_from, a, 0.0, w.depth, 0.0, h);
      const double c0 = 0.5 * (a + b) - 0.5 * o_.door_width_m;
      const double c1 = 0.5 * (a + b) + 0.5 * o_.door_width_m;
      if (room)
      {
        // Front wall with a door and a lintel, the room behind it, the band's solid behind the room.
        box(w, a, c0, 0.0, t, 0.0, h);
        box(w, c1, b, 0.0, t, 0.0, h);
        box(w, c0, c1, 0.0, t, kFloorDoorHeight, h);
        box(w, a, b, t + w.room_depth, w.depth, 0.0, h);
      }
      else if (niche)
      {
        box(w, a, b, kFloorNicheDepth, w.depth, 0.0, h);
      }
      else
      {
        box(w, a, b, o_.recess_depth_m, w.depth, 0.0, h);
        box(w, a, b, 0.0, o_.recess_depth_m, kFloorDoorHeight, h);
      }
      solid_from = b;
      cursor = b + o_.feature_spacing_m * 0.25;
    }
    box(w, solid_from, w.u1, 0.0, w.depth, 0.0, h);
  }

private:
  Scene* scene_;
  const RingFloorOptions& o_;
};
}  // namespace

std::vector<Eigen::Vector2d> ringFloorCenterline(const RingFloorOptions& o)
{
  const double hx = 0.5 * (o.core_x_m + o.width_m);
  const double hy = 0.5 * (o.core_y_m + o.width_m);
  return { Eigen::Vector2d(0.0, -hy), Eigen::Vector2d(hx, -hy), Eigen::Vector2d(hx, hy), Eigen::Vector2d(-hx, hy),
           Eigen::Vector2d(-hx, -hy) };
}

Scene ringFloorScene(unsigned seed, const RingFloorOptions& o)
{
  const double t = o.wall_thickness_m;
  if (!(o.core_x_m > 2.0 && o.core_y_m > 2.0 && o.width_m > 0.5 && o.height_m > kFloorDoorHeight && t > 0.0 &&
        o.feature_spacing_m > 0.0 && o.door_width_m > 0.0 && o.door_width_m < kFloorRoomWidthMin &&
        o.recess_depth_m > 0.0))
  {
    throw std::invalid_argument("ringFloorScene: invalid dimensions");
  }
  DeterministicRng rng(seed);
  Scene scene;
  const double cx = 0.5 * o.core_x_m;
  const double cy = 0.5 * o.core_y_m;
  const double ox = cx + o.width_m;  // outer wall faces
  const double oy = cy + o.width_m;
  const double outer_depth = 2.0 * t + o.room_depth_m;
  const double reach = std::max(ox, oy) + outer_depth + kFloorMargin;
  scene.add(PlanePatch::horizontal(0.0, -ox - outer_depth - kFloorMargin, ox + outer_depth + kFloorMargin,
                                   -oy - outer_depth - kFloorMargin, oy + outer_depth + kFloorMargin),
            SurfaceClass::Ground);
  scene.add(PlanePatch::horizontal(o.height_m, -reach, reach, -reach, reach), SurfaceClass::Building);

  FloorBuilder builder(&scene, o);
  // Core: a band behind each face (overlapping in the corners, where no features are carved), solid inside.
  const double core_depth = std::min(2.0 * t + o.room_depth_m, std::min(cx, cy) * 2.0 / 3.0);
  const double core_room = core_depth - 2.0 * t;
  const WallBand core[4] = {
    { false, -cy, 1.0, -cx, cx, core_depth, -cx + core_depth, cx - core_depth, core_room },
    { true, cx, -1.0, -cy, cy, core_depth, -cy + core_depth, cy - core_depth, core_room },
    { false, cy, -1.0, -cx, cx, core_depth, -cx + core_depth, cx - core_depth, core_room },
    { true, -cx, 1.0, -cy, cy, core_depth, -cy + core_depth, cy - core_depth, core_room },
  };
  // Outer walls: rooms behind them, the bands reaching round the corners.
  const WallBand outer[4] = {
    { false, -oy, -1.0, -ox - outer_depth, ox + outer_depth, outer_depth, -ox, ox, o.room_depth_m },
    { true, ox, 1.0, -oy, oy, outer_depth, -oy, oy, o.room_depth_m },
    { false, oy, 1.0, -ox - outer_depth, ox + outer_depth, outer_depth, -ox, ox, o.room_depth_m },
    { true, -ox, -1.0, -oy, oy, outer_depth, -oy, oy, o.room_depth_m },
  };
  for (const WallBand& band : core)
  {
    builder.band(band, rng);
  }
  for (const WallBand& band : outer)
  {
    builder.band(band, rng);
  }
  if (cx - core_depth > 1e-6 && cy - core_depth > 1e-6)
  {
    scene.add(OrientedBox(Eigen::Vector3d(0.0, 0.0, 0.5 * o.height_m),
                          Eigen::Vector3d(cx - core_depth, cy - core_depth, 0.5 * o.height_m)),
              SurfaceClass::Building);
  }
  // Ceiling lights along the centerline.
  if (o.light_spacing_m > 0.0)
  {
    const std::vector<Eigen::Vector2d> line = ringFloorCenterline(o);
    for (std::size_t i = 1; i < line.size(); ++i)
    {
      const Eigen::Vector2d a = line[i];
      const Eigen::Vector2d b = line[(i + 1) % line.size()];
      const double length = (b - a).norm();
      const Eigen::Vector2d d = (b - a) / length;
      for (double s = 0.5 * o.light_spacing_m; s < length - 0.25 * o.light_spacing_m; s += o.light_spacing_m)
      {
        const Eigen::Vector2d p = a + s * d;
        const bool along_x = std::abs(d.x()) > 0.5;
        scene.add(OrientedBox(Eigen::Vector3d(p.x(), p.y(), o.height_m - kLightHalf[2]),
                              Eigen::Vector3d(along_x ? kLightHalf[0] : kLightHalf[1],
                                              along_x ? kLightHalf[1] : kLightHalf[0], kLightHalf[2])),
                  SurfaceClass::Other);
      }
    }
  }
  return scene;
}

// ---------------------------------------------------------------------------------------------
// Revisits

std::vector<Revisit> trueRevisits(const std::vector<double>& times, const std::vector<Eigen::Isometry3d>& poses,
                                  double radius_m, double min_gap_s)
{
  if (times.size() != poses.size())
  {
    throw std::invalid_argument("trueRevisits: times and poses differ in size");
  }
  std::vector<Revisit> revisits;
  for (std::size_t j = 0; j < poses.size(); ++j)
  {
    double best = std::numeric_limits<double>::infinity();
    std::size_t best_i = 0;
    for (std::size_t i = 0; i < j; ++i)
    {
      if (times[j] - times[i] <= min_gap_s)
      {
        continue;
      }
      const double d = (poses[j].translation() - poses[i].translation()).norm();
      if (d < best)
      {
        best = d;
        best_i = i;
      }
    }
    if (best <= radius_m)
    {
      revisits.push_back({ times[best_i], times[j], best });
    }
  }
  return revisits;
}

std::vector<Revisit> trueRevisits(const PoseFunction& pose_at, double duration_s, double step_s, double radius_m,
                                  double min_gap_s)
{
  if (!(step_s > 0.0))
  {
    throw std::invalid_argument("trueRevisits: the step must be positive");
  }
  std::vector<double> times;
  std::vector<Eigen::Isometry3d> poses;
  const long samples = static_cast<long>(std::floor(duration_s / step_s + 1e-9));
  for (long k = 0; k <= samples; ++k)
  {
    times.push_back(static_cast<double>(k) * step_s);
    poses.push_back(pose_at(times.back()));
  }
  return trueRevisits(times, poses, radius_m, min_gap_s);
}

bool isTrueRevisit(const PoseFunction& pose_at, double t_a, double t_b, double radius_m)
{
  return (pose_at(t_a).translation() - pose_at(t_b).translation()).norm() <= radius_m;
}

}  // namespace sim
}  // namespace aloam
