// Extra deterministic scenes for the simulator: an urban street with a hill, an indoor corridor, an
// open field, an L-shaped office corridor, a road tunnel and a stairwell. ROS-free.
#pragma once

#include <vector>

#include "aloam_nodelet/sim/scene.h"

namespace aloam
{
namespace sim
{
/// Smooth ground height along x: flat (z = 0) before `start_x`, then a ramp of `grade` over
/// `length_m`, then flat again at grade * length_m. The two kinks are rounded over `blend_length_m`
/// (centered on the kinks; the slope follows a smoothstep there) so that the slope and its derivative
/// are continuous.
struct GroundProfile
{
  double start_x = 30.0;         // metres, start of the ramp (center of the first vertical curve)
  double length_m = 60.0;        // metres, horizontal length of the ramp (kink to kink)
  double grade = 0.04;           // rise over run of the ramp
  double blend_length_m = 10.0;  // metres, length of each vertical curve

  /// A profile with no hill (z = 0 everywhere).
  static GroundProfile flat();

  /// Ground height (metres) at x.
  double heightAt(double x) const;
  /// Slope dz/dx at x.
  double slopeAt(double x) const;
  /// Height at the top of the ramp.
  double rise() const { return grade * length_m; }
};

/// The street of Scene::urbanStreet(seed, length_m) on a ground following `profile`: the ground
/// plane is replaced by planar patches (vertical curves approximated by short chords) and every
/// other primitive is lifted by the lowest ground height under its footprint.
Scene urbanStreetWithHill(unsigned seed, double length_m, const GroundProfile& profile = GroundProfile());
/// The same with every option of the street (its length is options.length_m).
Scene urbanStreetWithHill(unsigned seed, const UrbanStreetOptions& options, const GroundProfile& profile);

/// Options of corridorScene. The corridor runs along +x from x = 0 to x = length_m, centered on y = 0.
struct CorridorOptions
{
  double length_m = 100.0;
  double width_m = 2.5;   // wall to wall
  double height_m = 3.0;  // floor (z = 0) to ceiling
  double wall_thickness_m = 0.4;
  double feature_spacing_m = 8.0;  // mean spacing of doors / recesses along each wall
  double spacing_jitter_m = 1.5;   // uniform jitter of that spacing
  double door_width_m = 1.0;
  double recess_depth_m = 0.3;     // doors are recessed this far behind the wall face
  double light_spacing_m = 4.0;    // ceiling lights (small boxes); 0: none
  double niche_probability = 0.3;  // chance that a feature is a full-height niche instead of a door
  bool back_wall = true;           // end wall at x = 0; without it the corridor is open there
  bool front_wall = true;          // end wall at x = length_m
  /// When not empty: the x of every feature's center (doors / niches), placed on alternating walls
  /// starting with the +y wall, instead of the layout every feature_spacing_m.
  std::vector<double> feature_x;
};

/// Indoor corridor with doors / recesses on alternating walls (deterministic for a seed).
Scene corridorScene(unsigned seed, const CorridorOptions& options = CorridorOptions());

/// Flat ground (z = 0) with very few objects (a few boxes, poles and a boulder) scattered along +x
/// between x = 20 and x = length_m, at least 8 m from the x axis.
Scene openFieldScene(unsigned seed, double length_m = 300.0, int object_count = 5);

/// Options of officeScene: an L of two corridors with doors, niches, cabinets and ceiling lights, floor
/// at z = 0 and a ceiling. The first corridor runs along +x from its end wall at x = 0, centered on
/// y = 0; at its far end (outer wall face at x = first_length_m) it turns 90 degrees left into the
/// second corridor, which runs along +y centered on x = turnCenterX() up to y = 0.5 * width_m +
/// second_length_m.
struct OfficeOptions
{
  double first_length_m = 16.0;   // x = 0 to the outer wall of the corner
  double second_length_m = 24.0;  // beyond the first corridor's wall line
  double width_m = 2.5;           // wall to wall, both corridors
  double height_m = 2.8;          // floor (z = 0) to ceiling
  double wall_thickness_m = 0.3;
  double feature_spacing_m = 6.0;  // mean spacing of doors / niches along each wall
  double spacing_jitter_m = 1.5;
  double door_width_m = 1.0;
  double recess_depth_m = 0.25;
  double light_spacing_m = 3.0;      // 0: no lights
  double clutter_probability = 0.5;  // chance of a cabinet against each stretch of wall between openings
  double clutter_depth_max_m = 0.5;  // cabinets stick out at most this far from the wall face

  /// x of the second corridor's centerline.
  double turnCenterX() const { return first_length_m - 0.5 * width_m; }
  /// y of the second corridor's end wall face.
  double secondEndY() const { return 0.5 * width_m + second_length_m; }
};

/// L-shaped office corridor (deterministic for a seed; the layout of openings and clutter depends on it).
Scene officeScene(unsigned seed, const OfficeOptions& options = OfficeOptions());

/// Options of tunnelScene: a road tunnel along +x with vertical side walls and a polygonal arch, a
/// raised walkway and a cable tray along the walls, and sparse features (safety niches, wall lights,
/// standpipes) every feature_spacing_min_m..feature_spacing_max_m.
struct TunnelOptions
{
  double length_m = 300.0;       // features from x = 0 to x = length_m; the end wall a little beyond
  double back_length_m = 100.0;  // the tunnel continues this far behind x = 0 (its end wall out of reach)
  double width_m = 6.0;          // wall to wall at the floor
  double wall_height_m = 3.0;    // the arch (radius width_m / 2, centered on the wall tops) starts here
  int arch_chords = 4;           // planar chords per side approximating the quarter circles
  double lining_thickness_m = 1.5;
  double walkway_width_m = 0.8;  // raised walkway along the +y wall
  double walkway_height_m = 0.2;
  double feature_spacing_min_m = 10.0;
  double feature_spacing_max_m = 20.0;
  double niche_width_m = 2.0;
  double niche_depth_m = 1.0;
  double niche_height_m = 2.4;

  /// Height of the crown above the floor.
  double crownHeight() const { return wall_height_m + 0.5 * width_m; }
};

/// Road tunnel (deterministic for a seed: the positions and kinds of the sparse features).
Scene tunnelScene(unsigned seed, const TunnelOptions& options = TunnelOptions());

/// Options of stairsScene: one straight flight in a walled stairwell along +x. Riser i (0-based) is at
/// x = i * tread_m; after it the floor is at (i + 1) * rise_m; the top landing starts at
/// x = (risers - 1) * tread_m at height risers * rise_m.
struct StairsOptions
{
  int risers = 17;
  double rise_m = 0.175;
  double tread_m = 0.28;
  double width_m = 2.2;           // wall to wall
  double bottom_landing_m = 4.0;  // floor behind the first riser
  double top_landing_m = 5.0;     // beyond the last riser
  double ceiling_height_m = 6.0;  // above the bottom floor
  double wall_thickness_m = 0.3;

  double run() const { return (risers - 1) * tread_m; }
  double totalRise() const { return risers * rise_m; }
};

/// Stairwell with doors at both ends, wall lamps, a stepped handrail and a few objects on the landings.
Scene stairsScene(unsigned seed, const StairsOptions& options = StairsOptions());

/// A smooth walking surface over the flight (for the trajectories): flat on the bottom landing, the
/// mean slope of the nosings over the flight, flat at totalRise() on the top landing.
GroundProfile stairsProfile(const StairsOptions& options = StairsOptions());

}  // namespace sim
}  // namespace aloam
