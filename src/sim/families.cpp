#include "aloam_nodelet/sim/families.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "deterministic_rng.h"

namespace aloam
{
namespace sim
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr unsigned kSeedMultiplier = 2654435761U;  // spreads consecutive seeds over the engine's seeds
constexpr double kOutdoorMargin = 150.0;           // m of scene beyond the end of the motion
constexpr double kCarStartX = 10.0;                // m
constexpr double kMinimumGap = 1.5;                // m, closest an end wall gets to the sensor's path
constexpr double kTurnWalkStart = 2.0;             // m, officeTurnWalk starts this far from the end wall
constexpr double kEndClearance = 3.0;              // m between the end of a walk and a wall ahead
// Issue 23's corridor: 2.5 m wide, 200 m long, closed; the walk starts 15 m from the back wall, six door
// recesses 0.25 m deep from 40 m ahead; 1.4 m/s from the first sweep, +-10 deg sway, 90 deg/s bursts.
constexpr double kIssueWidth = 2.5;
constexpr double kIssueLength = 200.0;
constexpr double kIssueStartX = 15.0;
constexpr double kIssueFirstDoorAhead = 40.0;
constexpr double kIssueDoorSpacing = 10.0;
constexpr int kIssueDoors = 6;
constexpr double kIssueRecess = 0.25;
constexpr double kIssueSpeed = 1.4;
constexpr double kIssueSwayDeg = 10.0;
constexpr double kIssueBurstDegS = 90.0;
// Loop families: the loop's size follows from the drawn speed, the drawn number of laps and the duration,
// within these bounds (so short durations give a small loop driven less than once).
constexpr double kBlockPerimeterMin = 200.0;  // m, street centerlines round the block
constexpr double kBlockPerimeterMax = 600.0;
constexpr double kEightLengthMin = 400.0;  // m, both lobes of the figure-eight
constexpr double kEightLengthMax = 900.0;
constexpr double kFloorPerimeterMin = 40.0;  // m, the ring corridor's centerline
constexpr double kFloorPerimeterMax = 200.0;
constexpr int kRepetitiveRings = 2;  // rings of identical blocks round the driven ones (beyond the lidar's reach)
constexpr double kRevisitLapsTarget = 1.2;  // loop_repetitive sizes its loop for about this many laps

const std::vector<std::pair<Family, std::string>>& familyTable()
{
  static const std::vector<std::pair<Family, std::string>> table = {
    { Family::Corridor, "corridor" },
    { Family::Tunnel, "tunnel" },
    { Family::Office, "office" },
    { Family::Stairwell, "stairwell" },
    { Family::Urban, "urban" },
    { Family::Field, "field" },
    { Family::CorridorIssue23, "corridor_issue23" },
    { Family::LoopBlock, "loop_block" },
    { Family::LoopEight, "loop_eight" },
    { Family::LoopFloor, "loop_floor" },
    { Family::LoopRepetitive, "loop_repetitive" },
  };
  return table;
}

/// Draws parameters from ranges and records each with its range.
class Drawer
{
public:
  Drawer(FamilyDraw* draw, unsigned stream) : draw_(draw), rng_(draw->seed * kSeedMultiplier + stream) {}

  double uniform(const std::string& key, double lo, double hi) { return record(key, rng_.uniform(lo, hi), lo, hi); }
  /// Uniform in log(value): as many draws in [5, 10] as in [50, 100].
  double logUniform(const std::string& key, double lo, double hi)
  {
    return record(key, lo * std::exp(rng_.uniform01() * std::log(hi / lo)), lo, hi);
  }
  /// An integer in [lo, hi], each equally likely.
  int integer(const std::string& key, int lo, int hi)
  {
    const int span = hi - lo + 1;
    const int value = std::min(hi, lo + static_cast<int>(std::floor(rng_.uniform01() * span)));
    return static_cast<int>(record(key, value, lo, hi));
  }
  bool flag(const std::string& key, double probability)
  {
    return record(key, rng_.bernoulli(probability) ? 1.0 : 0.0, 0.0, 1.0) > 0.5;
  }
  /// A value derived from drawn ones, with the range it can take.
  double derived(const std::string& key, double value, double lo, double hi) { return record(key, value, lo, hi); }
  /// A raw draw that is not recorded (positions and times).
  double raw(double lo, double hi) { return rng_.uniform(lo, hi); }

private:
  double record(const std::string& key, double value, double lo, double hi)
  {
    draw_->parameters.push_back({ key, value, lo, hi });
    return value;
  }

