// Scene families: a scene and a motion drawn from a family's parameter ranges by a seed, so that accuracy
// is measured over many scenes of a kind instead of one fixed scene. ROS-free and deterministic: the same
// family and seed give the same draw on every platform.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "aloam_nodelet/sim/loops.h"
#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scenes_extra.h"
#include "aloam_nodelet/sim/trajectories.h"

namespace aloam
{
namespace sim
{
enum class Family
{
  Corridor,         // straight corridor (or an L with one turn), hand-held
  Tunnel,           // road tunnel, car
  Office,           // L-shaped office corridor with clutter, hand-held walk around the corner
  Stairwell,        // one flight, hand-held climb
  Urban,            // street with buildings, car or hand-held
  Field,            // open ground with a few objects, car or hand-held
  CorridorIssue23,  // the corridor of issue 23 with its walk (fixed values; the seed varies the rest)
  LoopBlock,        // a car round an urban block 1.5-2 times (a loop back to the start street)
  LoopEight,        // a car on a figure-eight round two blocks, across the middle crossing both ways
  LoopFloor,        // a hand-held walk round the ring corridor of a building floor, 1.2-1.5 laps
  LoopRepetitive,   // a car in a grid of identical blocks: look-alike places, a true revisit or none
};

/// The families' command-line names: corridor tunnel office stairwell urban field corridor_issue23
/// loop_block loop_eight loop_floor loop_repetitive.
const std::vector<std::string>& familyNames();
std::optional<Family> familyFromName(const std::string& name);
std::string familyName(Family family);

/// How the sensor moves in a draw.
enum class MotionKind
{
  Car,       // carDrive
  HandHeld,  // handHeld (sway, yaw bursts, stops, maybe a start from rest)
  TurnWalk,  // handHeldTurn through an L (office, corridor with a turn)
  Path,      // pathFollow along rounded waypoints (the loop families; a car or a walker)
};

/// One drawn parameter with the range it was drawn from (for printing and for range checks).
struct DrawnParameter
{
  std::string key;
  double value = 0.0;
  double lo = 0.0;
  double hi = 0.0;
};

/// A scene and a motion drawn for a family and seed. Only the options of the family's scene kind and of
/// `motion` are used.
struct FamilyDraw
{
  Family family = Family::Corridor;
  unsigned seed = 0;
  double duration_s = 0.0;
  std::vector<DrawnParameter> parameters;  // in the order drawn

  // Scene (one of these, by family; a corridor with a turn is an office L).
  bool corridor_turn = false;
  CorridorOptions corridor;
  OfficeOptions office;
  TunnelOptions tunnel;
  StairsOptions stairs;
  UrbanStreetOptions urban;
  GroundProfile ground = GroundProfile::flat();  // urban hill / stairs walking surface
  double field_length_m = 0.0;
  int field_objects = 0;
  CityGridOptions city;         // loop_block, loop_eight, loop_repetitive
  RingFloorOptions ring_floor;  // loop_floor
  /// loop_repetitive: the blocks repeat every this many metres along x and y (0 for the other families).
  double block_period_m = 0.0;

  // Motion.
  MotionKind motion = MotionKind::HandHeld;
  CarDriveOptions car;
  HandHeldOptions walk;
  TurnWalkOptions turn_walk;
  PathFollowOptions path;

  /// The value of a drawn parameter (nullopt if it was not drawn).
  std::optional<double> parameter(const std::string& key) const;
  /// One line `family=NAME seed=N key=value ...` of everything drawn.
  std::string describe() const;
};

/// Draws a scene and motion of `family` for `seed`, sized so that a motion of `duration_s` seconds stays
/// inside the scene.
FamilyDraw drawFamily(Family family, unsigned seed, double duration_s);

/// The scene of a draw (built with the draw's seed).
Scene familyScene(const FamilyDraw& draw);
/// The sensor pose (world <- sensor) of a draw as a function of time.
PoseFunction familyMotion(const FamilyDraw& draw);

}  // namespace sim
}  // namespace aloam