  FamilyDraw* draw_;
  DeterministicRng rng_;
};

/// Hand-held motion: speed, sway, yaw bursts at random times, a start from rest, stops. `speed_lo`..`speed_hi`
/// and `burst_max_deg_s` are the family's.
void drawHandHeld(Drawer& d, HandHeldOptions* walk, double duration, double speed_lo, double speed_hi,
                  double burst_max_deg_s)
{
  walk->speed = d.uniform("speed_mps", speed_lo, speed_hi);
  const double sway = d.uniform("sway_deg", 0.0, 15.0);
  walk->roll_amplitude_rad = sway * kDegToRad;
  walk->pitch_amplitude_rad = d.uniform("pitch_sway_deg", 0.0, 0.5 * sway) * kDegToRad;
  walk->bob_amplitude_m = d.uniform("bob_m", 0.0, 0.05);
  walk->burst_rate_rad_s = d.uniform("burst_deg_s", 0.0, burst_max_deg_s) * kDegToRad;
  walk->burst_duration_s = d.uniform("burst_s", 0.3, 0.8);
  const bool rest = d.flag("start_at_rest", 0.3);
  walk->start_rest_s = d.derived("start_rest_s", rest ? d.raw(0.5, 2.0) : 0.0, 0.0, 2.0);
  const bool stops = d.flag("stops", 0.4);
  if (stops)
  {
    walk->stop_still_s = d.uniform("stop_still_s", 0.5, 2.0);
    walk->stop_interval_s = d.uniform("stop_interval_s", 4.0, 10.0);
    walk->first_stop_s = walk->start_rest_s + walk->stop_edge_s + d.uniform("first_stop_after_s", 1.0, 4.0);
  }
  else
  {
    walk->stop_interval_s = 0.0;
  }
  walk->burst_times_s.clear();
  for (double t = d.raw(0.5, 4.0); t < duration; t += d.raw(1.5, 6.0))
  {
    walk->burst_times_s.push_back(t);
  }
  d.derived("bursts", static_cast<double>(walk->burst_times_s.size()), 0.0, std::ceil(duration / 1.5) + 1.0);
}

void drawCar(Drawer& d, CarDriveOptions* car, double speed_lo, double speed_hi, double weave_max_m)
{
  car->speed = d.uniform("speed_mps", speed_lo, speed_hi);
  car->weave_amplitude_m = d.uniform("weave_m", 0.0, weave_max_m);
  car->weave_period_s = d.uniform("weave_period_s", 8.0, 16.0);
  car->start_x = kCarStartX;
}

void drawTurnWalk(Drawer& d, TurnWalkOptions* walk)
{
  walk->speed = d.uniform("speed_mps", 0.8, 1.8);
  walk->roll_amplitude_rad = d.uniform("sway_deg", 0.0, 15.0) * kDegToRad;
  walk->yaw_sway_rad = d.uniform("yaw_sway_deg", 0.0, 5.0) * kDegToRad;
  walk->bob_amplitude_m = d.uniform("bob_m", 0.0, 0.05);
}

/// The second leg of an L long enough for a turn walk of `distance` metres starting kTurnWalkStart into
/// the first leg.
double secondLegFor(const OfficeOptions& office, double distance)
{
  return std::max(office.second_length_m, distance - (office.first_length_m - kTurnWalkStart) + kEndClearance);
}

void drawCorridor(Drawer& d, FamilyDraw* out)
{
  const double duration = out->duration_s;
  const double width = d.uniform("width_m", 1.8, 4.0);
  const double height = d.uniform("height_m", 2.4, 3.5);
  const double spacing = d.logUniform("feature_spacing_m", 5.0, 100.0);
  const double niche_probability = d.uniform("niche_probability", 0.0, 0.5);
  const double recess = d.uniform("recess_m", 0.1, 0.6);
  const bool lights = d.flag("lights", 0.5);
  const double light_spacing = d.derived("light_spacing_m", lights ? d.raw(3.0, 8.0) : 0.0, 0.0, 8.0);
  out->corridor_turn = d.flag("turn", 0.25);
  if (out->corridor_turn)
  {
    OfficeOptions& office = out->office;
    office.width_m = width;
    office.height_m = height;
    office.feature_spacing_m = spacing;
    office.spacing_jitter_m = 0.15 * spacing;
    office.recess_depth_m = recess;
    office.light_spacing_m = light_spacing;
    office.clutter_probability = 0.0;
    office.first_length_m = d.uniform("first_leg_m", 15.0, 60.0);
    office.second_length_m = d.uniform("second_leg_m", 20.0, 100.0);
    out->motion = MotionKind::TurnWalk;
    drawTurnWalk(d, &out->turn_walk);
    office.second_length_m = secondLegFor(office, out->turn_walk.speed * duration);
    const TurnWalkOptions geometry = officeTurnWalk(office);
    out->turn_walk.start_xy = geometry.start_xy;
    out->turn_walk.start_heading = geometry.start_heading;
    out->turn_walk.turn_start_m = geometry.turn_start_m;
    return;
  }
  CorridorOptions& c = out->corridor;
  c.width_m = width;
  c.height_m = height;
  c.niche_probability = niche_probability;
  c.recess_depth_m = recess;
  c.light_spacing_m = light_spacing;
  c.length_m = d.uniform("length_m", 50.0, 300.0);
  out->motion = MotionKind::HandHeld;
  drawHandHeld(d, &out->walk, duration, 0.8, 1.8, 120.0);
  const double walked = handHeldDistance(out->walk, duration);
  // Which end wall the walk sees: 0 near behind, 1 far behind, 2 near ahead, 3 far ahead, 4 neither (the
  // walk in the middle, both ends open).
  const int ends = d.integer("ends", 0, 4);
  const bool near = ends == 0 || ends == 2;
  const double gap = d.derived("end_gap_m", near ? d.raw(kMinimumGap, 8.0) : d.raw(15.0, 40.0), kMinimumGap, 40.0);
  c.length_m = std::max(c.length_m, walked + gap + 2.0 * kMinimumGap);
  double start = 0.5 * (c.length_m - walked);
  if (ends <= 1)
  {
    start = gap;
  }
  else if (ends <= 3)
  {
    start = c.length_m - walked - gap;
  }
  c.back_wall = ends <= 1 || (ends <= 3 && d.flag("other_end_closed", 0.7));
  c.front_wall = (ends == 2 || ends == 3) || (ends <= 1 && d.flag("other_end_closed", 0.7));
  out->walk.start_x = start;
  // Features at `spacing` (jittered) over the whole length, alternating sides.
  c.feature_x.clear();
  for (double x = d.raw(0.0, spacing); x < c.length_m; x += spacing * (1.0 + d.raw(-0.15, 0.15)))
  {
    c.feature_x.push_back(x);
  }
  d.derived("back_gap_m", start, 0.0, 300.0);
  d.derived("front_gap_m", c.length_m - start - walked, 0.0, 300.0);
}

void drawIssue23(Drawer& d, FamilyDraw* out)
{
  CorridorOptions& c = out->corridor;
  c.width_m = d.derived("width_m", kIssueWidth, kIssueWidth, kIssueWidth);
  c.length_m = d.derived("length_m", kIssueLength, kIssueLength, kIssueLength);
  c.recess_depth_m = d.derived("recess_m", kIssueRecess, kIssueRecess, kIssueRecess);
  c.niche_probability = 0.0;
  c.light_spacing_m = 0.0;
  c.back_wall = true;
  c.front_wall = true;
  c.feature_x.clear();
  for (int i = 0; i < kIssueDoors; ++i)
  {
    c.feature_x.push_back(kIssueStartX + kIssueFirstDoorAhead + i * kIssueDoorSpacing);
  }
  out->motion = MotionKind::HandHeld;
  HandHeldOptions& walk = out->walk;
  walk.start_x = d.derived("back_gap_m", kIssueStartX, kIssueStartX, kIssueStartX);
  walk.speed = d.derived("speed_mps", kIssueSpeed, kIssueSpeed, kIssueSpeed);
  walk.roll_amplitude_rad = d.derived("sway_deg", kIssueSwayDeg, kIssueSwayDeg, kIssueSwayDeg) * kDegToRad;
  walk.burst_rate_rad_s = d.derived("burst_deg_s", kIssueBurstDegS, kIssueBurstDegS, kIssueBurstDegS) * kDegToRad;
  d.derived("doors", kIssueDoors, kIssueDoors, kIssueDoors);
  d.derived("first_door_ahead_m", kIssueFirstDoorAhead, kIssueFirstDoorAhead, kIssueFirstDoorAhead);
}

void drawTunnel(Drawer& d, FamilyDraw* out)
{
  TunnelOptions& t = out->tunnel;
  t.width_m = d.uniform("width_m", 5.0, 10.0);
  t.wall_height_m = d.uniform("wall_height_m", 2.5, 4.0);
  t.feature_spacing_min_m = d.uniform("feature_spacing_min_m", 8.0, 30.0);
  t.feature_spacing_max_m = t.feature_spacing_min_m + d.uniform("feature_spacing_spread_m", 0.0, 30.0);
  t.niche_depth_m = d.uniform("niche_depth_m", 0.5, 1.2);
  t.niche_height_m = std::min(t.niche_height_m, t.wall_height_m - 0.3);
  t.back_length_m = d.uniform("back_gap_m", 10.0, 150.0) + kCarStartX;
  out->motion = MotionKind::Car;
  drawCar(d, &out->car, 5.0, 20.0, 0.5);
  t.length_m = out->car.start_x + out->car.speed * out->duration_s + kOutdoorMargin;
}

void drawOffice(Drawer& d, FamilyDraw* out)
{
  OfficeOptions& o = out->office;
  o.width_m = d.uniform("width_m", 1.8, 3.5);
  o.height_m = d.uniform("height_m", 2.4, 3.2);
  o.first_length_m = d.uniform("first_leg_m", 12.0, 25.0);
  o.second_length_m = d.uniform("second_leg_m", 15.0, 30.0);
  o.feature_spacing_m = d.uniform("feature_spacing_m", 3.0, 10.0);
  o.spacing_jitter_m = 0.25 * o.feature_spacing_m;
  o.recess_depth_m = d.uniform("recess_m", 0.1, 0.5);
  o.clutter_probability = d.uniform("clutter_probability", 0.0, 0.8);
  o.clutter_depth_max_m = d.uniform("clutter_depth_m", 0.3, 0.6);
  const bool lights = d.flag("lights", 0.7);
  o.light_spacing_m = d.derived("light_spacing_m", lights ? d.raw(2.0, 5.0) : 0.0, 0.0, 5.0);
  out->motion = MotionKind::TurnWalk;
  drawTurnWalk(d, &out->turn_walk);
  o.second_length_m = secondLegFor(o, out->turn_walk.speed * out->duration_s);
  const TurnWalkOptions geometry = officeTurnWalk(o);
  out->turn_walk.start_xy = geometry.start_xy;
  out->turn_walk.start_heading = geometry.start_heading;
  out->turn_walk.turn_start_m = geometry.turn_start_m;
}

void drawStairwell(Drawer& d, FamilyDraw* out)
{
  StairsOptions& s = out->stairs;
  s.risers = d.integer("risers", 10, 20);
  s.rise_m = d.uniform("rise_m", 0.15, 0.19);
  s.tread_m = d.uniform("tread_m", 0.25, 0.32);
  s.width_m = d.uniform("width_m", 1.4, 3.0);
  s.bottom_landing_m = d.uniform("bottom_landing_m", 3.5, 6.0);
  s.top_landing_m = d.uniform("top_landing_m", 3.0, 6.0);
  s.ceiling_height_m = s.totalRise() + d.uniform("headroom_m", 2.5, 4.0);
  out->motion = MotionKind::HandHeld;
  HandHeldOptions& walk = out->walk;
  walk = stairsWalkOptions(s);
  drawHandHeld(d, &walk, out->duration_s, 0.4, 0.8, 60.0);
  // The top landing reaches past the end of the climb.
  const double end_x = walk.start_x + handHeldDistance(walk, out->duration_s);
  s.top_landing_m = std::max(s.top_landing_m, end_x - s.run() + kEndClearance);
  walk.ground = stairsProfile(s);
  out->ground = walk.ground;
}

void drawUrban(Drawer& d, FamilyDraw* out)
{
  UrbanStreetOptions& u = out->urban;
  u.street_width_min_m = d.uniform("street_width_m", 8.0, 16.0);
  u.street_width_max_m = u.street_width_min_m + d.uniform("street_width_spread_m", 0.0, 6.0);
  u.building_height_max_m = d.uniform("building_height_max_m", 8.0, 30.0);
  u.gap_probability = d.uniform("gap_probability", 0.1, 0.6);
  u.car_probability = d.uniform("car_probability", 0.0, 0.7);
  u.pole_spacing_min_m = d.uniform("pole_spacing_m", 8.0, 30.0);
  u.pole_spacing_max_m = u.pole_spacing_min_m + 10.0;
  u.tree_probability = d.uniform("tree_probability", 0.0, 0.6);
  GroundProfile hill;
  hill.grade = d.uniform("hill_grade", 0.0, 0.06);
  hill.start_x = d.uniform("hill_start_m", 20.0, 60.0);
  hill.length_m = d.uniform("hill_length_m", 30.0, 80.0);
  out->ground = hill;
  const bool hand_held = d.flag("hand_held", 0.5);
  double distance = 0.0;
  if (hand_held)
  {
    out->motion = MotionKind::HandHeld;
    drawHandHeld(d, &out->walk, out->duration_s, 0.8, 1.8, 120.0);
    out->walk.start_x = kCarStartX;
    out->walk.ground = hill;
    distance = out->walk.start_x + handHeldDistance(out->walk, out->duration_s);
  }
  else
  {
    out->motion = MotionKind::Car;
    drawCar(d, &out->car, 3.0, 15.0, 1.5);
    out->car.ground = hill;
    distance = out->car.start_x + out->car.speed * out->duration_s;
  }
  u.length_m = distance + kOutdoorMargin;
}

void drawField(Drawer& d, FamilyDraw* out)
{
  out->field_objects = d.integer("objects", 0, 10);
  const bool hand_held = d.flag("hand_held", 0.5);
  double distance = 0.0;
  if (hand_held)
  {
    out->motion = MotionKind::HandHeld;
    drawHandHeld(d, &out->walk, out->duration_s, 0.8, 1.8, 120.0);
    distance = out->walk.start_x + handHeldDistance(out->walk, out->duration_s);
  }
  else
  {
    out->motion = MotionKind::Car;
    drawCar(d, &out->car, 3.0, 15.0, 1.5);
    distance = out->car.start_x + out->car.speed * out->duration_s;
  }
  out->field_length_m = distance + kOutdoorMargin;
}

/// The frontage of the loop families' blocks (buildings, poles, trees, parked cars).
void drawFacade(Drawer& d, UrbanStreetOptions* facade)
{
  facade->building_height_max_m = d.uniform("building_height_max_m", 8.0, 30.0);
  facade->gap_probability = d.uniform("gap_probability", 0.1, 0.6);
  facade->car_probability = d.uniform("car_probability", 0.0, 0.6);
  facade->pole_spacing_min_m = d.uniform("pole_spacing_m", 10.0, 30.0);
  facade->pole_spacing_max_m = facade->pole_spacing_min_m + 10.0;
  facade->tree_probability = d.uniform("tree_probability", 0.0, 0.6);
}

/// A car on the path: speed, corner rounding and a lane offset to the right.
void drawPathCar(Drawer& d, PathFollowOptions* path, double corner_lo, double corner_hi)
{
  path->speed = d.uniform("speed_mps", 6.0, 10.0);
  path->corner_length_m = d.uniform("corner_length_m", corner_lo, corner_hi);
  path->lateral_offset_m = -d.uniform("lane_offset_m", 0.0, 0.5);
  path->height_m = 1.8;
}

/// Records the laps the motion makes of its (closed) path.
void recordLaps(Drawer& d, const FamilyDraw& draw, double max_laps)
{
  const RoundedPath path(draw.path.waypoints, draw.path.closed, draw.path.corner_length_m);
  d.derived("path_length_m", path.length(), 0.0, 1e5);
  d.derived("laps", std::min(max_laps, draw.path.speed * draw.duration_s / path.length()), 0.0, max_laps);
}

std::vector<Eigen::Vector2d> reversedLoop(std::vector<Eigen::Vector2d> loop)
{
  std::reverse(loop.begin() + 1, loop.end());  // same start, the other way round
  return loop;
}

void drawLoopBlock(Drawer& d, FamilyDraw* out)
{
  out->motion = MotionKind::Path;
  drawPathCar(d, &out->path, 20.0, 28.0);
  const double laps = d.uniform("laps_target", 1.5, 2.0);
  const double aspect = d.uniform("aspect", 0.4, 0.6);  // share of the half perimeter along x
  const bool clockwise = d.flag("clockwise", 0.5);
  CityGridOptions& city = out->city;
  city.street_width_m = d.uniform("street_width_m", 14.0, 18.0);
  city.outer_block_m = d.uniform("outer_block_m", 30.0, 50.0);
  drawFacade(d, &city.facade);
  const double perimeter = d.derived(
      "perimeter_m", std::clamp(out->path.speed * out->duration_s / laps, kBlockPerimeterMin, kBlockPerimeterMax),
      kBlockPerimeterMin, kBlockPerimeterMax);
  const double w = 0.5 * perimeter * aspect;
  const double h = 0.5 * perimeter - w;
  city.street_x = { 0.0, w };
  city.street_y = { 0.0, h };
  // From the middle of the south street, counterclockwise unless drawn otherwise.
  const std::vector<Eigen::Vector2d> loop = { Eigen::Vector2d(0.5 * w, 0.0), Eigen::Vector2d(w, 0.0),
                                              Eigen::Vector2d(w, h), Eigen::Vector2d(0.0, h),
                                              Eigen::Vector2d(0.0, 0.0) };
  out->path.waypoints = clockwise ? reversedLoop(loop) : loop;
  out->path.closed = true;
  recordLaps(d, *out, 100.0);
}

void drawLoopEight(Drawer& d, FamilyDraw* out)
{
  out->motion = MotionKind::Path;
  drawPathCar(d, &out->path, 20.0, 28.0);
  const double laps = d.uniform("laps_target", 1.1, 1.5);
  const double aspect = d.uniform("aspect", 0.4, 0.6);
  const bool reverse = d.flag("reverse", 0.5);
  CityGridOptions& city = out->city;
  city.street_width_m = d.uniform("street_width_m", 14.0, 18.0);
  city.outer_block_m = d.uniform("outer_block_m", 30.0, 50.0);
  drawFacade(d, &city.facade);
  const double length = d.derived(
      "eight_length_m", std::clamp(out->path.speed * out->duration_s / laps, kEightLengthMin, kEightLengthMax),
      kEightLengthMin, kEightLengthMax);
  const double w = 0.25 * length * aspect;
  const double h = 0.25 * length - w;
  city.street_x = { 0.0, w, 2.0 * w };
  city.street_y = { 0.0, h, 2.0 * h };
  // Two diagonal blocks touching at the middle crossing (w, h): east across it and round the north-east
  // block turning left, south across it and round the south-west block turning right.
  const std::vector<Eigen::Vector2d> eight = {
    Eigen::Vector2d(0.5 * w, h),       Eigen::Vector2d(w, h),       Eigen::Vector2d(2.0 * w, h),
    Eigen::Vector2d(2.0 * w, 2.0 * h), Eigen::Vector2d(w, 2.0 * h), Eigen::Vector2d(w, h),
    Eigen::Vector2d(w, 0.0),           Eigen::Vector2d(0.0, 0.0),   Eigen::Vector2d(0.0, h),
  };
  out->path.waypoints = reverse ? reversedLoop(eight) : eight;
  out->path.closed = true;
  recordLaps(d, *out, 100.0);
}

void drawLoopFloor(Drawer& d, FamilyDraw* out)
{
  out->motion = MotionKind::Path;
  PathFollowOptions& path = out->path;
  path.speed = d.uniform("speed_mps", 1.2, 1.5);
  const double laps = d.uniform("laps_target", 1.2, 1.5);
  path.corner_length_m = d.uniform("corner_length_m", 2.0, 3.5);
  path.height_m = d.uniform("height_m", 1.3, 1.6);
  path.roll_amplitude_rad = d.uniform("sway_deg", 0.0, 8.0) * kDegToRad;
  path.yaw_sway_rad = d.uniform("yaw_sway_deg", 0.0, 5.0) * kDegToRad;
  path.bob_amplitude_m = d.uniform("bob_m", 0.0, 0.05);
  path.bob_frequency_hz = 1.4 * path.speed;  // steps of about 0.7 m
  RingFloorOptions& f = out->ring_floor;
  f.width_m = d.uniform("width_m", 1.8, 3.0);
  f.height_m = d.uniform("ceiling_m", 2.4, 3.2);
  f.feature_spacing_m = d.uniform("feature_spacing_m", 3.0, 10.0);
  f.recess_depth_m = d.uniform("recess_m", 0.1, 0.5);
  f.room_probability = d.uniform("room_probability", 0.0, 0.5);
  f.niche_probability = d.uniform("niche_probability", 0.0, 0.3);
  f.room_depth_m = d.uniform("room_depth_m", 2.5, 5.0);
  const bool lights = d.flag("lights", 0.7);
  f.light_spacing_m = d.derived("light_spacing_m", lights ? d.raw(2.5, 5.0) : 0.0, 0.0, 5.0);
  const double aspect = d.uniform("aspect", 0.35, 0.65);
  const double perimeter =
      d.derived("perimeter_m", std::clamp(path.speed * out->duration_s / laps, kFloorPerimeterMin, kFloorPerimeterMax),
                kFloorPerimeterMin, kFloorPerimeterMax);
  // The centerline rectangle is (core_x + width) by (core_y + width).
  f.core_x_m = 0.5 * perimeter * aspect - f.width_m;
  f.core_y_m = 0.5 * perimeter * (1.0 - aspect) - f.width_m;
  const bool clockwise = d.flag("clockwise", 0.5);
  path.waypoints = clockwise ? reversedLoop(ringFloorCenterline(f)) : ringFloorCenterline(f);
  path.closed = true;
  recordLaps(d, *out, 100.0);
}

void drawLoopRepetitive(Drawer& d, FamilyDraw* out)
{
  out->motion = MotionKind::Path;
  drawPathCar(d, &out->path, 20.0, 26.0);
  CityGridOptions& city = out->city;
  city.street_x.clear();
  city.street_y.clear();
  const double period = d.uniform("block_period_m", 50.0, 80.0);
  out->block_period_m = period;
  city.street_width_m = d.uniform("street_width_m", 12.0, 16.0);
  city.outer_block_m = 0.0;
  city.identical_blocks = true;
  drawFacade(d, &city.facade);
  const bool revisit = d.flag("revisit", 0.5);
  const double distance = out->path.speed * out->duration_s;
  int nx = 0;
  int ny = 0;
  std::vector<Eigen::Vector2d>& w = out->path.waypoints;
  w.clear();
  if (revisit)
  {
    // Round a rectangle of blocks sized for about kRevisitLapsTarget laps (at least 1 x 1 block).
    const int blocks = std::clamp(static_cast<int>(std::floor(distance / (kRevisitLapsTarget * 2.0 * period))), 2, 6);
    nx = (blocks + 1) / 2;
    ny = blocks - nx;
    const double x = nx * period;
    const double y = ny * period;
    w = { Eigen::Vector2d(0.5 * period, 0.0), Eigen::Vector2d(x, 0.0), Eigen::Vector2d(x, y), Eigen::Vector2d(0.0, y),
          Eigen::Vector2d(0.0, 0.0) };
    out->path.closed = true;
    d.derived("loop_blocks", blocks, 2, 6);
  }
  else
  {
    // A serpentine: rows `row_blocks` long, one block apart, joined at alternate ends; it never comes back.
    nx = d.integer("row_blocks", 2, 4);
    const double row = nx * period;
    ny = static_cast<int>(std::ceil((distance + period) / (row + period)));
    w.push_back(Eigen::Vector2d(0.5 * period, 0.0));
    for (int j = 0; j <= ny; ++j)
    {
      const bool east = j % 2 == 0;
      w.push_back(Eigen::Vector2d(east ? row : 0.0, j * period));
      w.push_back(Eigen::Vector2d(east ? row : 0.0, (j + 1) * period));
    }
    w.pop_back();  // ends along the last row
    ny += 1;
    out->path.closed = false;
    d.derived("rows", ny, 1, 1e4);
  }
  for (int i = -kRepetitiveRings; i <= nx + kRepetitiveRings; ++i)
  {
    city.street_x.push_back(i * period);
  }
  for (int j = -kRepetitiveRings; j <= ny + kRepetitiveRings; ++j)
  {
    city.street_y.push_back(j * period);
  }
  if (revisit)
  {
    recordLaps(d, *out, 100.0);
  }
}

std::string motionName(MotionKind motion)
{
  switch (motion)
  {
    case MotionKind::Car:
      return "car";
    case MotionKind::HandHeld:
      return "handheld";
    case MotionKind::TurnWalk:
      return "turn_walk";
    case MotionKind::Path:
      return "path";
  }
  return "?";
}
}  // namespace

const std::vector<std::string>& familyNames()
{
  static const std::vector<std::string> names = []
  {
    std::vector<std::string> list;
    for (const auto& entry : familyTable())
    {
      list.push_back(entry.second);
    }
    return list;
  }();
  return names;
}

std::optional<Family> familyFromName(const std::string& name)
{
  for (const auto& [family, family_name] : familyTable())
  {
    if (family_name == name)
    {
      return family;
    }
  }
  return std::nullopt;
}

std::string familyName(Family family)
{
  for (const auto& [entry, name] : familyTable())
  {
    if (entry == family)
    {
      return name;
    }
  }
  return "?";
}

std::optional<double> FamilyDraw::parameter(const std::string& key) const
{
  for (const DrawnParameter& p : parameters)
  {
    if (p.key == key)
    {
      return p.value;
    }
  }
  return std::nullopt;
}

std::string FamilyDraw::describe() const
{
  std::string line = "family=" + familyName(family) + " seed=" + std::to_string(seed) + " motion=" + motionName(motion);
  char buffer[64];
  for (const DrawnParameter& p : parameters)
  {
    std::snprintf(buffer, sizeof(buffer), "%.4g", p.value);
    line += " " + p.key + "=" + buffer;
  }
  return line;
}

FamilyDraw drawFamily(Family family, unsigned seed, double duration_s)
{
  if (!(duration_s > 0.0))
  {
    throw std::invalid_argument("drawFamily: the duration must be positive");
  }
  FamilyDraw draw;
  draw.family = family;
  draw.seed = seed;
  draw.duration_s = duration_s;
  Drawer d(&draw, static_cast<unsigned>(family));
  switch (family)
  {
    case Family::Corridor:
      drawCorridor(d, &draw);
      break;
    case Family::CorridorIssue23:
      drawIssue23(d, &draw);
      break;
    case Family::Tunnel:
      drawTunnel(d, &draw);
      break;
    case Family::Office:
      drawOffice(d, &draw);
      break;
    case Family::Stairwell:
      drawStairwell(d, &draw);
      break;
    case Family::Urban:
      drawUrban(d, &draw);
      break;
    case Family::Field:
      drawField(d, &draw);
      break;
    case Family::LoopBlock:
      drawLoopBlock(d, &draw);
      break;
    case Family::LoopEight:
      drawLoopEight(d, &draw);
      break;
    case Family::LoopFloor:
      drawLoopFloor(d, &draw);
      break;
    case Family::LoopRepetitive:
      drawLoopRepetitive(d, &draw);
      break;
  }
  return draw;
}

Scene familyScene(const FamilyDraw& draw)
{
  switch (draw.family)
  {
    case Family::Corridor:
    case Family::CorridorIssue23:
      return draw.corridor_turn ? officeScene(draw.seed, draw.office) : corridorScene(draw.seed, draw.corridor);
    case Family::Tunnel:
      return tunnelScene(draw.seed, draw.tunnel);
    case Family::Office:
      return officeScene(draw.seed, draw.office);
    case Family::Stairwell:
      return stairsScene(draw.seed, draw.stairs);
    case Family::Urban:
      return urbanStreetWithHill(draw.seed, draw.urban, draw.ground);
    case Family::Field:
      return openFieldScene(draw.seed, draw.field_length_m, draw.field_objects);
    case Family::LoopBlock:
    case Family::LoopEight:
    case Family::LoopRepetitive:
      return cityGridScene(draw.seed, draw.city);
    case Family::LoopFloor:
      return ringFloorScene(draw.seed, draw.ring_floor);
  }
  throw std::invalid_argument("familyScene: unknown family");
}

PoseFunction familyMotion(const FamilyDraw& draw)
{
  switch (draw.motion)
  {
    case MotionKind::Car:
      return carDrive(draw.car);
    case MotionKind::HandHeld:
      return handHeld(draw.walk);
    case MotionKind::TurnWalk:
      return handHeldTurn(draw.turn_walk);
    case MotionKind::Path:
      return pathFollow(draw.path);
  }
  throw std::invalid_argument("familyMotion: unknown motion");
}

}  // namespace sim
}  // namespace aloam
